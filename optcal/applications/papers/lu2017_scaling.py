"""Lu 2017 at scale: the exact ML (eq. 8) against the norm-residual ML (eq. 13-14) from 10² to 10⁶ poses.

Directions uniform on the sphere (one fixed draw per size), Lu 2017's sensor, 5 mg per pose; per
size a Monte Carlo of complete fits (``calibrate``) by:

* ``mle`` — the norm-residual ML (eq. 14), the exact ML's start;
* ``exact`` — eq. 8 by variable projection (:mod:`optcal.families.accel.exact_profile`), the default;
* ``exact-full`` — eq. 8 as the 9 + 3n-variable NLP in IPOPT, up to :data:`FULL_NLP_MAX_POSES`
  (its answer compared with ``exact``'s run by run: the same optimum);
* ``exact-corrected`` — the curvature-corrected score (eq. 8's residuals less their second-order
  mean), which removes the O(σ²) bias that eq. 8's ML keeps at any n (Neyman–Scott: one latent
  direction per pose).

For each: Σ MSE / Σ CRLB (with its Monte Carlo standard error, from the per-run ratios), the bias
of each parameter in standard deviations of the bound (Monte Carlo standard error ``1/√runs``),
failures and the median time of a complete fit (validation, start, covariance included).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from optcal.core.jsonio import jsonable
from optcal.core.model import PARAM_NAMES
from optcal.errors import ConvergenceWarning, OptcalError
from optcal.families.accel.calibration import calibrate
from optcal.applications.papers.solver_study import uniform_design

#: Noise per pose of the study, g (the solver study's size sweep).
SIGMA = 0.005
#: The full NLP runs up to this many poses (about 5 s to build and 1 s to solve at 10⁴; a minute at 10⁵).
FULL_NLP_MAX_POSES = 10_000
#: method -> calibrate() settings.
METHODS: dict[str, dict[str, Any]] = {
    "mle": {"method": "mle"},
    "exact": {"method": "exact"},
    "exact-full": {"method": "exact", "formulation": "full"},
    "exact-corrected": {"method": "exact", "curvature_correction": True},
}


@dataclass(frozen=True)
class ScalingPlan:
    """Sizes and Monte Carlo runs per size (full or quick)."""

    runs: dict[int, int]
    full_nlp_max: int

    @classmethod
    def make(cls, quick: bool) -> "ScalingPlan":
        if quick:
            return cls({100: 40, 1000: 20, 10_000: 5}, 1000)
        return cls({100: 400, 1000: 200, 10_000: 100, 100_000: 40, 1_000_000: 10}, FULL_NLP_MAX_POSES)


def size_point(n: int, runs: int, seed: int, full_nlp: bool, progress: bool = False) -> dict[str, Any]:
    """Every method on ``runs`` pose tables of ``n`` uniform poses."""
    from tqdm import tqdm

    design = uniform_design(n, SIGMA, seed)
    crlb = np.diag(design.crlb())
    truth = design.model.theta
    methods = [m for m in METHODS if m != "exact-full" or full_nlp]
    errors: dict[str, list[np.ndarray]] = {m: [] for m in methods}
    times: dict[str, list[float]] = {m: [] for m in methods}
    failures: dict[str, int] = {m: 0 for m in methods}
    same_optimum_se: list[float] = []
    for run in tqdm(range(runs), desc=f"lu2017 scaling, {n} poses", disable=not progress, leave=False):
        poses = design.poses(seed, run)
        fits: dict[str, Any] = {}
        for m in methods:
            t0 = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", ConvergenceWarning)
                    res = calibrate(poses, **METHODS[m])
            except OptcalError:
                failures[m] += 1
                continue
            elapsed = time.perf_counter() - t0
            if not res.solver.success:
                failures[m] += 1
                continue
            fits[m] = res
            errors[m].append(res.params[:9] - truth)
            times[m].append(elapsed)
        if "exact" in fits and "exact-full" in fits:
            se = np.sqrt(np.diag(fits["exact-full"].covariance))
            same_optimum_se.append(float(np.max(np.abs(fits["exact"].params - fits["exact-full"].params) / se)))
    out: dict[str, Any] = {}
    for m in methods:
        e = np.array(errors[m])
        entry: dict[str, Any] = {"runs": len(e), "failures": failures[m]}
        if len(e):
            per_run = np.sum(e**2, axis=1) / np.sum(crlb)
            bias = e.mean(axis=0) / np.sqrt(crlb)
            entry.update({
                "efficiency": float(per_run.mean()),
                "efficiency_mc_se": float(per_run.std(ddof=1) / np.sqrt(len(e))) if len(e) > 1 else None,
                "bias_over_crlb_sd": dict(zip(PARAM_NAMES, bias)),
                "max_abs_bias_over_crlb_sd": float(np.max(np.abs(bias))),
                "bias_mc_se": float(1.0 / np.sqrt(len(e))),
                "median_time_s": float(np.median(times[m])),
            })
        out[m] = entry
    return {
        "n_poses": n,
        "runs": runs,
        "sigma_g": SIGMA,
        "crlb_sd": dict(zip(PARAM_NAMES, np.sqrt(crlb))),
        "methods": out,
        "exact_vs_full_max_difference_in_stderr": max(same_optimum_se) if same_optimum_se else None,
    }


def scaling(quick: bool = False, seed: int = 0, progress: bool = True) -> dict[str, Any]:
    """The study over sizes (module docstring); JSON-safe."""
    plan = ScalingPlan.make(quick)
    t0 = time.perf_counter()
    points = [size_point(n, r, seed, n <= plan.full_nlp_max, progress) for n, r in plan.runs.items()]
    return jsonable({"quick": quick, "seed": seed, "design": f"uniform directions, Lu 2017's sensor, {SIGMA * 1e3:g} mg",
                     "points": points, "runtime_s": time.perf_counter() - t0})


def format_scaling(res: dict[str, Any]) -> str:
    """The study as a table."""
    methods = list(METHODS)
    head = f"  {'poses':>9s} {'runs':>5s} " + " ".join(f"{m:>24s}" for m in methods)
    lines = [f"Exact ML at scale ({res['design']}): Σ MSE / Σ CRLB ± MC s.e. [max |bias|/sd] median time",
             head]
    for p in res["points"]:
        cells = []
        for m in methods:
            r = p["methods"].get(m)
            if r is None:
                cells.append(f"{'not run':>24s}")
            elif "efficiency" not in r:
                cells.append(f"{'failed ' + str(r['failures']):>24s}")
            else:
                se = r["efficiency_mc_se"]
                cells.append(f"{r['efficiency']:5.2f}±{se if se is not None else float('nan'):4.2f} "
                             f"[{r['max_abs_bias_over_crlb_sd']:4.1f}] {r['median_time_s']:6.3f}s")
        lines.append(f"  {p['n_poses']:9d} {p['runs']:5d} " + " ".join(cells))
        if p["exact_vs_full_max_difference_in_stderr"] is not None:
            lines.append(f"  {'':9s} {'':5s} exact (profile) vs exact-full: max |Δθ| = "
                         f"{p['exact_vs_full_max_difference_in_stderr']:.1e} standard errors")
    lines.append(f"  runtime {res['runtime_s']:.0f} s")
    return "\n".join(lines)


__all__ = ["FULL_NLP_MAX_POSES", "METHODS", "SIGMA", "ScalingPlan", "format_scaling", "scaling", "size_point"]
