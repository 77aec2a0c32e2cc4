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
# # Pose planning: how good are the published schedules, and how many random poses is a plan worth?
#
# For the lumped model (nine parameters, gravity directions as nuisance) every schedule of n poses
# is scored by its D-efficiency against the best n poses, `exp((log det M − log det M*)/9)`, where
# `M*` is bounded by the certified relaxation of `optcal.applications.plan` (the bound is ≥ every n-pose design,
# so these efficiencies are lower bounds), and by the expected standard error of every parameter at
# 1 mg pose noise (nominal sensor T = I, o = 0 in g, so T entries are relative and o is in g).
# Schedules: Lu 2017's three sweeps as written and about tilted axes (`optcal.families.simulate.poses`), Yin 2014's
# six cube faces, Sun 2011's ten turntable positions, the real 38-pose hand-held Xsens session of
# imu_tk (`shared/data/imutk-xsens`, with its own convex fit as the prior), random sets, and the
# plans of `optcal plan` of the same sizes. Then a Monte Carlo: K planned poses against N random ones.
#
# Regenerate with `python studies/pose_planning.py` (writes `studies/results/pose_planning.md` and
# `studies/results/figures/pose_planning_*.png`; about two minutes on an idle machine).

# %%
from pathlib import Path

import numpy as np

from optcal.families.accel.calibration import calibrate
from optcal.errors import IdentifiabilityError
from optcal.core.identifiability import analyse_design
from optcal.core.model import PARAM_NAMES
from optcal.applications.plan import Prior, plan_poses
from optcal.applications.plan.candidates import sphere_candidates
from optcal.report.plan_figure import sphere_figure
from optcal.applications.plan.information import covariance, information
from optcal.families.simulate.poses import lu2017_sweeps, simulate_poses, six_position, tilted_sweeps, uniform_directions
from optcal.applications.papers.sun2011.turntable import ten_position_scheme

from study_mode import FIGURES as FIG  # noqa: E402
from study_mode import RESULTS as OUT  # noqa: E402
from study_mode import STUDIES as ROOT  # noqa: E402
from study_mode import show, size  # noqa: E402
SHARED = ROOT.parents[1] / "shared" / "data"
SIGMA = 1e-3  # g per axis, per pose
SEED = 15
NOMINAL = Prior.nominal()
lines: list[str] = ["# Pose planning (issue 15)", "",
                    f"Nominal sensor (T = I, o = 0, g), pose noise σ = {SIGMA * 1e3:g} mg per axis; "
                    "T entries relative, o in g. Regenerate: `python studies/pose_planning.py`.", ""]


def scores(directions: np.ndarray, prior: Prior = NOMINAL) -> tuple[float, np.ndarray]:
    """log det of the information (normalised, unit noise) and the standard errors (normalised) at SIGMA."""
    M = information(prior.information_vectors(directions))
    sign, logdet = np.linalg.slogdet(M)
    stderr = np.sqrt(np.diag(covariance(M, SIGMA * prior.scale)))  # raw noise of 1 mg
    return (logdet if sign > 0 and np.isfinite(stderr).all() else -np.inf), stderr


# %% [markdown]
# ## 1. The bound for n poses, and the plans
#
# Without given poses the relaxation is homogeneous in n (`M*(n) = n M*(1)`), so one certified
# bound per prior serves every n: `log det M*(n) = log det M*(1) + 9 log n`.

# %%
# quick mode (CI): a 300-direction grid instead of the planner's 2000 (the relaxation's cost grows with the grid)
GRID = size(None, sphere_candidates(300))
plans = {k: plan_poses(k, sigma=SIGMA, seed=SEED, candidates=GRID) for k in (9, 10, 12, 24, 36)}
bound_1 = plans[12].bound - 9 * np.log(12)


def d_efficiency(logdet: float, n: int, bound1: float = bound_1) -> float:
    return float(np.exp((logdet - bound1 - 9 * np.log(n)) / 9)) if np.isfinite(logdet) else 0.0


# %% [markdown]
# ## 2. The schedules

# %%
sun = np.array([p.attitude[2] for p in ten_position_scheme()])  # Sun 2011, eq. 1: f^b = third row of C_b^n
schedules = {
    "Lu 2017 sweeps as written (3 × 40)": lu2017_sweeps(40),
    "Lu 2017 sweeps about tilted axes (3 × 40)": tilted_sweeps(40),
    "Yin 2014 six positions": six_position(),
    "Sun 2011 ten positions": sun,
}
rows = []
for name, d in schedules.items():
    logdet, se = scores(d)
    rows.append((name, len(d), d_efficiency(logdet, len(d)), se))
for k, plan in plans.items():
    logdet, se = scores(plan.directions)
    rows.append((f"optcal plan, K = {k}", k, d_efficiency(logdet, k), se))

rng = np.random.default_rng(SEED)
random_rows = []
for n in (9, 12, 24, 36, 120):
    draws = [scores(uniform_directions(n, rng)) for _ in range(size(200, 10))]
    eff = np.array([d_efficiency(ld, n) for ld, _ in draws])
    worst = np.array([se.max() for _, se in draws])
    random_rows.append((n, eff, worst))
    median_se = np.median(np.array([se for _, se in draws]), axis=0)
    rows.append((f"random, n = {n} (median of 200)", n, float(np.median(eff)), median_se))

xsens_note = "real Xsens session not available (../shared/data/imutk-xsens absent)"
xsens_path = SHARED / "imutk-xsens" / "xsens_imutk.csv"
if xsens_path.exists():
    from optcal.data import load

    session = load(str(xsens_path))
    xsens_prior = Prior.of_poses(session, "the imu_tk Xsens session")
    xsens_plan = plan_poses(session.n, prior=xsens_prior, sigma=SIGMA * xsens_prior.scale, seed=SEED, candidates=GRID)
    corrected = xsens_prior.model.correct(session.acc)
    logdet, se = scores(corrected / np.linalg.norm(corrected, axis=1, keepdims=True), xsens_prior)
    xsens_eff = float(np.exp((logdet - xsens_plan.bound) / 9))
    _, se_plan = scores(xsens_plan.directions, xsens_prior)
    rows.append((f"imu_tk Xsens hand-held session (real, {session.n} poses)", session.n, xsens_eff, se))
    rows.append((f"optcal plan for the same sensor, K = {session.n}", session.n,
                 float(np.exp((xsens_plan.value - xsens_plan.bound) / 9)), se_plan))
    xsens_note = (f"real Xsens session: {session.n} static poses found in {xsens_path.name} "
                  f"(excluded: {session.exclusions}); prior: {xsens_prior.source}")

lines += ["## Schedules against the best design of the same size", "",
          "D-efficiency against the certified bound (a lower bound on the efficiency against the true optimum; "
          "0 = does not identify the model); standard errors in units of 10⁻⁴ at 1 mg pose noise.", "",
          "| schedule | n | D-eff. | " + " | ".join(PARAM_NAMES) + " |",
          "|---|---:|---:|" + "---:|" * len(PARAM_NAMES)]
for name, n, eff, se in rows:
    cells = " | ".join("∞" if not np.isfinite(v) or v > 1e3 else f"{v * 1e4:.2f}" for v in se)
    lines.append(f"| {name} | {n} | {eff:.3f} | {cells} |")
lines += ["", xsens_note, "", "Why the zeros (optcal.core.identifiability on the noise-free design):", ""]
for name, d in schedules.items():
    report = analyse_design(NOMINAL.model, d)
    if not report.identifiable:
        distinct = len(np.unique(np.round(d, 9), axis=0))
        lines.append(f"- {name}: {distinct} distinct gravity directions; {report.describe()}")
lines.append("")
print("\n".join(lines))

# %% [markdown]
# ## 3. How many random poses is a plan worth?
#
# Predicted: the smallest N at which the median random N-set has a worst standard error no larger
# than the K-pose plan's. Then a Monte Carlo of maximum-likelihood fits (`optcal.calibrate`,
# method mle) at 1 mg: K planned poses, and N random poses drawn afresh in every run.

# %%
K = 12
plan_worst = float(np.max(list(plans[K].stderr.values())))
N = K
while True:
    worst = np.median([scores(uniform_directions(N, rng))[1].max() for _ in range(size(200, 10))])
    if worst <= plan_worst:
        break
    N += 1

runs = size(300, 10)
truth = NOMINAL.model.theta


def mc_rms(make_directions) -> tuple[np.ndarray, int]:
    """RMS error of θ over the runs, and how many pose sets were refused as not identifying the model."""
    errors, refused = [], 0
    for r in range(runs):
        poses = simulate_poses(NOMINAL.model, make_directions(r), SIGMA, rng=np.random.default_rng([SEED, r]))
        try:
            errors.append(calibrate(poses, method="mle").params - truth)
        except IdentifiabilityError:
            refused += 1
    return np.sqrt(np.mean(np.square(errors), axis=0)), refused


rms_plan = mc_rms(lambda r: plans[K].directions)
rms_random_n = mc_rms(lambda r: uniform_directions(N, np.random.default_rng([SEED, 10_000 + r])))
rms_random_k = mc_rms(lambda r: uniform_directions(K, np.random.default_rng([SEED, 20_000 + r])))
lines += [f"## {K} planned poses against N random ones", "",
          f"Predicted: the median random set needs N = {N} poses for a worst standard error of "
          f"{plan_worst * 1e4:.2f}·10⁻⁴ (the {K}-pose plan's). Monte Carlo, {runs} maximum-likelihood fits each "
          f"(RMS error, 10⁻⁴; a fresh random set in every run):", "",
          "| design | " + " | ".join(PARAM_NAMES) + " | worst |", "|---|" + "---:|" * (len(PARAM_NAMES) + 1)]
for name, (rms, refused) in ((f"plan, K = {K}", rms_plan), (f"random, N = {N}", rms_random_n),
                             (f"random, n = {K}", rms_random_k)):
    note = f" ({refused} of {runs} sets refused as not identifying the model)" if refused else ""
    lines.append(f"| {name}{note} | " + " | ".join(f"{v * 1e4:.2f}" for v in rms) + f" | {rms.max() * 1e4:.2f} |")
lines += ["", f"Expected (Cramér–Rao) for the plan: "
          + ", ".join(f"{p} {v * 1e4:.2f}" for p, v in plans[K].stderr.items()), ""]
print("\n".join(lines[-8:]))

# %% [markdown]
# ## 4. Figures

# %%
fig = sphere_figure(plans[K].directions, title=f"D-optimal plan, K = {K} (efficiency {100 * plans[K].efficiency:.2f} %)")
fig.savefig(FIG / "pose_planning_sphere_k12.png", dpi=110)
show(FIG / "pose_planning_sphere_k12.png")

from matplotlib.figure import Figure

fig = Figure(figsize=(7.0, 4.0), layout="constrained")
ax = fig.subplots()
for n, eff, _ in random_rows:
    ax.boxplot(eff, positions=[np.log2(n)], widths=0.35, showfliers=False)
ax.plot([np.log2(k) for k in plans], [d_efficiency(scores(p.directions)[0], k) for k, p in plans.items()],
        "r*", ms=12, label="optcal plan")
for name, n, eff, _ in rows[:4]:
    ax.plot(np.log2(n), eff, "s", label=name)
ax.set_xticks([np.log2(n) for n in (6, 9, 12, 24, 36, 120)], ["6", "9", "12", "24", "36", "120"])
ax.set_xlabel("number of poses")
ax.set_ylabel("D-efficiency (vs certified bound)")
ax.set_ylim(-0.03, 1.03)
ax.legend(fontsize=7, loc="lower right")
ax.set_title("random sets (boxes, 200 draws) against schedules and plans", fontsize=10)
fig.savefig(FIG / "pose_planning_efficiency.png", dpi=110)
show(FIG / "pose_planning_efficiency.png")

(OUT / "pose_planning.md").write_text("\n".join(lines + [
    "Figures: `figures/pose_planning_sphere_k12.png` (the 12-pose plan on the sphere), "
    "`figures/pose_planning_efficiency.png` (D-efficiency by size).", ""]))
