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
# # `optcal diagnose` on real sessions: issue 13's acceptance families
#
# Each family has its truth hidden from `diagnose` (the number of seeds is stated in each table):
#
# * two effects at once (a temperature bias on one axis, a drift on another);
# * 20-30-pose sessions (every candidate tested one at a time), with and without an effect;
# * raw 100 Hz recordings whose noise has a Gauss–Markov component at the pose time scale (1 mg,
#   4 s), with and without an effect: the null cases must stay clean, the noise model named;
# * the same kind of recordings read in m/s² instead of counts;
# * effects planted in the real Xsens recording (its own lumped calibration as the base model, a
#   synthetic warm-up/cool-down temperature channel).
#
# Regenerate with `python studies/diagnose_issue13.py` (N13 seeds per family and effect, default 20;
# the committed results state the count they were run with); writes `results/diagnose_issue13.md`.
# A quick run (`OPTCAL_STUDY_QUICK=1`, as CI executes this notebook) runs no seeds and shows the
# last full run's tables.

# %%
import multiprocessing
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from study_mode import QUICK  # noqa: E402
from study_mode import RESULTS as OUT  # noqa: E402
from study_mode import STUDIES as HERE  # noqa: E402

sys.path.insert(0, str(HERE.parent / "tests"))

from diagnosis_cases import make_case  # noqa: E402

from optcal.diagnosis import diagnose  # noqa: E402
from optcal.diagnosis.effects import EFFECTS  # noqa: E402

N13 = int(os.environ.get("N13", "0" if QUICK else "20"))
XSENS = HERE.parents[1] / "shared" / "data" / "imutk-xsens" / "xsens_imutk.csv"


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson 95 % interval of a proportion."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return centre - half, centre + half


def judge_parametric(diag, truths: list[tuple[str, str, float]]) -> dict:
    """Every (effect, axis, value) named on its axis within 30 %, and nothing else named."""
    named = {(f.effect, a): f.estimate[a] for f in diag.findings for a in f.axes}
    hits = [(e, a) in named and abs(named[(e, a)] / v - 1) < 0.3 for e, a, v in truths]
    extra = [k for k in named if k not in {(e, a) for e, a, _ in truths}]
    extra += ["outliers"] if any(f.effect == "outliers" for f in diag.findings) else []
    return {"ok": bool(all(hits) and not extra), "named_all": bool(all((e, a) in named for e, a, _ in truths)),
            "findings": [f.effect for f in diag.findings], "extra": extra}


def run_two_effects(seed: int) -> dict:
    from optcal.extended_model import ExtendedModel
    from optcal.model import lu2017_reference_model
    from optcal.simulate import uniform_directions
    from optcal.simulate_effects import simulate_extended, warmup_cooldown

    rng = np.random.default_rng(seed)
    n = int(rng.integers(60, 121))
    t = np.sort(rng.uniform(0, 1200, n))
    temp = warmup_cooldown(t, 22, 22 + rng.uniform(15, 30), 28)
    a, b = rng.permutation(3)[:2]
    k = rng.choice([-1, 1]) * 0.5e-3 * rng.uniform(1.5, 2.5)
    d = rng.choice([-1, 1]) * 3e-3 * rng.uniform(1.5, 2.5) / 1200
    model = ExtendedModel(lu2017_reference_model(), {"temperature_bias": np.eye(3)[:, [a]] * k,
                                                   "bias_drift": np.eye(3)[:, [b]] * d}, temp_ref=30, t_ref=600)
    poses = simulate_extended(model, uniform_directions(n, rng), rng.uniform(0.2e-3, 0.5e-3), temp=temp, t=t, rng=rng)
    out = judge_parametric(diagnose(poses, simulations=0), [("temperature_bias", "xyz"[a], k), ("bias_drift", "xyz"[b], d)])
    return {**out, "seed": seed, "n": n}


#: The small-session outlier cases: the acceptance's 8 % of the poses (2 of 20-30), and a stress row with
#: 3-4 times that fraction (24-32 %: 5-10 poses, near the breakdown of a 9-parameter fit to 20-30 poses).
OUTLIER_FRACTION_SCALE = {"outliers": (1.0, 1.0), "outliers (24-32 %)": (3.0, 4.0)}


def run_small(args: tuple) -> dict:
    label, seed = args
    effect = "outliers" if label in OUTLIER_FRACTION_SCALE else label
    case = make_case(effect, seed, scale=OUTLIER_FRACTION_SCALE.get(label, (3.0, 4.0)), n_range=(20, 30),
                     sigma_range=(0.2e-3, 0.5e-3))
    diag = diagnose(case.poses, simulations=0)
    if effect is None:
        out = {"ok": not diag.findings, "findings": [f.effect for f in diag.findings]}
    elif effect == "outliers":
        rows = set(next((f.rows for f in diag.findings if f.effect == "outliers"), None) or [])
        truth = set(case.outlier_rows)
        out = {"ok": truth <= rows and len(rows - truth) <= 0.3 * len(truth) and len(diag.findings) == 1,
               "named_all": truth <= rows, "findings": [f.effect for f in diag.findings]}
    else:
        out = judge_parametric(diag, [(effect, case.axis, case.value)])
    limits = [lim.limit for lim in diag.detection_limits if effect and lim.effect == effect and lim.axis == case.axis]
    return {**out, "effect": label or "none", "seed": seed, "n": case.poses.n,
            "limit_over_truth": limits[0] / abs(case.value) if limits and case.value else None}


def recording(effect, seed: int, gauss_markov_g: float, units: str):
    """A raw recording with ``effect`` (or none) and Gauss–Markov noise, read back in ``units``."""
    from optcal.data import load
    from optcal.simulate_effects import recording_with_effect

    frame, truth = recording_with_effect(effect, gauss_markov_g=gauss_markov_g, correlation_s=4.0, seed=seed)
    if units == "m/s^2":  # the demo sensor's nominal 16,384 counts per g, written as m/s²
        for c in ("ax", "ay", "az"):
            frame[c] = frame[c] * 9.80665 / 16384.0
        frame = frame.rename(columns={"ax": "acc_x_mps2", "ay": "acc_y_mps2", "az": "acc_z_mps2"})
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rec.csv"
        frame.to_csv(path, index=False, float_format="%.8g")
        return load(path), truth


def run_coloured(args: tuple) -> dict:
    effect, seed, units = args
    poses, truth = recording(effect, seed, 1e-3, units)
    diag = diagnose(poses, simulations=0)
    nm = diag.noise_model
    out = {"effect": effect or "none", "seed": seed, "units": poses.units, "findings": [f.effect for f in diag.findings],
           "noise_named": bool(nm.named), "chi2_after": nm.reduced_chi2_after}
    if effect in (None, "outliers"):
        out["ok"] = not diag.findings if effect is None else any(f.effect == "outliers" for f in diag.findings)
    else:
        out.update(judge_parametric(diag, [(effect, truth.axis, truth.value)]))
    return out


def run_units(args: tuple) -> dict:
    effect, seed, units = args
    poses, truth = recording(effect, seed, 0.0, units)
    out = judge_parametric(diagnose(poses, simulations=0), [(effect, truth.axis, truth.value)])
    return {**out, "effect": effect, "seed": seed, "units": poses.units}


def run_xsens(args: tuple) -> dict:
    """An effect planted in the real Xsens recording (base: its own lumped calibration; synthetic temperature)."""
    import pandas as pd

    from optcal.calibration import calibrate
    from optcal.data import load
    from optcal.extended_model import ExtendedModel
    from optcal.simulate_effects import distort_recording, warmup_cooldown

    effect, seed = args
    rng = np.random.default_rng(seed)
    raw = pd.read_csv(XSENS).rename(columns={"t_s": "t", "acc_x_counts": "ax", "acc_y_counts": "ay", "acc_z_counts": "az"})
    raw = raw[["t", "ax", "ay", "az"]]
    base = calibrate(load(XSENS), "mle").model
    raw["temp"] = warmup_cooldown(raw["t"].to_numpy(), 22, 22 + rng.uniform(12, 20), 27)
    axis = int(rng.integers(3))
    value = {"temperature_bias": 0.3e-3, "temperature_scale": 200e-6, "bias_drift": 2e-3 / 512,
             "scale_nonlinearity": 3e-3}[effect] * rng.uniform(1.0, 1.5) * rng.choice([-1, 1])
    model = ExtendedModel.with_effect(base, effect, axis, value, temp_ref=30.0, t_ref=256.0)
    frame = distort_recording(raw, model)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "xsens_planted.csv"
        frame.rename(columns={"ax": "acc_x_counts", "ay": "acc_y_counts", "az": "acc_z_counts", "t": "t_s"}).to_csv(
            path, index=False, float_format="%.8g")
        poses = load(path)
    out = judge_parametric(diagnose(poses, simulations=0), [(effect, "xyz"[axis], value)])
    return {**out, "effect": effect, "seed": seed}


def pool_map(fn, jobs):
    # fork: the workers inherit the functions defined here, also when this runs as a notebook
    with ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("fork")) as ex:
        return list(ex.map(fn, jobs, chunksize=2))


# %%
t0 = time.time()
report = ["# `optcal diagnose` on real sessions: issue 13's families", "",
          f"Generated by `studies/diagnose_issue13.py` with the default settings ({N13} seeds per family and effect "
          "unless stated); success = the hidden effect alone named on its axis with the estimate within 30 %.", ""]
# %% [markdown]
# ## 7-11. Issue 13's families

# %%
def rate_line(rows: list[dict], key: str = "ok") -> str:
    k = sum(bool(r[key]) for r in rows)
    lo, hi = wilson(k, len(rows))
    return f"{k}/{len(rows)} = {100 * k / max(len(rows), 1):.0f} % (95 % interval {100 * lo:.0f}-{100 * hi:.0f} %)"

two = pool_map(run_two_effects, [3000 + s for s in range(N13)])
report += ["## 7. Two effects at once", "",
           f"A temperature bias (0.75-1.25 mg/°C) on one axis and a drift (4.5-7.5 mg over 20 min) on another, 60-120 "
           f"poses, 0.2-0.5 mg, {N13} seeds: both named on their axes within 30 %, nothing else: **{rate_line(two)}**; "
           f"both named: {rate_line(two, 'named_all')}.", ""]
small = pool_map(run_small, [(e, 4000 + s) for e in (None, *EFFECTS) for s in range(N13)])
report += ["## 8. Small sessions: 20-30 poses", "",
           f"3-4× the smallest acceptance magnitudes, 0.2-0.5 mg, {N13} seeds per effect; every candidate tested one at a "
           "time (each test keeps 10 degrees of freedom).", "",
           "| hidden | sessions | success (alone, axis, 30 %; none: no finding) | named | median detection limit / truth |",
           "|---|---|---|---|---|"]
for effect in ("none", *EFFECTS):
    rs = [r for r in small if r["effect"] == effect]
    ratios = [r["limit_over_truth"] for r in rs if r.get("limit_over_truth") is not None]
    report.append(f"| {effect} | {len(rs)} | {rate_line(rs)} | "
                  f"{rate_line(rs, 'named_all') if effect != 'none' else '—'} | "
                  f"{np.median(ratios):.2f} |" if ratios else f"| {effect} | {len(rs)} | {rate_line(rs)} | "
                  f"{rate_line(rs, 'named_all') if effect != 'none' else '—'} | — |")
report.append("")
coloured = pool_map(run_coloured, [(e, 5000 + s, "counts") for e in (None, *EFFECTS) for s in range(N13)])
report += ["## 9. Raw 100 Hz recordings with Gauss–Markov noise at the pose time scale (1 mg, 4 s)", "",
           "| hidden | recordings | success (effect alone, axis, 30 %; null: no finding) | noise model named | "
           "reduced χ² after (median) |", "|---|---|---|---|---|"]
for effect in ("none", *EFFECTS):
    rs = [r for r in coloured if r["effect"] == effect]
    report.append(f"| {effect} | {len(rs)} | {rate_line(rs)} | {sum(r['noise_named'] for r in rs)} | "
                  f"{np.median([r['chi2_after'] for r in rs]):.2f} |")
report.append("")
units = pool_map(run_units, [(e, 6000 + s, u) for e in EFFECTS[:4] for s in range(N13 // 2) for u in ("counts", "m/s^2")])
report += ["## 10. Counts and m/s² inputs (the same recordings read in either unit)", "",
           "| effect | counts | m/s² |", "|---|---|---|"]
for effect in EFFECTS[:4]:
    cells = [rate_line([r for r in units if r["effect"] == effect and r["units"] == u]) for u in ("counts", "m/s^2")]
    report.append(f"| {effect} | {cells[0]} | {cells[1]} |")
report.append("")
if XSENS.exists():
    xs = pool_map(run_xsens, [(e, 7000 + s) for e in EFFECTS[:4] for s in range(N13 // 2)])
    report += ["## 11. Effects planted in the real Xsens recording", "",
               "Base model: the recording's own maximum-likelihood calibration; synthetic warm-up/cool-down "
               "temperature channel; 0.3-0.45 mg/°C, 200-300 ppm/°C, 2-3 mg drift over 512 s, 3-4.5 mg/g²; the "
               "recording's own noise (its unexplained z wander and excess scatter stay in).", "",
               "| effect | recordings | success (named alone, axis, 30 %) | named |", "|---|---|---|---|"]
    for effect in EFFECTS[:4]:
        rs = [r for r in xs if r["effect"] == effect]
        report.append(f"| {effect} | {len(rs)} | {rate_line(rs)} | {rate_line(rs, 'named_all')} |")
    report.append("")
report += ["", f"Run time {time.time() - t0:.0f} s.", ""]
if N13:
    (OUT / "diagnose_issue13.md").write_text("\n".join(report))
    print("\n".join(report))

# %% [markdown]
# ## The full run's tables

# %%
if QUICK:
    print((HERE / "results" / "diagnose_issue13.md").read_text())
