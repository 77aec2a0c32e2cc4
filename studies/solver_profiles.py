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
# # One formulation, every solver: performance profiles (issue 29)
#
# The estimator study (`solver_comparison`) compares estimators; this one compares **solvers on one
# formulation**.  Each instance is the norm-residual maximum-likelihood NLP (Lu 2017, eq. 13-14) as
# `optcal.problems.norm_residual_ml` builds it — its first pass, from the convex start, with the loss
# the instance asks for — and every CasADi `nlpsol` plugin that runs here solves it from the same
# start (`optcal.solvers.registry`: each plugin is probed on a constrained two-variable problem; the
# ones that fail the probe are listed with CasADi's reason).  The convex fit of the same poses is
# solved by every installed cvxpy solver that takes its semidefinite constraint.
#
# * **Instances**: synthetic designs varying one factor at a time about a base (Lu 2017's sensor, 120
#   poses uniform on the sphere, 5 mg) — size, noise, distortion, coverage (spherical caps), outliers
#   (a share of poses moved by 50 σ, with the squared, Huber and Cauchy losses) — and the real
#   recordings in `../shared/data` read with the options their PROVENANCE.md gives.
# * **Success**: the solver reports success *and* its objective is within 1e-6 (relative) of the best
#   any solver found (≈ 0.015 standard errors at 120 poses: `solver_profiles` module docstring).
# * **Performance profiles** (Dolan & Moré 2002): `ρ_s(τ)` is the share of instances a solver solves
#   within a factor τ of the fastest (fewest iterations) on that instance; failures never count.
#   Iterations are compared only between solvers that count iterations (alpaqa reports gradient
#   evaluations, bonmin branch-and-bound nodes).  Solve times are the best of three solves of an
#   already built solver (building the CasADi function is left out: it is the same for all).
#
#     python studies/solver_profiles.py                        # full run: every solver (about 4 min on 2 cores)
#     OPTCAL_STUDY_QUICK=1 python studies/solver_profiles.py   # quick: 5 solvers, the quick library
#     OPTCAL_STUDY_REUSE=1 python studies/solver_profiles.py   # redraw from the saved full run
#
# The computation is `optcal.applications.papers.solver_profiles.run` (in `optcal reproduce solvers
# --json` as `performance_profile`).

# %%
from __future__ import annotations

import json
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from optcal.applications.papers.solver_profiles import format_profile, profile_figure, run  # noqa: E402

from study_mode import FIGURES as FIG  # noqa: E402
from study_mode import QUICK, show  # noqa: E402
from study_mode import RESULTS as OUT  # noqa: E402
from study_mode import STUDIES as HERE  # noqa: E402

saved = HERE / "results" / "solver_profiles.json"
if os.environ.get("OPTCAL_STUDY_REUSE", "") not in ("", "0") and saved.exists():
    res = json.loads(saved.read_text())
else:
    res = run(quick=QUICK, seed=0, progress=sys.stderr.isatty())
    (OUT / "solver_profiles.json").write_text(json.dumps(res, indent=1, allow_nan=False, default=str))
print(format_profile(res))

# %% [markdown]
# ## Findings (full run: 36 instances, 12 of them real recordings, every solver that runs here)
#
# * On the well-posed instances — every size from 12 to 3000 poses, every noise level, distortion up to ×4,
#   the full sphere and 90-120° caps, outliers under the squared loss, 10 of the 12 recordings — **every
#   solver reaches the same optimum** (relative objective gaps 1e-16 to 1e-9).  The MPU-6050 example's 10
#   poses (one degree of freedom) defeat the SQP methods and sleqp.  The SQP methods and fatrop
#   are the fastest there (median 0.35-0.4 ms against IPOPT's 1.2 ms: IPOPT's per-solve set-up dominates
#   a 9-variable problem), IPOPT and fatrop the most reliable of the fast ones (92 %).
# * **The robust losses** separate them: CasADi's sqpmethod, whatever its QP solver, fails on the Huber
#   and Cauchy instances (non-regular sensitivities, QP failures, iteration limit), where the
#   interior-point and augmented-Lagrangian solvers succeed.
# * **Narrow coverage** (60° and 45° caps: weakly determined problems) defeats every solver but Bonmin,
#   whose embedded IPOPT runs with its own defaults; IPOPT with optcal's scaled-cost tuning reaches its
#   iteration limit there.  imucal's Ferraris session (13 poses that leave o_z undetermined) is the real
#   recording on which no solver reports success (uno reaches the lowest objective and says it is not
#   optimal; CasADi cannot even read sqpmethod's statistics afterwards).
# * Iteration counts say little between families: 2-6 for the Newton-type methods on every
#   well-posed instance; the time profile is the informative one.
# * The convex fit: Clarabel and SCS agree to 2e-6 (normalised θ) on every instance, 1e-15 or better
#   where the semidefinite constraint is inactive.

# %% [markdown]
# ## The profiles
#
# Left: solve time; right: iterations.  A curve that starts high is often the fastest; one that ends
# high solves many instances at all.

# %%
fig = profile_figure(res)
fig.savefig(FIG / "solver_profiles.png", dpi=110)
plt.close(fig)
show(FIG / "solver_profiles.png")


# %% [markdown]
# ## Success by instance family
#
# Which factor makes which solver fail (share of the family's instances solved to the optimum).

# %%
def success_table(res: dict) -> list[str]:
    factors = list(dict.fromkeys(r["factor"] for r in res["instances"]))
    rows = ["| solver | " + " | ".join(factors) + " | all |", "|---|" + "---:|" * (len(factors) + 1)]
    for s in res["solvers"]:
        cells = []
        for f in factors:
            block = [r["solvers"][s]["success"] for r in res["instances"] if r["factor"] == f]
            cells.append(f"{sum(block)}/{len(block)}")
        rows.append(f"| {s} | " + " | ".join(cells) + f" | {res['success_rate'][s]:.0%} |")
    return rows


lines = [f"Solvers on {res['n_instances']} instances ({res['n_real_instances']} real recordings)", ""]
lines += success_table(res)
print("\n".join(lines))

# %% [markdown]
# ## Every instance: status and distance to the best objective
#
# The solver's own status, and `(f − f_best)/|f_best|`; ✓ marks a success.

# %%
rows = ["| instance | n | " + " | ".join(res["solvers"]) + " |", "|---|---:|" + "---|" * len(res["solvers"])]
for r in res["instances"]:
    cells = []
    for s in res["solvers"]:
        v = r["solvers"][s]
        gap = "—" if v["gap"] is None else f"{v['gap']:.0e}"
        cells.append(("✓ " if v["success"] else "") + f"{str(v['status'])[:28]} ({gap})")
    rows.append(f"| {r['name']} | {r['n_poses']} | " + " | ".join(cells) + " |")
table = "\n".join(rows)
(OUT / "solver_profiles.md").write_text("\n".join(lines) + "\n\n" + table + "\n")
print(table)

# %% [markdown]
# ## Median solve time per solver and family (successful solves, milliseconds)

# %%
fig, ax = plt.subplots(figsize=(8, 4))
factors = list(dict.fromkeys(r["factor"] for r in res["instances"]))
width = 0.8 / max(len(res["solvers"]), 1)
for k, s in enumerate(res["solvers"]):
    med = []
    for f in factors:
        t = [r["solvers"][s]["time_s"] for r in res["instances"] if r["factor"] == f and r["solvers"][s]["success"]]
        med.append(1e3 * float(np.median(t)) if t else np.nan)
    ax.bar(np.arange(len(factors)) + k * width, med, width, label=s)
ax.set_xticks(np.arange(len(factors)) + 0.4 - width / 2, factors)
ax.set_yscale("log")
ax.set_ylabel("median solve time, ms")
ax.legend(fontsize=7, ncol=2)
ax.grid(True, axis="y", alpha=0.3)
fig.tight_layout()
fig.savefig(FIG / "solver_profiles_time.png", dpi=110)
plt.close(fig)
show(FIG / "solver_profiles_time.png")

# %% [markdown]
# ## The convex fit by every suited conic solver
#
# Unpolished answers (the KKT polish would make them identical), largest difference from the first
# solver in normalised θ (entries of order one).  SCS runs at `eps_abs = eps_rel = 1e-10`
# (`optcal.families.accel.ellipsoid.CONIC_DEFAULTS`).

# %%
conic = res["conic"]
rows = ["| instance | " + " | ".join(f"{s} status, iters, Δθ" for s in conic["solvers"]) + " |",
        "|---|" + "---|" * len(conic["solvers"])]
for c in conic["instances"]:
    cells = []
    for s in conic["solvers"]:
        v = c["solvers"].get(s, {})
        cells.append(f"{v.get('status')}, {v.get('iterations', '—')}, {v.get('max_abs_difference_normalised', float('nan')):.1e}")
    rows.append(f"| {c['name']} | " + " | ".join(cells) + " |")
print("\n".join(rows))
print({k: v for k, v in conic["max_abs_difference_normalised"].items()})

# %% [markdown]
# ## Solvers that did not run, and recordings left out

# %%
print(json.dumps({"not run here": res["not_run"], "installed but not in this run": res["not_in_this_run"],
                  "recordings left out": res["real_skipped"], "runtime_s": round(res["runtime_s"], 1)}, indent=1))
