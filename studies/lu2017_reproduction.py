# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Lu et al. 2017: maximum-likelihood calibration, reproduced
#
# Section 3.1 of the paper: the simulated sensor (S_M = diag(1.2, 0.8, 1.3), o = [0.20, 0.15, 0.10] g,
# ρ = 2°, φ = 1°, λ = 1.5°, V_L as printed), Table 1 by Monte Carlo with every optcal method, and the
# paper's Fig. 2 (norm of the measured gravity before and after calibration) and Fig. 3 (the point cloud
# before and after). Regenerate with `python studies/lu2017_reproduction.py` (writes
# `studies/results/lu2017.md` and `studies/results/figures/lu2017_*.png`).

# %%
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from optcal import calibrate
from optcal.core.model import lu2017_reference_model
from optcal.applications.papers.lu2017 import format_report, run
from optcal.families.simulate.poses import simulate_poses, tilted_sweeps
from study_mode import FIGURES as FIG
from study_mode import show  # noqa: E402
from study_mode import RESULTS as OUT
from study_mode import size

# %% [markdown]
# ## Table 1 by Monte Carlo (200 runs, 1 mg per pose) and the literal schedule

# %%
res = run(runs=size(200, 10), seed=0, sigma=0.001, progress=False)
text = format_report(res)
print(text)

# %% [markdown]
# ## Fig. 2 and Fig. 3 analogues (one run, 5 mg per pose so that the scatter is visible)

# %%
model = lu2017_reference_model()
poses = simulate_poses(model, tilted_sweeps(40), 0.005, rng=np.random.default_rng(1))
fit = calibrate(poses, method="mle")
raw_norm = np.linalg.norm(poses.acc, axis=1)
cal = fit.correct(poses.acc)
cal_norm = np.linalg.norm(cal, axis=1)

fig, ax = plt.subplots(figsize=(8, 3.5))
ax.plot(raw_norm, ".-", lw=0.7, label="before calibration")
ax.plot(cal_norm, ".-", lw=0.7, label="after calibration (mle)")
ax.axhline(1.0, color="k", lw=0.8, label="reference 1 g")
ax.set_xlabel("pose")
ax.set_ylabel("|a| (g)")
ax.set_title("Lu 2017 Fig. 2 analogue: norm of the measured specific force")
ax.legend()
fig.tight_layout()
fig.savefig(FIG / "lu2017_fig2_norm.png", dpi=120)
show(FIG / "lu2017_fig2_norm.png")

fig = plt.figure(figsize=(9, 4.2))
for k, (pts, title) in enumerate(((poses.acc, "before calibration"), (cal, "after calibration"))):
    ax = fig.add_subplot(1, 2, k + 1, projection="3d")
    u, v = np.mgrid[0 : 2 * np.pi : 30j, 0 : np.pi : 15j]
    ax.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.8", lw=0.4)
    ax.scatter(*pts.T, s=6, c="C0" if k == 0 else "C1")
    ax.set_title(title)
    ax.set_box_aspect((1, 1, 1))
fig.suptitle("Lu 2017 Fig. 3 analogue: measured gravity vectors and the unit sphere")
fig.tight_layout()
fig.savefig(FIG / "lu2017_fig3_cloud.png", dpi=120)
show(FIG / "lu2017_fig3_cloud.png")

# %%
rms_before = float(np.sqrt(np.mean((raw_norm - 1) ** 2)))
rms_after = fit.rms_norm_residual_g
md = [
    "# Lu et al. 2017 reproduction",
    "",
    "Regenerate: `python studies/lu2017_reproduction.py` (or `optcal reproduce lu2017`).",
    "",
    "```",
    text,
    "```",
    "",
    f"Fig. 2/3 analogue (one run, 5 mg per pose, {poses.n} poses): rms of |a|-1 before {rms_before * 1e3:.1f} mg, "
    f"after {rms_after * 1e3:.2f} mg.",
    "",
    "![norm](figures/lu2017_fig2_norm.png)",
    "![cloud](figures/lu2017_fig3_cloud.png)",
]
(OUT / "lu2017.md").write_text("\n".join(md) + "\n")
