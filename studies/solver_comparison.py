# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Solver comparison: Cramér–Rao efficiency, speed, scaling (issue 7)
#
# Every estimator of optcal — the algebraic fits (`svd`; `convex` with Clarabel and with SCS),
# the norm-residual maximum likelihood (`mle`, IPOPT in CasADi), the exact errors-in-variables
# ML (`exact`, Lu 2017 eq. 8, IPOPT), the paper's gradient descent (`gd`) — and scipy's
# `least_squares` (LM and TRF) on the same simulated pose tables.  For each: MSE / CRLB per
# parameter (the Cramér–Rao bound with the gravity directions as nuisance parameters), bias,
# iterations, time and failures; sweeps of the number of poses, the noise, the coverage and
# the distortion; speed to the same cost; throughput; 10⁶ poses.
#
# Regenerate everything (tables, figures, JSON) with one command from the repository root:
#
#     python studies/solver_comparison.py            # full study (~8 min on 2 cores)
#     OPTCAL_STUDY_QUICK=1 python studies/solver_comparison.py   # quick check (into results/quick, not kept)
#     OPTCAL_STUDY_REUSE=1 python studies/solver_comparison.py   # redraw tables/figures from the saved JSON
#
# CI executes this notebook with both set (tests/test_notebooks.py): it redraws from the saved full
# run; the computation itself is exercised by `benchmarks/run_quick.sh` and `tests/families/test_solvers.py`.
#
# The computation is `optcal.applications.papers.solver_study.run` (also `optcal reproduce solvers [--json]`).

# %%
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

# Single-threaded BLAS, set before numpy loads: on a shared 2-core machine OpenBLAS's worker
# threads contend with other jobs and turn each (n×3)·(3×3) product of 10⁶ poses from ~5 ms
# into ~0.3 s (see the "10⁶ poses" section).  Every solver gets the same setting.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from optcal.core.model import PARAM_NAMES  # noqa: E402
from optcal.applications.papers.solver_study import run  # noqa: E402

from study_mode import FIGURES as FIG  # noqa: E402
from study_mode import show  # noqa: E402
from study_mode import QUICK  # noqa: E402
from study_mode import RESULTS as OUT  # noqa: E402
from study_mode import STUDIES as HERE  # noqa: E402
FIG.mkdir(parents=True, exist_ok=True)

if os.environ.get("OPTCAL_STUDY_REUSE", "") not in ("", "0"):  # only re-draw tables and figures from the full run's JSON
    res = json.loads((HERE / "results" / "solver_comparison.json").read_text())
else:
    res = run(quick=QUICK, seed=0, progress=sys.stderr.isatty())
    (OUT / "solver_comparison.json").write_text(json.dumps(res, indent=1, allow_nan=False))
exp = res["details"]["experiments"]


# %% [markdown]
# ## Helpers: tables in Markdown

# %%
def fmt(v: float | None, spec: str = ".3f") -> str:
    return "—" if v is None else format(v, spec)


def method_table(block: dict) -> list[str]:
    rows = [
        "| method | Σ MSE / Σ CRLB | mean of MSE_i/CRLB_i | max abs bias / CRLB sd | median time | median iterations | failures |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for m, r in block["methods"].items():
        if "efficiency" not in r:
            rows.append(f"| {m} | — | — | — | — | — | {r['failures']} ({', '.join(r['failure_reasons'])}) |")
            continue
        reasons = f" ({', '.join(f'{k}: {v}' for k, v in r['failure_reasons'].items())})" if r["failures"] else ""
        rows.append(
            f"| {m} | {r['efficiency']:.3f} | {r['mean_mse_over_crlb']:.3f} | {r['max_abs_bias_over_crlb_sd']:.3f} | "
            f"{r['median_time_s'] * 1e3:.2f} ms | {r['median_iterations']:.0f} | {r['failures']}{reasons} |"
        )
    return rows


def per_parameter_table(block: dict, methods: tuple[str, ...]) -> list[str]:
    rows = ["| parameter | CRLB sd | " + " | ".join(f"{m} MSE/CRLB | {m} bias/sd" for m in methods) + " |",
            "|---|---:|" + "---:|---:|" * len(methods)]
    for p in PARAM_NAMES:
        cells = []
        for m in methods:
            r = block["methods"][m]
            cells += [fmt(r.get("mse_over_crlb", {}).get(p)), fmt(r.get("bias_over_crlb_sd", {}).get(p), "+.3f")]
        rows.append(f"| {p} | {block['crlb_sd'][p]:.3g} | " + " | ".join(cells) + " |")
    return rows


def sweep_table(blocks: list[dict], key: str, label: str) -> list[str]:
    methods = list(dict.fromkeys(m for b in blocks for m in b["methods"]))
    rows = [f"| {label} | cond(F) | " + " | ".join(methods) + " |", "|---|---:|" + "---:|" * len(methods)]
    for b in blocks:
        cells = []
        for m in methods:
            r = b["methods"].get(m)
            if r is None:
                cells.append("not run")
            elif "efficiency" not in r:
                cells.append(f"fails {r['failures']}/{b['runs']}")
            else:
                cells.append(f"{r['efficiency']:.2f}" + (f" (fails {r['failures']})" if r["failures"] else ""))
        rows.append(f"| {b[key] if key != 'design' else b['design']} | {b['fisher_condition_number']:.3g} | " + " | ".join(cells) + " |")
    return rows


# %% [markdown]
# ## Figures

# %%
def efficiency_plot(blocks: list[dict], x: list[float], xlabel: str, name: str, logx: bool = True) -> None:
    methods = list(dict.fromkeys(m for b in blocks for m in b["methods"]))
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for m in methods:
        xs = [xi for xi, b in zip(x, blocks) if "efficiency" in b["methods"].get(m, {})]
        ys = [b["methods"][m]["efficiency"] for b in blocks if "efficiency" in b["methods"].get(m, {})]
        ax.plot(xs, ys, "o-", label=m)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xscale("log" if logx else "linear")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("Σ MSE / Σ CRLB")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(FIG / f"{name}.png", dpi=120)
    show(FIG / f"{name}.png")
    plt.close(fig)


n_list = [b["n_poses"] for b in exp["poses"]]
efficiency_plot(exp["poses"], n_list, "number of poses (uniform directions, 5 mg)", "solvers_efficiency_vs_poses")
efficiency_plot(exp["noise"], [b["sigma_g"] * 1e3 for b in exp["noise"]], "noise per pose, mg (120 poses)",
                "solvers_efficiency_vs_noise")
distortion = [float(b["design"].split("×")[1].split(",")[0]) for b in exp["distortion"]]
efficiency_plot(exp["distortion"], distortion, "distortion factor (×Lu 2017's scale and non-orthogonality errors)",
                "solvers_efficiency_vs_distortion", logx=False)

# time per fit against the number of poses
fig, ax = plt.subplots(figsize=(6.4, 4.2))
for m in dict.fromkeys(m for b in exp["poses"] for m in b["methods"]):
    pts = [(b["n_poses"], b["methods"][m]["median_time_s"]) for b in exp["poses"] if "median_time_s" in b["methods"].get(m, {})]
    ax.plot(*zip(*pts), "o-", label=m)
big = res["details"]["large"]
ax.plot([big["n_poses"]], [big["mle_s"]], "k*", ms=12, label=f"mle, {big['n_poses']:.0e} poses")
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_xlabel("number of poses")
ax.set_ylabel("median time per complete fit, s")
ax.legend(fontsize=8)
ax.grid(True, which="both", alpha=0.3)
fig.tight_layout()
fig.savefig(FIG / "solvers_time_vs_poses.png", dpi=120)
show(FIG / "solvers_time_vs_poses.png")
plt.close(fig)

# coverage: failures of svd and convex over caps and noise
cov = exp["coverage"]
caps = sorted({float(b["design"].split("°")[0].split()[1]) for b in cov}, reverse=True)
noises = sorted({b["sigma_g"] * 1e3 for b in cov})
fig, axes = plt.subplots(1, 3, figsize=(11, 3.6), sharey=True)
for ax, m in zip(axes, ("svd", "convex-clarabel", "mle")):
    grid = np.full((len(caps), len(noises)), np.nan)
    for b in cov:
        i = caps.index(float(b["design"].split("°")[0].split()[1]))
        j = noises.index(b["sigma_g"] * 1e3)
        grid[i, j] = b["methods"][m]["failures"] / b["runs"]
    im = ax.imshow(grid, vmin=0, vmax=1, cmap="Reds", aspect="auto")
    ax.set_xticks(range(len(noises)), [f"{s:g}" for s in noises])
    ax.set_yticks(range(len(caps)), [f"{c:g}°" for c in caps])
    ax.set_xlabel("noise, mg")
    ax.set_title(f"{m}: failure rate")
    for i in range(len(caps)):
        for j in range(len(noises)):
            ax.text(j, i, f"{grid[i, j]:.0%}", ha="center", va="center", fontsize=8)
axes[0].set_ylabel("cap half-angle (coverage)")
fig.colorbar(im, ax=axes, shrink=0.8)
fig.savefig(FIG / "solvers_coverage_failures.png", dpi=120, bbox_inches="tight")
show(FIG / "solvers_coverage_failures.png")
plt.close(fig)

# speed to the same cost
speed = res["details"]["speed"]
fig, ax = plt.subplots(figsize=(7.5, 4.2))
keys = ["mle", "scipy-lm", "scipy-trf", "gd_1e-09", "gd_1e-12"]
width = 0.8 / len(speed)
for k, s in enumerate(speed):
    ax.bar(np.arange(len(keys)) + k * width, [s["median_time_s"][key] * 1e3 for key in keys], width, label=s["design"])
ax.set_xticks(np.arange(len(keys)) + width * (len(speed) - 1) / 2, ["mle (IPOPT)", "scipy LM", "scipy TRF",
                                                                  "gd to f*(1+1e-9)", "gd to f*(1+1e-12)"], fontsize=8)
ax.set_yscale("log")
ax.set_ylabel("median solve time, ms")
ax.legend(fontsize=7)
ax.grid(True, axis="y", which="both", alpha=0.3)
fig.tight_layout()
fig.savefig(FIG / "solvers_speed.png", dpi=120)
show(FIG / "solvers_speed.png")
plt.close(fig)

# %% [markdown]
# ## Where `convex` succeeds and `svd` fails

# %%
svd_fail_convex_ok = [
    (b["design"], b["methods"]["svd"]["failures"], b["methods"]["convex-clarabel"]["failures"], b["runs"],
     b["methods"]["convex-clarabel"].get("efficiency"), b["methods"]["mle"].get("efficiency"), b["methods"]["mle"]["failures"])
    for b in cov
    if b["methods"]["svd"]["failures"] > b["methods"]["convex-clarabel"]["failures"]
]

# One example, looked at closely: the algebraic quadric of each fit on a 30° cap at 20 mg.
from optcal.errors import FitError  # noqa: E402
from optcal.families.accel.ellipsoid import ConvexEllipsoidFit, SVDEllipsoidFit  # noqa: E402
from optcal.core.model import lu2017_reference_model  # noqa: E402
from optcal.families.simulate.poses import cap_directions, simulate_poses  # noqa: E402

example_poses = simulate_poses(lu2017_reference_model(), cap_directions(120, 30.0, np.random.default_rng(1)), 0.020,
                               rng=np.random.default_rng(2))
try:
    SVDEllipsoidFit(allow_degenerate=True).fit(example_poses)
    svd_example = "svd returned an ellipsoid on this draw"
except FitError as exc:
    svd_example = f"svd: {exc}".split("; this happens")[0]
convex_example = ConvexEllipsoidFit(allow_degenerate=True).fit(example_poses)
example_text = (
    f"Example (120 poses on a 30° cap, 20 mg, one draw): {svd_example}.  convex: an ellipsoid with the "
    f"semidefinite constraint {'active' if convex_example.extra['psd_constraint_active'] else 'inactive'} "
    f"(smallest eigenvalue of the normalised A {convex_example.extra['min_eigenvalue_normalised_A']:.3g}); "
    f"identifiability report: {convex_example.identifiability.describe()}."
)

# %% [markdown]
# ## The Markdown report

# %%
h = res
big_speed = next(s for s in speed if s["design"].startswith("uniform") and s["n_poses"] == h["speedup_large"]["n_poses"])
t1 = exp["table1"]
eff = exp["efficiency_140_10mg"]
lines = [
    "# Solver comparison (issue 7)",
    "",
    "Generated by `python studies/solver_comparison.py` (the computation is `optcal reproduce solvers`); "
    f"seed {h['seed']}, runtime {h['runtime_s'] / 60:.1f} min on a 2-core machine shared with other jobs. "
    "Raw numbers: `solver_comparison.json`.",
    "",
    "θ = (T_xx, T_yx, T_yy, T_zx, T_zy, T_zz, o_x, o_y, o_z) (optcal's canonical identifiable parameters, "
    "raw units = g here).  CRLB: `optcal.cramer_rao_bound` — the Fisher information with the unknown gravity "
    "directions eliminated (checked against the brute-force Schur complement in `tests/core/test_crlb.py`).  "
    "**Σ MSE / Σ CRLB** is the issue's \"MSE / CRLB summed over parameters\"; 1 is efficient, and a biased "
    "estimator can fall below 1.  The relative Monte Carlo standard error of each MSE is √(2/runs).  A failure "
    "is an optcal error (no ellipsoid, unidentifiable answer) or a solver that does not report convergence; "
    "failed runs are left out of the MSE.",
    "",
    "## Headline figures against the issue's targets",
    "",
    "| figure | target | measured |",
    "|---|---|---|",
    f"| exact ML, Σ MSE / Σ CRLB, 140 poses, 10 mg, {eff['runs']} runs | ≤ 1.10 | "
    f"**{fmt(h['efficiency'].get('exact'))}** (mle {fmt(h['efficiency'].get('mle'))}) |",
    f"| mle vs gd to the same cost, {h['speedup']['design']}, median of per-run ratios | ≥ 20× | "
    f"**{h['speedup']['mle_vs_gd']:.1f}×** (gd to f ≤ f*·(1+1e-9)) |",
    f"| mle vs scipy least_squares ({h['speedup']['scipy_method']}, the faster), same design | ≥ 3× | "
    f"**{h['speedup']['mle_vs_scipy']:.2f}×** |",
    f"| the same two ratios at {h['speedup_large']['n_poses']:,} poses (uniform, 5 mg) | ≥ 20×, ≥ 3× | "
    f"**{h['speedup_large']['mle_vs_gd']:.1f}×** vs gd (1e-9), **{h['speedup_large']['mle_vs_scipy']:.2f}×** vs "
    f"{h['speedup_large']['scipy_method']} |",
    f"| complete mle fits per second, problem built once | ≥ 200 | **{h['throughput_fits_per_s']:.0f}** |",
    f"| {h['large']['n_poses']:,} poses through `calibrate(method=\"mle\")` | ≤ 5 s | **{h['large']['mle_s']:.2f} s** "
    f"(IPOPT {big['ipopt_s']:.2f} s, {big['iterations']} iterations; max |error|/stderr {big['max_abs_error_over_stderr']:.2f}) |",
    "",
    "## Efficiency: exact ML at 140 poses, 10 mg",
    "",
    f"Design: {eff['design']} (one fixed draw of directions), Lu 2017's sensor; {eff['runs']} runs; "
    f"Fisher condition number {eff['fisher_condition_number']:.3g}.",
    "",
    *method_table(eff),
    "",
    *per_parameter_table(eff, ("exact", "mle")),
    "",
    f"## Table 1 setup ({t1['design']}, 5 mg, {t1['runs']} runs), every method",
    "",
    *method_table(t1),
    "",
    "Times are complete fits (validation, start, covariance and identifiability report included).  `convex-scs` "
    "solves the same semidefinite problem with SCS (first-order, more iterations); both polish to the exact "
    "equality-constrained solution when the semidefinite constraint is inactive, hence identical estimates.",
    "",
    *per_parameter_table(t1, ("mle", "exact", "svd")),
    "",
    "## Sweeps (Σ MSE / Σ CRLB; `fails k` = failed runs)",
    "",
    "### Number of poses (uniform directions, 5 mg)",
    "",
    *sweep_table(exp["poses"], "n_poses", "poses"),
    "",
    "`exact` has 9 + 3n variables (its problem is built in ~5 s for 10⁴ poses, then solved in under a second). "
    "Runs per point: as in the JSON (fewer above 10³ poses, so those ratios carry ±0.2 of Monte Carlo noise).",
    "",
    "The norm-residual ML (`mle`, eq. 13-14; gd and scipy minimise the same cost) replaces each latent "
    "direction by the radial projection of the measurement (eq. 10-12), which is exact only for an orthogonal "
    "C: it carries a bias of order σ² that does not shrink with n, while the bound shrinks as 1/n.  Invisible "
    f"at 10²-10³ poses, it is {big['max_abs_error_over_stderr']:.1f} standard errors at {big['n_poses']:,} poses "
    "(the `large` run below; the same estimate as scipy's LM on the same cost, so not a convergence issue).  "
    "The exact ML (eq. 8) has no such bias, but its NLP grows with n.",
    "",
    "![efficiency vs poses](figures/solvers_efficiency_vs_poses.png)",
    "![time vs poses](figures/solvers_time_vs_poses.png)",
    "",
    "### Noise (120 uniform poses)",
    "",
    *sweep_table(exp["noise"], "sigma_g", "σ, g"),
    "",
    "![efficiency vs noise](figures/solvers_efficiency_vs_noise.png)",
    "",
    "### Distortion (Lu 2017's scale and non-orthogonality errors × factor; 120 uniform poses, 5 mg)",
    "",
    *sweep_table(exp["distortion"], "design", "design"),
    "",
    "![efficiency vs distortion](figures/solvers_efficiency_vs_distortion.png)",
    "",
    "### Coverage (directions uniform on a spherical cap about z; 120 poses)",
    "",
    "Here every estimator may return a degenerate answer (`allow_degenerate=True`), so a failure means no "
    "calibration at all: `svd` returns a quadric that is not an ellipsoid (FitError), or a solver does not converge.",
    "",
    *sweep_table(cov, "design", "design"),
    "",
    "![coverage failures](figures/solvers_coverage_failures.png)",
    "",
    "`mle` falls behind the algebraic fits as coverage shrinks and noise grows (e.g. the hemisphere at 20 mg): "
    "scipy's LM on the same cost reaches the same estimates run by run, so this is the norm-residual ML at low "
    "signal-to-noise on a partial sphere (its O(σ²) bias and the nonlinearity of the radial projection), not "
    "a solver failure; the failures on the smallest caps are IPOPT stopping at its iteration limit on an "
    "almost flat cost (cond(F) ≥ 10⁴).",
    "",
    "#### Where `convex` succeeds and `svd` fails",
    "",
]
if svd_fail_convex_ok:
    lines += ["| design | svd failures | convex failures | runs | convex Σ MSE/Σ CRLB | mle (from convex) Σ MSE/Σ CRLB | mle failures |",
              "|---|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {d} | {a} | {b} | {r} | {fmt(c)} | {fmt(e)} | {f} |" for d, a, b, r, c, e, f in svd_fail_convex_ok]
else:
    lines.append("No design of this run had more svd than convex failures.")
lines += [
    "",
    example_text,
    "",
    "Why: both fit the quadric `aᵀAa + bᵀa + c = 0` by minimising the algebraic residual `‖Jη‖` (Lu 2017, "
    "eq. 18-24), but they exclude the trivial answer η = 0 differently.  The SVD fit takes the unit vector η with "
    "the smallest residual (`‖η‖ = 1`), which weighs the quadratic part A, the linear part b and the constant c "
    "alike.  Poses on a cap of the sphere are explained almost as well by degenerate quadrics (a cylinder or "
    "hyperboloid bending the same way near the cap) whose A has tiny or negative eigenvalues, and noise picks "
    "one of them: the SVD answer is then not an ellipsoid and there is no calibration at all (FitError).  The "
    "convex fit fixes the scale of the quadratic part instead (`tr A = 3`, the curvature of a sphere, in the "
    "spirit of ellipse-specific fitting) and adds `A ⪰ εI`: the trace normalisation alone already keeps A away "
    "from the degenerate quadrics in the example above, and the semidefinite constraint guarantees an "
    "ellipsoid when even that is not enough (answer = nearest ellipsoid, constraint active).  On well-spread "
    "poses the two normalisations give nearly the same ellipsoid (compare their rows in the tables above).  "
    "Where convex alone succeeds its answer is poorly determined: the identifiability report flags one or two "
    "parameter combinations (in the example with standard errors of 5 % and 20 % of full scale), Σ MSE / Σ CRLB "
    "is large, and the ML "
    "refinement started from it usually does not converge.  The ratio can also fall below 1 on caps: the bound "
    "holds for unbiased estimators, and the algebraic fits are biased there.",
    "",
    "## Speed to the same cost",
    "",
    "Same normalised data, same start (the SVD fit), same weights (propagated at the start), same cost "
    "`f(θ) = Σ w_k r_k(θ)²`.  `mle`: one IPOPT solve of the ML problem (built once).  `gd`: the paper's "
    "fixed-step gradient descent (μ = 1/L) run until `f ≤ f*·(1+ε)`, f* the cost IPOPT reached.  scipy: "
    "`least_squares` with the analytic Jacobian from the same numpy evaluator, xtol = ftol = gtol = 1e-10 "
    "(its final cost is checked to be within 1e-9 of f*).  On each run's data every solver is timed three times "
    "in a row and its best time kept (solvers interleaved run by run); ratios are medians of per-run ratios.  "
    "Iterations: IPOPT 2 on every design, against hundreds to thousands for gd (last column).",
    "",
    "| design | runs | mle | scipy LM | scipy TRF | gd (ε=1e-9) | gd (ε=1e-12) | mle vs gd (1e-9) | mle vs gd (1e-12) | mle vs LM | mle vs TRF | gd iterations (1e-9) |",
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
]
for s in speed:
    t = s["median_time_s"]
    lines.append(
        f"| {s['design']} | {s['runs']} | {t['mle'] * 1e3:.2f} ms | {t['scipy-lm'] * 1e3:.2f} ms | {t['scipy-trf'] * 1e3:.2f} ms | "
        f"{t['gd_1e-09'] * 1e3:.2f} ms | {t['gd_1e-12'] * 1e3:.2f} ms | {s['speedup_vs_gd']['1e-09']:.1f}× | "
        f"{s['speedup_vs_gd']['1e-12']:.1f}× | {s['speedup_vs_scipy']['scipy-lm']:.2f}× | {s['speedup_vs_scipy']['scipy-trf']:.2f}× | "
        f"{s['median_iterations']['gd_1e-09']:.0f} |"
    )
lines += [
    "",
    "![speed](figures/solvers_speed.png)",
    "",
    "Reading: IPOPT converges in 2 Newton iterations from the algebraic start, but every IPOPT solve carries "
    "about 0.35 ms of fixed set-up (building its algorithm objects and the linear solver; a trivial 9-variable "
    "problem takes as long), which dominates at ~10² poses.  Gradient descent needs hundreds of iterations on "
    "the Table 1 design (condition number of the normalised problem ≈ 30), tens on a uniform design and "
    "thousands on a poorly conditioned one (a hemisphere), so the ratio against gd depends mostly on the "
    "design's conditioning.  scipy's MINPACK Levenberg–Marquardt has almost no per-call overhead and needs "
    "3-5 evaluations of the same numpy residuals: on this small, unconstrained least-squares problem it is "
    "faster than IPOPT, until the data term dominates (10⁴ poses) and both are limited by the same evaluations.  "
    "Beyond that IPOPT pulls ahead: its 2 iterations cost one 9×n by n×9 product for the (Gauss–Newton) "
    "Hessian and a 9×9 solve, while MINPACK factors the n×9 Jacobian by QR at every iteration, so at "
    "10⁵-10⁶ poses `mle` is several times faster than LM.  "
    f"At {h['speedup_large']['n_poses']:,} poses: mle is {h['speedup_large']['mle_vs_scipy']:.1f}× faster than "
    f"scipy (target 3×) and {h['speedup_large']['mle_vs_gd']:.1f}× / {big_speed['speedup_vs_gd']['1e-12']:.1f}× "
    "faster than gd at ε = 1e-9 / 1e-12 (target 20×).  "
    f"On the 120-pose Table 1 design ({h['speedup']['mle_vs_gd']:.1f}× and {h['speedup']['mle_vs_scipy']:.2f}×) "
    "IPOPT's fixed cost is about half of its time: a trivial 9-variable IPOPT problem takes ≈ 0.4 ms on the "
    "machine of this run, so against gd's time at ε = 1e-9 no IPOPT solve could reach 20× there.",
    "",
    "## Throughput and 10⁶ poses",
    "",
    f"{res['details']['throughput']['fits']} complete default `mle` fits (convex start, weights re-propagated until "
    f"they change by < 0.1 %, covariance, identifiability report) on pre-simulated Table 1 tables: "
    f"{res['details']['throughput']['seconds']:.2f} s, **{h['throughput_fits_per_s']:.0f} fits/s**.",
    "",
    f"{big['n_poses']:,} poses: **{big['mle_s']:.2f} s** through `calibrate` (validation, start, IPOPT "
    f"{big['ipopt_s']:.2f} s in {big['iterations']} iterations over the passes, covariance and report).  "
    "Above 200 poses the ML problem is a CasADi `nlpsol` whose cost, gradient and Gauss–Newton Hessian are "
    "numpy callbacks over column vectors (nothing is built per n), instead of an SX graph.",
    "",
    f"BLAS threads: `OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}` (set by this script).  With "
    "OpenBLAS's default threading on this shared 2-core machine the same 10⁶-pose fit took 4.1-5.0 s, of which "
    "~3 s were the (10⁶×3)·(3×3) matrix products of the residuals, Jacobian and normal gains in "
    "`estimators.base.finish` / `identifiability` (the covariance and identifiability report), whose threads "
    "contend with other jobs; the ML solve itself (start, IPOPT, weights) takes ~0.4 s.",
    "",
]
(OUT / "solver_comparison.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines[:20]))
