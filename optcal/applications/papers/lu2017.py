"""Reproduction of Lu et al. 2017, section 3.1 and Table 1, by Monte Carlo with every method.

The simulated sensor is the paper's (``S_M = diag(1.2, 0.8, 1.3)``, ``o = [0.20, 0.15, 0.10]ᵀ g``,
ρ = 2°, φ = 1°, λ = 1.5°, ``V_L`` as printed), which reproduces Table 1's reference A exactly.

The paper's attitude schedule, taken literally (three sweeps about z, x and y starting from
the level attitude), does not identify every parameter: the z sweep never moves gravity
off the z axis, and the x and y sweeps keep it in the planes x = 0 and y = 0, on which the
quadric ``ā_x ā_y = 0`` vanishes, so ``A_xy`` (in the directions' frame) is not determined.
This module shows that (Fisher rank 8 of 9) and runs the Monte Carlo on the same three sweeps
started from tilted attitudes (:func:`optcal.families.simulate.poses.tilted_sweeps`), which identify all
nine parameters.  The paper does not state its noise level; ``sigma`` (per averaged pose, in
g) is a setting, 1 mg by default (about what 10 s of averaging leaves of a consumer MEMS
part's noise, generously).  Table 1 is printed to four decimals, so agreement below 5e-5
cannot be judged; 200 runs at 1 mg give a standard error of the mean of about 8e-5 on A.
"""

from __future__ import annotations

import time
from typing import Any

import click
import numpy as np

from optcal.families.accel.calibration import calibrate
from optcal.errors import FitError, IdentifiabilityError, InputError, SolverError
from optcal.core.identifiability import analyse_design
from optcal.core.model import (
    LU2017_TABLE1_A_PAPER,
    LU2017_TABLE1_A_REF,
    LU2017_TABLE1_O_PAPER,
    LU2017_TABLE1_O_REF,
    lu2017_reference_model,
)
from optcal.applications.papers.command_output import show_progress
from optcal.core.jsonio import json_text, jsonable
from optcal.families.simulate.poses import lu2017_sweeps, simulate_poses, tilted_sweeps

METHODS = ("svd", "convex", "mle", "exact", "gd")


def literal_schedule_finding(n_per_axis: int = 40, sigma: float = 0.001, seed: int = 0) -> dict[str, Any]:
    """Identifiability of the paper's schedule as written, and what a fit on it does."""
    model = lu2017_reference_model()
    d = lu2017_sweeps(n_per_axis)
    report = analyse_design(model, d)
    distinct = int(np.unique(np.round(d, 12), axis=0).shape[0])
    poses = simulate_poses(model, d, sigma, rng=np.random.default_rng([seed, 99]))
    refused = None
    try:
        calibrate(poses, method="mle")
    except IdentifiabilityError as exc:
        refused = str(exc)
    forced = calibrate(poses, method="mle", allow_degenerate=True)
    return {
        "schedule": f"rotations about z, x, y from the level attitude, {n_per_axis} angles each in [0, 2π)",
        "n_poses": int(len(d)),
        "distinct_directions": distinct,
        "fisher_rank": report.rank,
        "n_params": report.n_params,
        "unidentified": [u["text"] for u in report.unidentified],
        "explanation": (
            "the z sweep leaves gravity on the z axis, so its poses are all the same; the x and y sweeps keep "
            "gravity in the planes x = 0 and y = 0 of the sensor frame, where the quadric x·y vanishes, so the "
            "cross term A_xy (in the frame of the true directions) can change without changing any residual"
        ),
        "refusal_message": refused,
        "forced_fit_A_error_max": float(np.max(np.abs(forced.A - model.A))),
        "forced_fit_A_xy": float(forced.A[0, 1]),
        "true_A_xy": float(model.A[0, 1]),
    }


def monte_carlo(runs: int = 200, n_per_axis: int = 40, sigma: float = 0.001, seed: int = 0,
                methods: tuple[str, ...] = METHODS, progress: bool = True) -> dict[str, Any]:
    """Table 1 by Monte Carlo on the identifying (tilted) sweeps, every method on the same data."""
    from tqdm import tqdm

    model = lu2017_reference_model()
    d = tilted_sweeps(n_per_axis)
    design = analyse_design(model, d)
    est: dict[str, dict[str, list]] = {m: {"A": [], "o": [], "t": [], "it": [], "se_A": [], "cost": []} for m in methods}
    failures = {m: 0 for m in methods}
    for run in tqdm(range(runs), desc="lu2017 Monte Carlo", disable=not progress, file=None):
        poses = simulate_poses(model, d, sigma, rng=np.random.default_rng([seed, run]))
        for m in methods:
            try:
                r = calibrate(poses, method=m)
            except (FitError, SolverError):
                failures[m] += 1
                continue
            e = est[m]
            e["A"].append(r.A)
            e["o"].append(r.o)
            e["t"].append(r.solver.solve_time_s)
            e["it"].append(r.solver.iterations)
            e["se_A"].append(r.A_stderr)
            e["cost"].append(r.chisqr)
    out: dict[str, Any] = {}
    for m in methods:
        e = est[m]
        if not e["A"]:
            out[m] = {"failures": failures[m]}
            continue
        A = np.array(e["A"])
        o = np.array(e["o"])
        mean_A, mean_o = A.mean(axis=0), o.mean(axis=0)
        k = len(A)
        out[m] = {
            "runs": k,
            "failures": failures[m],
            "mean_A": mean_A,
            "mean_o": mean_o,
            "max_abs_error_A_vs_table1": float(np.max(np.abs(mean_A - LU2017_TABLE1_A_REF))),
            "max_abs_error_o_vs_table1": float(np.max(np.abs(mean_o - LU2017_TABLE1_O_REF))),
            "max_abs_error_A_vs_truth": float(np.max(np.abs(mean_A - model.A))),
            "max_abs_error_o_vs_truth": float(np.max(np.abs(mean_o - model.o))),
            "mc_std_A_max": float(np.max(A.std(axis=0, ddof=1))),
            "mean_reported_stderr_A_max": float(np.max(np.mean(e["se_A"], axis=0))),
            "standard_error_of_mean_A_max": float(np.max(A.std(axis=0, ddof=1)) / np.sqrt(k)),
            "median_solve_time_s": float(np.median(e["t"])),
            "median_iterations": float(np.median(e["it"])),
            "mean_cost": float(np.mean(e["cost"])),
        }
    return {
        "schedule": f"three sweeps about z, x, y from attitudes tilted by 35°, {n_per_axis} angles each ({len(d)} poses)",
        "sigma_g": sigma,
        "runs": runs,
        "design_fisher_rank": design.rank,
        "design_condition_number": design.condition_number,
        "methods": out,
    }


def run(runs: int = 200, seed: int = 0, sigma: float = 0.001, n_per_axis: int = 40, progress: bool = True) -> dict[str, Any]:
    """The whole reproduction: Table 1 by Monte Carlo, and the literal-schedule finding."""
    t0 = time.perf_counter()
    mc = monte_carlo(runs=runs, n_per_axis=n_per_axis, sigma=sigma, seed=seed, progress=progress)
    literal = literal_schedule_finding(n_per_axis, sigma, seed)
    model = lu2017_reference_model()
    return jsonable(
        {
            "paper": "Lu, Liu, Zhang, He 2017, J. NUDT 39(5), section 3.1, Table 1",
            "table1": {
                "reference_A": LU2017_TABLE1_A_REF,
                "reference_o": LU2017_TABLE1_O_REF,
                "paper_mean_A": LU2017_TABLE1_A_PAPER,
                "paper_mean_o": LU2017_TABLE1_O_PAPER,
                "model_A_exact": model.A,
            },
            "monte_carlo": mc,
            "literal_schedule": literal,
            "runtime_s": time.perf_counter() - t0,
        }
    )


def format_report(res: dict[str, Any]) -> str:
    """The reproduction as readable text."""
    mc = res["monte_carlo"]
    lines = [
        "Lu et al. 2017, Table 1: maximum-likelihood calibration on simulated data",
        f"  schedule: {mc['schedule']}; noise {mc['sigma_g'] * 1e3:g} mg per pose; {mc['runs']} Monte Carlo runs",
        f"  design: Fisher rank {mc['design_fisher_rank']}/9, condition number {mc['design_condition_number']:.3g}",
        "",
        f"  {'method':<7s} {'max|ΔA| vs T1':>14s} {'max|Δo| vs T1':>14s} {'MC std A':>10s} {'stderr A':>10s} {'median t':>10s} {'iters':>7s} {'fail':>5s}",
    ]
    for m, r in mc["methods"].items():
        if "mean_A" not in r:
            lines.append(f"  {m:<7s} all runs failed ({r['failures']})")
            continue
        lines.append(
            f"  {m:<7s} {r['max_abs_error_A_vs_table1']:14.2e} {r['max_abs_error_o_vs_table1']:14.2e} "
            f"{r['mc_std_A_max']:10.2e} {r['mean_reported_stderr_A_max']:10.2e} "
            f"{r['median_solve_time_s'] * 1e3:8.2f}ms {r['median_iterations']:7.0f} {r['failures']:5d}"
        )
    mle = mc["methods"].get("mle", {})
    if "mean_A" in mle:
        lines += ["", "  mean A (mle):"] + ["    " + "  ".join(f"{v: .4f}" for v in row) for row in mle["mean_A"]]
        lines += ["  Table 1 reference A:"] + ["    " + "  ".join(f"{v: .4f}" for v in row) for row in res["table1"]["reference_A"]]
        lines.append("  mean o (mle): " + "  ".join(f"{v:.4f}" for v in mle["mean_o"]) + "   (Table 1: 0.20 0.15 0.10)")
    lit = res["literal_schedule"]
    lines += [
        "",
        "The paper's schedule taken literally:",
        f"  {lit['schedule']}: {lit['n_poses']} poses, {lit['distinct_directions']} distinct directions",
        f"  Fisher rank {lit['fisher_rank']}/{lit['n_params']}; not determined: {'; '.join(lit['unidentified'])}",
        f"  why: {lit['explanation']}",
        f"  a forced fit (--allow-degenerate) gets A_xy = {lit['forced_fit_A_xy']:.4f} (truth {lit['true_A_xy']:.4f}); "
        f"max |ΔA| = {lit['forced_fit_A_error_max']:.3g}",
        f"  runtime {res['runtime_s']:.1f} s",
    ]
    return "\n".join(lines)


@click.command("lu2017")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--runs", type=click.IntRange(1), default=200, show_default=True, help="Monte Carlo runs.")
@click.option("--sigma", type=click.FloatRange(0, min_open=True), default=0.001, show_default=True, help="Noise per pose, g.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--scaling", is_flag=True,
              help="Instead: the exact ML (eq. 8) against the norm-residual ML from 10² to 10⁶ poses "
                   "(efficiency against the Cramér-Rao bound, bias, time; about 20 min).")
@click.option("--quick", is_flag=True, help="With --scaling: 10² to 10⁴ poses, few runs (CI).")
def command(as_json: bool, runs: int, sigma: float, seed: int, scaling: bool, quick: bool) -> None:
    """Lu 2017 Table 1 by Monte Carlo with every method, and the literal schedule's identifiability."""
    if quick and not scaling:
        raise InputError("--quick applies to --scaling only")
    if scaling:
        from optcal.applications.papers.lu2017_scaling import format_scaling
        from optcal.applications.papers.lu2017_scaling import scaling as exact_scaling

        out = exact_scaling(quick=quick, seed=seed, progress=show_progress())
        click.echo(json_text(out) if as_json else format_scaling(out))
        return
    res = run(runs=runs, seed=seed, sigma=sigma, progress=show_progress())
    if as_json:
        click.echo(json_text(res))
    else:
        click.echo(format_report(res))
