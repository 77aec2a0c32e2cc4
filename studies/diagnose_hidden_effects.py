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
# # `optcal diagnose` finds hidden effects: two at once, small sessions, correlated noise, counts, the real Xsens log
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
# Regenerate with `python studies/diagnose_hidden_effects.py` (N13 seeds per family and effect, default 20;
# the committed results state the count they were run with); writes `results/diagnose_hidden_effects.md`.
# A quick run (`OPTCAL_STUDY_QUICK=1`, as CI executes this notebook) runs no seeds and shows the
# last full run's tables.

# %%
import functools
import multiprocessing
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from study_mode import QUICK, wilson  # noqa: E402
from study_mode import RESULTS as OUT  # noqa: E402
from study_mode import STUDIES as HERE  # noqa: E402

sys.path.insert(0, str(HERE.parent / "tests"))

from helpers.diagnosis_cases import make_case  # noqa: E402

from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings, diagnose  # noqa: E402
from optcal.applications.diagnosis.effects import EFFECTS  # noqa: E402
from optcal.core.extended_model import format_value  # noqa: E402

N13 = int(os.environ.get("N13", "0" if QUICK else "20"))
#: Seeds of the cells that passed at 100 % in the last run or are at their detection limit by construction
#: (the Gauss–Markov rows at the demo's sizes, counts and m/s²): half as many, to keep the run under 40 min.
N13_LIGHT = max(N13 // 2, min(N13, 1))
#: The families to run (``N13_FAMILIES=gm,xsens``: a part of the study, e.g. on a shared machine) and the file
#: the results go to (``N13_OUT``, in results/).
FAMILIES = os.environ.get("N13_FAMILIES", "two,small,gm,xsens,units").split(",")
RESULT_NAME = os.environ.get("N13_OUT", "diagnose_hidden_effects.md")
XSENS = HERE.parents[1] / "shared" / "data" / "imutk-xsens" / "xsens_imutk.csv"
#: Smallest planted magnitude in the Xsens recording (drawn up to 1.5×): mg/°C, ppm/°C, g/s (2 mg over 512 s), g/g².
XSENS_MAGNITUDE = {"temperature_bias": 0.3e-3, "temperature_scale": 200e-6, "bias_drift": 2e-3 / 512,
                   "scale_nonlinearity": 3e-3}


def limit_of(diag, effect: str | None, axis: str | None) -> float | None:
    """``diagnose``'s own detection limit for ``effect`` on ``axis``: the reported one, or, when the term
    entered the model, the same quantile times its standard error."""
    from scipy import stats as sps

    if effect is None or axis is None:
        return None
    for lim in diag.detection_limits:
        if lim.effect == effect and lim.axis == axis:
            return lim.limit
    levels = [lim.level for lim in diag.detection_limits]
    for f in diag.findings:
        if f.effect == effect and axis in f.stderr and levels:
            return float(sps.norm.isf(levels[0] / 2)) * f.stderr[axis]
    return None


def named_terms(diag) -> set:
    """``(effect, axis)`` of every finding (``("outliers", None)`` for outlier poses)."""
    return {(f.effect, a) for f in diag.findings for a in f.axes} | (
        {("outliers", None)} if any(f.effect == "outliers" for f in diag.findings) else set())


def judge_parametric(diag, truths: list[tuple[str, str, float]], own: set | None = None) -> dict:
    """Every (effect, axis, value) named on its axis within 30 %, and nothing else named.

    ``own``: the findings of the same recording without the planted effect (a real recording has
    its own); those may be named again and do not count against the planted effect.
    """
    named = {(f.effect, a): f.estimate[a] for f in diag.findings for a in f.axes}
    hits = [(e, a) in named and abs(named[(e, a)] / v - 1) < 0.3 for e, a, v in truths]
    allowed = {(e, a) for e, a, _ in truths} | (own or set())
    extra = sorted((k for k in named_terms(diag) if k not in allowed), key=str)
    return {"ok": bool(all(hits) and not extra), "hits": bool(all(hits)), "named_all": bool(all((e, a) in named for e, a, _ in truths)),
            "findings": sorted(named_terms(diag), key=str), "extra": extra,
            "estimates": {f"{e}({a})": named.get((e, a)) for e, a, _ in truths}}


def run_two_effects(seed: int) -> dict:
    from optcal.core.extended_model import ExtendedModel
    from optcal.core.model import lu2017_reference_model
    from optcal.families.simulate.poses import uniform_directions
    from optcal.families.simulate.effects import simulate_extended, warmup_cooldown

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
        out = {"ok": not diag.findings, "findings": sorted(named_terms(diag), key=str)}
    elif effect == "outliers":
        rows = set(next((f.rows for f in diag.findings if f.effect == "outliers"), None) or [])
        truth = set(case.outlier_rows)
        out = {"ok": truth <= rows and len(rows - truth) <= 0.3 * len(truth) and len(diag.findings) == 1,
               "named_all": truth <= rows, "findings": sorted(named_terms(diag), key=str),
               "outlier_rows": sorted(rows), "truth_rows": sorted(truth)}
    else:
        out = judge_parametric(diag, [(effect, case.axis, case.value)])
    limit = limit_of(diag, effect, case.axis)
    if effect == "outliers":  # the outlier test's own limit for the weakest planted outlier
        limit = max(outlier_limit_over_truth(case))
        return {**out, "effect": label, "seed": seed, "n": case.poses.n, "limit_over_truth": limit}
    return {**out, "effect": label or "none", "seed": seed, "n": case.poses.n,
            "limit_over_truth": limit / abs(case.value) if limit and case.value else None}


def outlier_limit_over_truth(case) -> list[float]:
    """For each planted outlier: the outlier test's detection limit at its pose (the planted outliers set
    aside, as the deleted-residual test has them) over what its shift changes the pose's calibrated norm by
    under the true sensor (Lu 2017, eq. 5: the only part of the shift the norm residual sees)."""
    from optcal.applications.diagnosis import Diagnoser
    from optcal.applications.diagnosis.limits import pose_outlier_limits
    from optcal.core.model import lu2017_reference_model

    true = lu2017_reference_model()
    diagnoser = Diagnoser()
    fitter, _ = diagnoser.prepare(case.poses)
    ratios = []
    fit = fitter.fit({}, frozenset(case.outlier_rows), fitter.x_start)
    limits = pose_outlier_limits(fitter, fit, diagnoser.settings.alpha / 2, np.array(case.outlier_rows))
    for k, shift, limit in zip(case.outlier_rows, case.outlier_shifts, limits):
        a = case.poses.acc[k]
        change = np.linalg.norm(true.correct(a)) - np.linalg.norm(true.correct(a - shift))
        ratios.append(float(limit / abs(change)))
    return ratios


def recording(effect, seed: int, gauss_markov_g: float, units: str, value: float | None = None):
    """A raw recording with ``effect`` (or none) and Gauss–Markov noise, read back in ``units`` as the command
    reads it (with its static detection, whose still parts give the measured route of the noise model).

    ``value``: the effect's size (default: the demo's); its sign is drawn from the seed.
    """
    from optcal.data import load_with_segmentation
    from optcal.families.simulate.effects import recording_with_effect

    if value is not None:
        value *= float(np.random.default_rng(seed + 10**6).choice([-1.0, 1.0]))
    frame, truth = recording_with_effect(effect, value=value, gauss_markov_g=gauss_markov_g, correlation_s=4.0,
                                         seed=seed)
    if units == "m/s^2":  # the demo sensor's nominal 16,384 counts per g, written as m/s²
        for c in ("ax", "ay", "az"):
            frame[c] = frame[c] * 9.80665 / 16384.0
        frame = frame.rename(columns={"ax": "acc_x_mps2", "ay": "acc_y_mps2", "az": "acc_z_mps2"})
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rec.csv"
        frame.to_csv(path, index=False, float_format="%.8g")
        return load_with_segmentation(path), truth


def diagnose_recording(loaded):
    """``optcal diagnose`` on a raw recording: the poses with the still parts of the recording."""
    return Diagnoser(DiagnosisSettings(simulations=0)).run(loaded.poses, still_parts=loaded.segmentation)


def coverage(diag, poses) -> tuple[float, float]:
    """Fraction of the nominal 95 % intervals of the nine calibration parameters (T and o; standard errors
    with the noise scale from the residuals) that cover the truth (the demo sensor), with the pose
    correlation `diagnose` estimated, and as if the poses were independent."""
    from scipy import stats as sps

    from optcal.applications.diagnosis.fitting import Fitter
    from optcal.core.model import theta_from
    from optcal.families.simulate.effects import demo_sensor

    truth, base = demo_sensor(), diag.model.base
    z = float(sps.norm.isf(0.025))
    out = []
    for correlation in (diag.noise_model.correlation.operator, None):
        fitter = Fitter(poses, diag.regressors, base.T_canonical, base.o, 2, correlation=correlation)
        fit = fitter.fit(diag.final.terms, diag.final.outliers, diag.final.x)
        se = np.sqrt(np.maximum(np.diag(fitter.covariance(fit))[:9], 0.0))
        error = np.abs(fit.x[:9] - fitter.norm.theta_to_normalised(theta_from(truth.T_canonical, truth.o)))
        out.append(float(np.mean(error < z * se)))
    return out[0], out[1]


def run_coloured(args: tuple) -> dict:
    effect, seed, units, value = args
    loaded, truth = recording(effect, seed, 1e-3, units, value)
    diag = diagnose_recording(loaded)
    nm = diag.noise_model
    out = {"effect": effect or "none", "seed": seed, "units": loaded.poses.units,
           "findings": sorted(named_terms(diag), key=str), "noise_named": bool(nm.named),
           "chi2_after": nm.reduced_chi2_after, "scaled": value is not None,
           "correlation_used": bool(nm.correlation is not None and nm.correlation.used),
           "neighbour_rho": nm.correlation.neighbour_rho if nm.correlation is not None else 0.0,
           "limits": {f"{lim.effect}({lim.axis})": lim.limit for lim in diag.detection_limits}}
    if effect in (None, "outliers"):
        out["ok"] = not diag.findings if effect is None else named_terms(diag) == {("outliers", None)}
        if effect is None:
            out["coverage"], out["coverage_independent"] = coverage(diag, loaded.poses)
    else:
        out.update(judge_parametric(diag, [(effect, truth.axis, truth.value)]))
        limit = limit_of(diag, effect, truth.axis)
        out["limit_over_truth"] = limit / abs(truth.value) if limit else None
    return out


def run_units(args: tuple) -> dict:
    effect, seed, units = args
    loaded, truth = recording(effect, seed, 0.0, units)
    out = judge_parametric(diagnose_recording(loaded), [(effect, truth.axis, truth.value)])
    return {**out, "effect": effect, "seed": seed, "units": loaded.poses.units}


@functools.lru_cache(maxsize=1)
def xsens_base():
    """The Xsens samples (t, ax, ay, az) and the recording's own lumped maximum-likelihood model (read once per process)."""
    import pandas as pd

    from optcal.families.accel.calibration import calibrate
    from optcal.data import load

    raw = pd.read_csv(XSENS).rename(columns={"t_s": "t", "acc_x_counts": "ax", "acc_y_counts": "ay", "acc_z_counts": "az"})
    return raw[["t", "ax", "ay", "az"]], calibrate(load(XSENS), "mle").model


def run_xsens(args: tuple) -> dict:
    """An effect (or, with ``None``, nothing) planted in the real Xsens recording (base: its own lumped
    calibration; a synthetic temperature channel drawn from the seed, the same with and without the effect).

    ``own``: the findings of the same seed without the effect (``None`` for the unplanted run itself).
    """
    from optcal.data import load
    from optcal.core.extended_model import ExtendedModel
    from optcal.families.simulate.effects import distort_recording, warmup_cooldown

    effect, seed, own = args
    rng = np.random.default_rng(seed)
    raw, base = xsens_base()
    raw = raw.copy()
    raw["temp"] = warmup_cooldown(raw["t"].to_numpy(), 22, 22 + rng.uniform(12, 20), 27)
    axis = int(rng.integers(3))
    value = XSENS_MAGNITUDE[effect or "bias_drift"] * rng.uniform(1.0, 1.5) * rng.choice([-1, 1])
    model = (ExtendedModel(base, temp_ref=30.0, t_ref=256.0) if effect is None else
             ExtendedModel.with_effect(base, effect, axis, value, temp_ref=30.0, t_ref=256.0))
    frame = distort_recording(raw, model)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "xsens_planted.csv"
        frame.rename(columns={"ax": "acc_x_counts", "ay": "acc_y_counts", "az": "acc_z_counts", "t": "t_s"}).to_csv(
            path, index=False, float_format="%.8g")
        poses = load(path)
    diag = diagnose(poses, simulations=0)
    if effect is None:
        return {"effect": "none", "seed": seed, "findings": sorted(named_terms(diag), key=str), "own": named_terms(diag),
                "ok": True}
    out = judge_parametric(diag, [(effect, "xyz"[axis], value)], own)
    # The recording's own effects have no known cause.  An extra finding is the recording's own effect under
    # its other name when the report's temperature-or-time decision on that axis names the unplanted
    # diagnosis's term as the rival it could not tell apart from the one kept.
    declared = {(d.chosen, d.axis) for d in diag.decisions if (d.other, d.axis) in own}
    out["ok_up_to_declared"] = bool(out["ok"] or (out["hits"] and set(map(tuple, out["extra"])) <= declared))
    limit = limit_of(diag, effect, "xyz"[axis])
    return {**out, "effect": effect, "seed": seed, "own": sorted(own, key=str),
            "limit_over_truth": limit / abs(value) if limit else None}


def pool_map(fn, jobs):
    # fork: the workers inherit the functions defined here, also when this runs as a notebook
    with ProcessPoolExecutor(max_workers=int(os.environ.get("N13_WORKERS", "2")), mp_context=multiprocessing.get_context("fork")) as ex:
        return list(ex.map(fn, jobs, chunksize=2))


# %%
t0 = time.time()
report = ["# `optcal diagnose` on real sessions: issue 13's families", "",
          f"Generated by `studies/diagnose_hidden_effects.py` with the default settings ({N13} seeds per family cell unless "
          f"stated; `N13={N13} nice -n 10 python studies/diagnose_hidden_effects.py`); success = the hidden effect named on its "
          "axis with the estimate within 30 % and nothing else named (on the real recording: nothing the recording "
          "without the planted effect does not already show); null = no finding.  Rates with their Wilson 95 % "
          "interval.  Effect sizes are stated against the detection limit `diagnose` itself reports "
          "(`limit / truth`: the limit is the coefficient the selection's test finds half the time; the 30 % "
          "criterion is attainable at 95 % from about 1.9× the limit, where 30 % of the truth is 1.96 standard "
          "errors: 0.3 · 1.9 · 3.45 SE ≈ 1.96 SE).", ""]
# %% [markdown]
# ## 7-11. Issue 13's families

# %%
def rate_line(rows: list[dict], key: str = "ok") -> str:
    k = sum(bool(r[key]) for r in rows)
    lo, hi = wilson(k, len(rows))
    return f"{k}/{len(rows)} = {100 * k / max(len(rows), 1):.0f} % (95 % interval {100 * lo:.0f}-{100 * hi:.0f} %)"


def median_ratio(rows: list[dict]) -> str:
    ratios = [r["limit_over_truth"] for r in rows if r.get("limit_over_truth") is not None]
    return f"{np.median(ratios):.2f}" if ratios else "—"


def failures(title: str, rows: list[dict]) -> list[str]:
    """The failing seeds with what `diagnose` named (the evidence for the causes stated below each table)."""
    bad = [r for r in rows if not r["ok"]]
    if not bad:
        return []
    lines = [f"<details><summary>{title}: the {len(bad)} failing cases</summary>", ""]
    for r in bad:
        est = ", ".join(f"{k} = {v:.3g}" for k, v in (r.get("estimates") or {}).items() if v is not None)
        extra = f"; extra {r['extra']}" if r.get("extra") else ""
        rows_txt = (f"; outlier rows {r['outlier_rows']} (truth {r['truth_rows']}; the weakest at "
                    f"{1 / r['limit_over_truth']:.2g}× its limit)" if "truth_rows" in r else "")
        lines.append(f"- {r['effect']} seed {r['seed']}: named {r['findings']}{extra}{rows_txt}"
                     + (f"; estimate {est}" if est else ""))
    return lines + ["", "</details>", ""]


def save() -> None:
    """Write what has been run so far (a run cut short leaves its finished families)."""
    if N13:
        (OUT / RESULT_NAME).write_text("\n".join(report))


if "two" in FAMILIES:
    two = pool_map(run_two_effects, [3000 + s for s in range(N13)])
    report += ["## 7. Two effects at once", "",
               f"A temperature bias (0.75-1.25 mg/°C) on one axis and a drift (4.5-7.5 mg over 20 min) on another, 60-120 "
               f"poses, 0.2-0.5 mg, {N13} seeds: both named on their axes within 30 %, nothing else: **{rate_line(two)}**; "
               f"both named: {rate_line(two, 'named_all')}.", ""]
    report += failures("two effects", [{**r, "effect": "two effects"} for r in two])
    save()
if "small" in FAMILIES:
    SMALL = ("none", *EFFECTS[:4], "outliers", "outliers (24-32 %)")
    small = pool_map(run_small, [(None if e == "none" else e, 4000 + s) for e in SMALL for s in range(N13)])
    report += ["## 8. Small sessions: 20-30 poses", "",
               f"3-4× the smallest acceptance magnitudes, 0.2-0.5 mg, {N13} seeds per effect; every candidate tested one at a "
               "time (each test keeps 10 degrees of freedom).  Outliers: the acceptance's 8 % of the poses (2 of 20-30, "
               "10-40 σ off), and a stress row with 3-4 times that fraction (24-32 %: 5-10 poses, near the breakdown "
               "of a 9-parameter fit to 20-30 poses); success there: every outlier pose named, at most 30 % more.", "",
               "| hidden | sessions | success (alone, axis, 30 %; none: no finding) | named | median detection limit / truth |",
               "|---|---|---|---|---|"]
    for effect in SMALL:
        rs = [r for r in small if r["effect"] == effect]
        report.append(f"| {effect} | {len(rs)} | {rate_line(rs)} | "
                      f"{rate_line(rs, 'named_all') if effect != 'none' else '—'} | {median_ratio(rs)} |")
    report.append("")
    for label in OUTLIER_FRACTION_SCALE:
        rs = [r for r in small if r["effect"] == label]
        above = [r for r in rs if r["limit_over_truth"] <= 1 / 1.5]
        report.append(f"* {label}: the weakest planted outlier's part along its pose's direction is at least 1.5× the "
                      f"outlier test's own limit at that pose (the planted outliers set aside, as the test has them) in {len(above)} of {len(rs)} "
                      f"sessions; success among those {rate_line(above)}, among the others "
                      f"{rate_line([r for r in rs if r not in above])}.")
    report.append("")
    report += failures("small sessions", small)
    save()
if "gm" in FAMILIES:
    coloured_null = pool_map(run_coloured, [(None, 5000 + s, "counts", None) for s in range(N13)])
    gm_limit = {e: float(np.median([v for r in coloured_null for k, v in r["limits"].items() if k.startswith(e + "(")]))
                if coloured_null else float("nan") for e in EFFECTS[:4]}
    scaled = pool_map(run_coloured, [(e, 5000 + s, "counts", 3 * gm_limit[e]) for e in EFFECTS[:4] for s in range(N13)])
    coloured = coloured_null + pool_map(run_coloured, [(e, 5000 + s, "counts", None) for e in EFFECTS
                                                       for s in range(N13_LIGHT)])
    report += ["## 9. Raw 100 Hz recordings with Gauss–Markov noise at the pose time scale (1 mg, 4 s)", "",
               f"48 poses of 4 s (4 mg white noise per sample); {N13} null recordings; the demo's effect sizes (0.8 mg/°C, "
               f"400 ppm/°C, 5 mg over the recording, 6 mg/g², 3 outlier poses; {N13_LIGHT} seeds each), and each "
               f"parametric effect again ({N13} seeds each) at 3× the median detection "
               "limit `diagnose` reports on the null recordings of this family (" + ", ".join(
                   f"{e} {format_value(e, gm_limit[e]).lstrip('+')}" for e in EFFECTS[:4]) + ").  Diagnosed as "
               "`optcal diagnose FILE` does (with the recording's still parts: the measured noise route).  The "
               "pose noise is correlated between neighbouring poses; `diagnose` estimates that correlation and "
               "tests under it (generalised least squares), so its detection limits are the honest ones under "
               "the correlation (a limit computed as if the poses were independent overstates the power): the "
               "demo's sizes are 1.5-3.5× these limits, and `3× limit` means 3× the honest limit.", "",
               "| hidden | size | recordings | success (effect alone, axis, 30 %; null: no finding) | median detection "
               "limit / truth | noise model named | correlation used (median neighbour ρ) | reduced χ² after (median) |",
               "|---|---|---|---|---|---|---|---|"]
    for effect in ("none", *EFFECTS):
        for label, rows in (("demo", coloured), ("3× limit", scaled)):
            rs = [r for r in rows if r["effect"] == effect]
            if rs:
                report.append(f"| {effect} | {label if effect not in ('none', 'outliers') else '—'} | {len(rs)} | "
                              f"{rate_line(rs)} | {median_ratio(rs)} | {sum(r['noise_named'] for r in rs)} | "
                              f"{sum(r['correlation_used'] for r in rs)} ({np.median([r['neighbour_rho'] for r in rs]):.2f}) | "
                              f"{np.median([r['chi2_after'] for r in rs]):.2f} |")
    if coloured_null:
        chi2s = np.array([r["chi2_after"] for r in coloured_null])
        cover = np.array([r["coverage"] for r in coloured_null])
        cover_white = np.array([r["coverage_independent"] for r in coloured_null])
        report += ["", "**The noise-model explanation on the null recordings** (issue 13's acceptance line: reduced χ² after "
                   "the extension within [0.7, 1.5], standard-error coverage within 5 points of nominal): reduced χ² after "
                   f"the extension within [0.7, 1.5] on {int(np.sum((chi2s >= 0.7) & (chi2s <= 1.5)))}/{len(chi2s)} recordings "
                   f"(median {np.median(chi2s):.2f}, range {chi2s.min():.2f}-{chi2s.max():.2f}); coverage of the nominal 95 % "
                   f"intervals of the nine calibration parameters (T and o, standard errors with the noise scale from the "
                   f"residuals) against the true sensor, over the {len(cover)} recordings × 9 parameters: "
                   f"**{100 * cover.mean():.1f} %** with the pose correlation `diagnose` estimated, "
                   f"{100 * cover_white.mean():.1f} % as if the poses were independent (Monte Carlo over the family's "
                   f"recordings, the truth known; binomial standard error ≈ {100 * np.sqrt(0.95 * 0.05 / max(cover.size * 9, 1)):.1f} "
                   "points, the nine parameters of one recording not independent).", ""]
    report += failures("Gauss–Markov recordings", coloured + scaled)
    save()
if "xsens" in FAMILIES and XSENS.exists():
    own = {r["seed"]: r["own"] for r in pool_map(run_xsens, [(None, 7000 + s, None) for s in range(N13)])}
    xs = pool_map(run_xsens, [(e, 7000 + s, own[7000 + s]) for e in EFFECTS[:4] for s in range(N13)])
    own_counts: dict[str, int] = {}
    for terms in own.values():
        for e, a in terms:
            key = f"{e}({a})" if a else e
            own_counts[key] = own_counts.get(key, 0) + 1
    report += ["## 11. Effects planted in the real Xsens recording", "",
               "Base model: the recording's own maximum-likelihood calibration; a synthetic warm-up/cool-down "
               "temperature channel drawn from the seed; 0.3-0.45 mg/°C, 200-300 ppm/°C, 2-3 mg drift over 512 s, "
               "3-4.5 mg/g²; the recording's own noise stays in.  The recording has findings of its own: the same "
               f"seeds without a planted effect name {', '.join(f'{k} ({v}/{len(own)})' for k, v in sorted(own_counts.items())) or 'nothing'}. "
               "A planted effect is judged against that unplanted diagnosis of the same seed (same temperature "
               "channel): named on its axis within 30 %, and nothing named that the unplanted recording does not "
               "show.  (Judged as \"named alone\", a real recording with its own findings could never pass.)  The "
               "recording's own effects have no known cause, and a synthetic temperature channel can be collinear "
               "with them: the next column also counts as a success a case whose only extra is the recording's own "
               "effect under the other name of a temperature-or-time decision the report states (the unplanted "
               "diagnosis's term named as the rival the data could not tell apart from the one kept).", "",
               "| effect | recordings | success (named on its axis, 30 %, nothing new) | success, own effect under "
               "its declared other name | named | median detection limit / truth |", "|---|---|---|---|---|---|"]
    for effect in EFFECTS[:4]:
        rs = [r for r in xs if r["effect"] == effect]
        report.append(f"| {effect} | {len(rs)} | {rate_line(rs)} | {rate_line(rs, 'ok_up_to_declared')} | "
                      f"{rate_line(rs, 'named_all')} | {median_ratio(rs)} |")
    report.append("")
    report += failures("Xsens", xs)
    save()
if "units" in FAMILIES:
    units = pool_map(run_units, [(e, 6000 + s, u) for e in EFFECTS[:4] for s in range(N13_LIGHT) for u in ("counts", "m/s^2")])
    report += ["## 10. Counts and m/s² inputs (the same recordings read in either unit)", "",
               f"White noise, the demo's effect sizes, {N13_LIGHT} recordings per effect, each read in both units.", "",
               "| effect | counts | m/s² |", "|---|---|---|"]
    for effect in EFFECTS[:4]:
        cells = [rate_line([r for r in units if r["effect"] == effect and r["units"] == u]) for u in ("counts", "m/s^2")]
        report.append(f"| {effect} | {cells[0]} | {cells[1]} |")
    report.append("")
    report += failures("counts and m/s²", units)
    save()
report += [
    "## Why the failing families failed, and what changed", "",
    "Measured on the failing seeds' diagnoses (their candidates, p values and levels printed), main at abf7ae9 "
    "against this engine, 40 seeds each (`diagnose(poses, simulations=0)` on the cases of this script).", "",
    "* **Outliers in 20-30-pose sessions (1/10).** The family planted 3-4× the acceptance's 8 % *fraction*: 24-32 % "
    "of the poses (5-10 of 20-30) off. A larger fraction is not a larger effect but a harder one: the least-squares "
    "baseline is bent by the outlier poses, which mask each other (2-4 σ under the baseline instead of 10-40 σ), and "
    "the Cauchy fit started there found 3 of 7 or none. Two causes, two changes. (1) The family: the acceptance's "
    "outlier magnitude is 8 % of the poses; the row `outliers` now plants that (2 of 20-30, 10-40 σ; main: 38/40, "
    "as this engine), and 24-32 % stays as a stress row. (2) The method had no high-breakdown start: the outlier "
    "search now starts from least trimmed squares (concentration steps from the best of 500 elemental quadrics "
    "through 9 poses, Sampson distance), then the Cauchy M-step, then the exact deleted-residual test "
    "(stress row: main 4/40, this engine in the table). The robust scales now count the nine fitted "
    "parameters' degrees of freedom (√(m/(m−p)): at 21 poses the median scale was 0.76 σ); without that the "
    "trimmed start flagged a clean pose in 10/40 null sessions, with it 1/40. What the stress row still misses: "
    "sessions where a fit through a different half of the poses trims to a smaller sum than the clean fit (the "
    "data cannot tell those outliers from another T, o), and outliers whose radial part (7-10 σ) does not pass "
    "the Bonferroni t test at 7-13 residual degrees of freedom.",
    "* **Two effects at once (39/40; the previous run 40/40).** Seed 3023: the drift on x entered as a cubic and is now stepped down to order 1 (as it was planted); the cubic had absorbed a temperature-shaped remainder on x, which then entered as temperature_bias(x) at p = 0.0005 against its level 0.000625, an extra finding by chance at the selection's level (the planted drift and temperature bias are named on their axes within 30 %).",
    "* **bias_drift in 20-30-pose sessions (previous run 37/40).** Three failures named the drift on its axis as a "
    "cubic in time (order 3 entering directly, as a bias that rises and falls must be able to): the first-order "
    "coefficient of a cubic shares the linear trend with the s³ term (s and s³ correlate ≈ 0.9 over a recording) "
    "and landed 34-53 % off. Now a time term that enters at a higher order directly is stepped down to the lowest "
    "order its higher coefficients do not significantly improve on (F test at the level it entered at, the level "
    "a later step would need to raise the order again; seed 4023: order 3 against order 1, p = 0.010 > 0.00056, "
    "although s³ given s and s² alone has p = 0.003). The rise-then-fall bias keeps its order 2 "
    "(tests/applications/test_diagnosis_correlation.py). In the table: 40/40.",
    "* **Null Gauss–Markov recordings (previous run 37/40).** The three false findings were single outlier poses "
    "(seeds 5009, 5013) and scale_nonlinearity(y) (5027), not a term smooth in time. Two changes. (1) The pose "
    "noise correlated in time is now part of the noise model (`optcal.applications.diagnosis.correlation`): the noise of pose "
    "means a few seconds apart is modelled as a first-order Gauss–Markov process of the pose times along each "
    "pose's normal, corr = ρ₀ exp(−Δt/τ) (d_k·d_j), estimated by restricted maximum likelihood from the baseline "
    "(τ at most two pose gaps, the first-order drift and temperature terms among the fixed effects, so that a trend "
    "is not taken for noise: allowed to span the recording, the correlation absorbed linear drifts and 6/40 "
    "small-session drifts went unnamed), and used by every test, standard error and detection limit through "
    "generalised least squares when its own likelihood-ratio test is significant or when the noise of the pose "
    "means measured on the still parts is at least 1.5× σ/√n (so on every recording of this family, median 1.8×; on white recordings ≈ 1). With 48 "
    "poses of random orientation the estimate is noisy and low (median neighbour ρ 0.15 against the 0.31 the "
    "process implies for the pose's own normal; two random normals share on average nothing), which is why the "
    "still parts' evidence decides its use. `--pose-correlation off|on` overrides the decision. (2) The outlier "
    "test set aside every suspect at three robust scales of a trimmed fit (≈ 0.6 σ at 48 poses) and tested "
    "each against the noise scale of the rest: clean suspects set aside with it deflated that scale (seed 5009: "
    "a pose at 2.6 σ in the least-squares fit tested at t = 4.3, Bonferroni p = 0.006). The flagged poses are "
    "now tested again with only the flagged poses set aside, until the set holds (real outliers stay set aside "
    "together and cannot mask each other; the outlier rows of every family are in the tables). What remains, over 100 seeds: five null recordings with a finding (5013 and 5099: an outlier pose; 5027: scale_nonlinearity(y); 5069: an outlier pose and temperature_scale(z); 5087: temperature_bias(z)), 5/100 against the selection's family-wise level of 0.02 per step (see the next point).",
    "* **Effects in the Gauss–Markov recordings.** The detection limits are the honest ones under the "
    "correlation (generalised least-squares standard errors, `limit / truth` column): the demo's sizes are "
    "1.5-3.5× those limits, and at that size the test names the effect about half to nine times in ten, the 30 % "
    "window being 1-2 standard errors. The rows at 3× the honest limit show what the method does where the data "
    "resolve the effect (100 seeds each in the last run): almost every failure there is one of the null "
    "recordings' own false findings, because the effect rows reuse the null recordings' noise: the five null "
    "recordings with a finding (seeds 5013, 5027, 5069, 5087, 5099) fail in nearly every row. Among the 95 seeds "
    "whose null recording is clean, the 3×-limit rows succeed in 94, 94, 93 and 95 (temperature_bias, "
    "temperature_scale, bias_drift, scale_nonlinearity). A 400-seed run of this family (`N13=400 "
    "N13_FAMILIES=gm N13_OUT=diagnose_hidden_effects_gm400.md`, results/diagnose_hidden_effects_gm400.md, 1,683 s) settles "
    "it: no finding on 389/400 null recordings (97 %), and at 3× the limit 387, 385, 387 and 390 of 400 "
    "(97, 96, 97 and 98 %, Wilson lower bounds 94-95 %); the first hundred seeds held five of the 400 null "
    "recordings' eleven findings. At the demo's sizes (200 seeds): 96, 74, 77 and 88 %. The null's 5/100 is against a nominal 3 % (0.02 for "
    "the selection, 0.01 for the outlier test; 5 or more of 100 at 3 % has probability 0.18): three are one outlier "
    "pose each, the noise itself at about 3.4 σ (3.0-3.1 mg off under the true sensor over the pose's true dwell, "
    "not a mis-detected interval), two a term at p = 0.0002-0.0003 against its level 0.00056. The correlation "
    "estimated from 48 poses is low and noisy (median neighbour ρ 0.22 against ≈ 0.3 for the process along a "
    "pose's own normal; coverage of the 95 % intervals below: 91.9 %), but it is not their cause: with the "
    "correlation fixed at the process's own values (ρ₀ 0.95, τ 5.36 s: neighbour ρ 0.31) the same five seeds "
    "name the same findings, and the outlier test, now run under the correlation too (each suspect's mean shift "
    "in the generalised fit), names the same poses. One cause of failure was in the selection and is fixed: in 5 "
    "of 100 temperature_bias recordings at 3× the limit a cubic in time mimicked the warm-up and cool-down with "
    "three coefficients and beat the single temperature coefficient on BIC by about 2 (seed 5052: -59.7 against "
    "-57.7), by fitting part of the correlated noise as well. Within a BIC difference of 6 (not strong evidence, "
    "Kass & Raftery) the term with the fewest coefficients now goes first, as the one-standard-error rule picks "
    "the simplest model the data do not reject: temperature_bias at 3× the limit 90 → 94/100, at the demo's size "
    "47 → 48/50; the other Gauss–Markov rows unchanged. The price is in the Xsens family: with its synthetic "
    "warm-up and cool-down temperature channel, the log's own rise-and-fall bias on z is explained about as well by "
    "temperature_bias(z) as by a time polynomial, and in 2 of 40 bias_drift seeds (7005, 7026) the planted drift on "
    "y tipped that choice to the temperature term (bias_drift row 40 → 38/40: an extra temperature_bias(z) where the "
    "unplanted diagnosis of the same seed keeps the drift). The report's temperature-or-time decision now names the "
    "rival at its order and says it fitted a shade better with more coefficients.",
    "* **Planted in the Xsens log (temperature_scale and scale_nonlinearity 0/5 \"named alone\").** The log has "
    "its own finding (a bias on z that rises and falls, found without any planting), so \"alone\" could never "
    "hold; the planted effect is now judged against the same seed's unplanted diagnosis.",
    "* **Larger runs of this engine (where 40 or 100 seeds left a row near 95 %).** `N13=400 N13_FAMILIES=gm` "
    "(results/diagnose_hidden_effects_gm400.md), `N13=120 N13_FAMILIES=xsens` (results/diagnose_hidden_effects_xsens120.md) and "
    "`N13=120 N13_FAMILIES=two,small` (results/diagnose_hidden_effects_small120.md), all three run again on the engine of "
    "2026-11-26. Gauss–Markov: null 389/400, 3× the limit 387, 385, 387 and 390 of 400 (all ≥ 96 %), at the demo's sizes 193, 148, 154 and 175 of 200. Two effects 118/120; small sessions: "
    "null 118/120, effects 116, 115, 117 and 115 of 120. Counts and m/s² (`N13=40 N13_FAMILIES=units`, "
    "results/diagnose_hidden_effects_units40.md): 160 of 160, 20 recordings per effect read in each unit. Taken as families (every planted row of a family together): "
    "small sessions 574/600 (96 %, outliers included), the Xsens log 471/480 (98 %). Two rows fall below 95 % on "
    "their own, each for a measured reason. (1) Xsens bias_drift 111/120: the planted drift is named on its axis "
    "within 30 % in 120/120, and all nine failures are the same extra, the log's own rise-and-fall bias on z named "
    "as temperature_bias(z) instead of the unplanted diagnosis's bias_drift(z, order 2), the two within the BIC tie "
    "(seed 7005: ΔBIC -20.1 against -14.7). That is the parsimony rule's price, measured both ways on the same "
    "seeds: without it (tie 0) Xsens bias_drift 120/120 but Gauss–Markov temperature_bias at 3× the limit 371/400 "
    "(93 %); at Kass & Raftery's 'bare mention' boundary (tie 2) 120/120 and 379/400; with it (tie 6) 111/120 and "
    "387/400: no threshold puts both at 95 %, and none was tuned to these rows. The synthetic temperature channel "
    "is collinear with the log's own wander (r = -0.5), so the data cannot attribute it, and in all nine the report's "
    "temperature-or-time decision on z names bias_drift(z) as the rival it could not tell apart: counted with the "
    "log's own effect allowed under that declared other name (the table's second column), 120/120. (2) Small-session "
    "outliers 111/120, planted 10-40 σ off. `diagnose` now states the outlier test's own detection limit, the shift "
    "of one pose along its own direction the test names about half the time (tests/applications/test_diagnosis_outliers.py: a "
    "pose shifted by its limit was named in 16 of 40 sessions, by twice it in 40 of 40). Against that limit the "
    "weakest planted outlier is below 1.5× in 14 of the 120 sessions, and five of the nine failures are among them: "
    "1.0-1.3× in the four where one or both outliers were not named (4081, 4094, 4102, 4103), 1.2× in 4071, where "
    "a fit through two other poses leaves a smaller residual sum than the true one (1.7e-6 against 4.2e-6) and the "
    "data cannot refute it. Where every planted outlier is at least 1.5× its limit: 102/106 (96 %). The four "
    "failures there: two sessions with an extra term (4018, 4067), and two where clean poses were flagged with the "
    "outliers (4025: the least-trimmed-squares start, the best 18 of 26 poses for 9 parameters, fits one outlier "
    "and trims clean poses, its trimmed sum 1.1e-7 against 2.5e-7 for the true partition; 4062: 20 poses, two "
    "clean ones at Bonferroni p 0.001 with four set aside and 7 degrees of freedom left). Tried and not kept: (a) "
    "also taking as suspects the poses far off in the trimmed start, which the Cauchy step can absorb (4103): "
    "outliers 112/120 and the 24-32 % stress row 71/120 (from 57), but in sessions with an unmodelled effect the "
    "half-sample fit set aside the poses the effect moves most, and 6 of the 480 planted effects were named as "
    "5-9 outlier poses instead; (b) on top of (a), a floor at the poses' declared σ under the deleted-residual "
    "test's noise scale: clean sessions 120/120 (from 118), outliers 112/120, the stress row 60/120 (from 71); it "
    "helps only where σ is exact, as in a simulation (on the real recordings σ/√n understates the pose noise).",
    "",
]
report += ["", f"Run time {time.time() - t0:.0f} s.", ""]
save()
if N13:
    print("\n".join(report))

# %% [markdown]
# ## The full run's tables

# %%
if QUICK:
    print((HERE / "results" / "diagnose_hidden_effects.md").read_text())
