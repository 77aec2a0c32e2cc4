# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
# ---

# %% [markdown]
# # Fleets: flag rule, population prior, and the scale of a run (issue 17)
#
# 1. **False-flag rate** of the flag rule (:mod:`optcal.applications.fleet.population`) on clean synthetic
#    fleets of several sizes (no planted trouble), and the detection of an 8 % scale error.
# 2. **Population prior** on fleets with known truth: error of weak units (six faces only; a 60°
#    cap) with the prior against their own degenerate fit; bias and error of well-determined units
#    with the prior against their own fit.
# 3. **A measured run of 10⁴ synthetic units** through `optcal fleet` on a 2-worker LocalCluster,
#    and the per-unit cost that the scale plan of `studies/fleet_scale.md` extrapolates from.
#
# Regenerate with `python studies/fleet_scale.py` (writes `studies/fleet_scale.md` and
# `studies/results/fleet_scale.json`; about 10 minutes on a busy 2-core machine).  Sections 1 and 2
# use the batched solver (:mod:`optcal.families.accel.batched`, identical to `mle` to the solver
# tolerance) for the thousands of own fits.

# %%
from __future__ import annotations

import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from optcal.families.accel.calibration import calibrate
from optcal.families.accel.batched import BatchedMaximumLikelihood
from optcal.applications.fleet.engine import refit_unit
from optcal.applications.fleet.inputs import expand_inputs
from optcal.applications.fleet.population import DEFAULT_FLAG_THRESHOLD, flag_units, population_stats
from optcal.applications.fleet.prior import estimate_prior, fit_with_prior
from optcal.applications.fleet.synthetic import unit_model, write_fleet
from optcal.applications.fleet.unit import UnitOutcome, fit_unit, read_unit
from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import cap_directions, simulate_poses, six_position, uniform_directions

from study_mode import size as full_or_quick  # noqa: E402
from study_mode import RESULTS as OUT  # noqa: E402
SEED = 2026
SIGMA = 0.002
N_POSES = 120
RESULTS: dict = {"seed": SEED, "sigma_g": SIGMA, "n_poses": N_POSES, "machine": f"{platform.machine()}, {os.cpu_count()} cores"}


def clean_fleet(n_units: int, seed: int, scale_error: int = 0) -> tuple[list[UnitOutcome], np.ndarray]:
    """Own fits of a clean synthetic fleet (the last ``scale_error`` units with an 8 % x scale error)."""
    truth, tables = [], []
    for k in range(n_units):
        rng = np.random.default_rng([seed, k])
        model = unit_model(rng, 0.08 if k >= n_units - scale_error else 0.0)
        truth.append(model.theta)
        tables.append(simulate_poses(model, uniform_directions(N_POSES, rng), SIGMA, rng=rng))
    fit = BatchedMaximumLikelihood().fit_many(tables)
    outcomes = [UnitOutcome(f"u{k}", "", "calibrated", theta=fit.theta[k], stderr=fit.stderr[k], covariance=fit.covariance[k],
                            rms_g=float(fit.rms_g[k]), n_poses=N_POSES, units="g", sigma_known=True) for k in range(n_units)]
    return outcomes, np.array(truth)


# %% [markdown]
# ## 1. False-flag rate on clean fleets

# %%
t0 = time.perf_counter()
flag_rows = []
for n_units, n_fleets in full_or_quick(((50, 40), (100, 20), (300, 10), (1000, 4)), ((30, 1),)):
    flagged = total = detected = 0
    for f in range(n_fleets):
        outcomes, _ = clean_fleet(n_units + 1, SEED + 1000 * n_units + f, scale_error=1)
        stats = population_stats(outcomes, DEFAULT_FLAG_THRESHOLD)
        flag_units(outcomes, stats)
        flagged += sum(bool(o.flag) for o in outcomes[:-1])
        total += n_units
        detected += bool(outcomes[-1].flag)
    rate = flagged / total
    flag_rows.append({"units": n_units, "fleets": n_fleets, "normal_units": total, "false_flags": flagged,
                      "false_flag_rate": rate, "rate_se": float(np.sqrt(max(rate * (1 - rate), 1e-12) / total)),
                      "scale_error_detected": f"{detected}/{n_fleets}"})
RESULTS["false_flags"] = {"threshold": DEFAULT_FLAG_THRESHOLD, "rows": flag_rows,
                          # nine two-sided parameter checks and the one-sided residual check, if independent
                          "union_bound": 9.5 * math.erfc(DEFAULT_FLAG_THRESHOLD / math.sqrt(2)),
                          "seconds": time.perf_counter() - t0}
for r in flag_rows:
    print(r)

# %% [markdown]
# ## 2. The population prior: weak units and well-determined units

# %%
t0 = time.perf_counter()
population, _ = clean_fleet(full_or_quick(300, 40), SEED + 7)
stats = population_stats(population)
flag_units(population, stats)
prior = estimate_prior(population)


def a_error(theta: np.ndarray, true_theta: np.ndarray) -> float:
    return float(np.max(np.abs(LumpedModel.from_theta(theta).A - LumpedModel.from_theta(true_theta).A)))


weak_rows = {}
for label, make_dirs in (("six faces ×4 (24 poses)", lambda rng: np.repeat(six_position(), 4, axis=0)),
                         ("60° cap, 30 poses", lambda rng: cap_directions(30, 60.0, rng))):
    alone, with_prior, share = [], [], []
    for k in range(full_or_quick(40, 3)):
        rng = np.random.default_rng([SEED, 99, k, len(label)])
        model = unit_model(rng)
        poses = simulate_poses(model, make_dirs(rng), SIGMA, rng=rng)
        try:
            alone.append(a_error(calibrate(poses, allow_degenerate=True).params[:9], model.theta))
        except Exception:  # noqa: BLE001 - a collapsed fit counts as a failure of the unit alone
            alone.append(np.inf)
        fit = fit_with_prior(poses, prior)
        with_prior.append(a_error(fit.result.params[:9], model.theta))
        share.append(fit.prior_weight)
    alone_arr, prior_arr = np.array(alone), np.array(with_prior)
    weak_rows[label] = {"units": len(alone), "alone_median": float(np.median(alone_arr)), "alone_p90": float(np.quantile(alone_arr, 0.9)),
                        "alone_failed": int(np.sum(~np.isfinite(alone_arr))), "prior_median": float(np.median(prior_arr)),
                        "prior_p90": float(np.quantile(prior_arr, 0.9)), "prior_max": float(prior_arr.max()),
                        "mean_prior_share": np.mean(share, axis=0).round(3).tolist()}

own_err, prior_err = [], []
for k in range(full_or_quick(100, 5)):
    rng = np.random.default_rng([SEED, 55, k])
    model = unit_model(rng)
    poses = simulate_poses(model, uniform_directions(N_POSES, rng), SIGMA, rng=rng)
    own = calibrate(poses)
    fit = fit_with_prior(poses, prior, start=own.params[:9])
    own_err.append(own.params[:9] - model.theta)
    prior_err.append(fit.result.params[:9] - model.theta)
own_err, prior_err = np.array(own_err), np.array(prior_err)
bias_z = prior_err.mean(axis=0) / (prior_err.std(axis=0, ddof=1) / np.sqrt(len(prior_err)))
RESULTS["prior"] = {
    "population_units": prior.n_units, "prior_sd": np.sqrt(np.diag(prior.covariance)).tolist(), "weak": weak_rows,
    "well_determined": {"units": 100, "rms_error_ratio_prior_over_own": (np.sqrt(np.mean(prior_err**2, 0)) / np.sqrt(np.mean(own_err**2, 0))).tolist(),
                        "max_abs_bias_z": float(np.max(np.abs(bias_z)))},
    "seconds": time.perf_counter() - t0,
}
print(json.dumps(RESULTS["prior"], indent=1))

# %% [markdown]
# ## 3. A measured run of 10⁴ synthetic units

# %%
N_RUN = int(os.environ.get("OPTCAL_FLEET_UNITS", full_or_quick("10000", "40")))
with tempfile.TemporaryDirectory() as tmp:
    t0 = time.perf_counter()
    fleet = write_fleet(Path(tmp) / "units", N_RUN, seed=SEED, scale_error_units=2, six_face_units=5, unreadable_units=5)
    written = time.perf_counter() - t0
    t0 = time.perf_counter()
    # the command line a user runs, in its own process (Dask's worker processes re-import __main__)
    # (quick mode, CI: one worker process, one interpreter's imports fewer; the full run measures two)
    proc = subprocess.run([sys.executable, "-m", "optcal.cli.main", "fleet", str(Path(tmp) / "units"), "-o",
                           str(Path(tmp) / "r.parquet"), "--workers", full_or_quick("2", "1"), "--json", "--no-progress"],
                          capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    code = proc.returncode
    summary = json.loads(proc.stdout)
    size = (Path(tmp) / "r.parquet").stat().st_size
flagged = {f["unit"] for f in summary["flagged"]}
normal = fleet.units("normal")
RESULTS["run"] = {
    "units": N_RUN, "exit_code": code, "write_s": written, "wall_s": wall, "run_s": summary["seconds"],
    "cluster_start_and_exit_s": wall - summary["seconds"], "engine": summary["engine"], "units_per_task": summary["units_per_task"],
    "status_counts": summary["status_counts"], "failed_listed": len(summary["failed"]),
    "scale_error_flagged": sum(u in flagged for u in fleet.units("scale_error")),
    "normal_flagged": sum(u in flagged for u in normal), "normal_units": len(normal),
    "units_per_s": N_RUN / summary["seconds"], "worker_ms_per_unit": 2 * 1e3 * summary["seconds"] / N_RUN,
    "parquet_bytes": size, "load_average_1min": os.getloadavg()[0],
}
print(json.dumps(RESULTS["run"], indent=1))

# %% [markdown]
# ## 4. Cost of each stage of a unit, in one process
#
# The per-unit CPU time of reading (``optcal.data.load``), the own fit (``optcal calibrate``'s
# code path) and the refit with the prior, on 120 units, and the file size: the inputs of the
# scale plan.

# %%
def per_unit_ms(step, items) -> tuple[float, float]:
    """Wall and CPU milliseconds per item of ``step`` (CPU time does not grow with the machine's load)."""
    w0, c0 = time.perf_counter(), time.process_time()
    for item in items:
        step(*item)
    return ((time.perf_counter() - w0) / len(items) * 1e3, (time.process_time() - c0) / len(items) * 1e3)


with tempfile.TemporaryDirectory() as tmp:
    write_fleet(tmp, full_or_quick(120, 25), SEED + 5, scale_error_units=0, six_face_units=0, unreadable_units=0)
    units = expand_inputs([tmp])
    tables = [read_unit(u, {}) for u in units]
    own = [fit_unit(u, p) for u, p in zip(units, tables)]
    flag_units(own, population_stats(own))
    unit_prior = estimate_prior(own)
    stages = {
        "read": per_unit_ms(read_unit, [(u, {}) for u in units]),
        "fit": per_unit_ms(fit_unit, list(zip(units, tables))),
        "prior_refit": per_unit_ms(refit_unit, [(o, p, unit_prior) for o, p in zip(own, tables)]),
    }
    RESULTS["stages"] = {"wall_ms": {k: v[0] for k, v in stages.items()}, "cpu_ms": {k: v[1] for k, v in stages.items()},
                         "file_bytes": Path(units[0].path).stat().st_size, "load_average_1min": os.getloadavg()[0]}
print(RESULTS["stages"])
(OUT / "fleet_scale.json").write_text(json.dumps(RESULTS, indent=1, default=float))
