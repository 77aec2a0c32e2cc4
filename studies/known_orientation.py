# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Known orientations: Yin 2014's least squares, the tilts estimated, and Ferraris
#
# Six hand-placed faces give each pose a *nominal* direction of gravity, true only to the placement.
# Three ways to use them, all on the same six face means:
#
# * **sixpos** — Yin 2014, eq. 4: least squares with the nominal directions taken as exact
#   (`optcal.families.accel.sixpos`); a tilt common to a pair of opposite faces reads as bias.
# * **nominal** — maximum likelihood with each face's tilt estimated as a random effect of scatter σ_t
#   (REML), then the joint fit in IPOPT (`optcal.families.accel.nominal`).
# * **ferraris** — Ferraris 1995 as imucal implements it: bias from the pairs, scale and axes from their
#   differences (`optcal.families.ferraris.method.ferraris_accelerometer`, imucal's eqs. 19-23).
#
# 1. **imucal's example session** (`shared/data/imucal-ferraris`): the three fits on its six faces (imucal's
#    own section list), judged on the seven rests of the session none of them used.
# 2. **Monte Carlo**: six faces of a sensor with known calibration, each tilted by N(0, σ_t²) per axis;
#    the bias error, the scale error and the error of |a| on random orientations, for three σ_t.
# 3. **What the poses determine** without the nominal orientations.
#
# Regenerate with `python studies/known_orientation.py` (writes `studies/results/known_orientation.md`).

# %%
import numpy as np

from optcal.core.poses import PoseTable
from optcal.data import load_with_segmentation
from optcal.families.accel.calibration import calibrate
from optcal.families.ferraris import regions_from_section_list
from optcal.families.ferraris.method import ferraris_accelerometer

from study_mode import RESULTS as OUT  # noqa: E402
from study_mode import STUDIES, size  # noqa: E402

DATA = STUDIES.parents[1] / "shared" / "data" / "imucal-ferraris"
FACES = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")
NOMINAL = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
METHODS = ("sixpos", "nominal", "ferraris")
lines: list[str] = ["# Known orientations: Yin 2014's least squares, the tilts estimated (nominal), Ferraris", ""]


def fit_faces(acc: np.ndarray, sigma: np.ndarray, units: str) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(W, V) of each method on six face means in the order x_p, x_a, y_p, y_a, z_p, z_a."""
    extra = {"gx_ref": NOMINAL[:, 0], "gy_ref": NOMINAL[:, 1], "gz_ref": NOMINAL[:, 2]}
    poses = PoseTable(acc=acc, sigma=sigma, units=units, extra=extra)
    out = {}
    for method in ("sixpos", "nominal"):
        r = calibrate(poses, method=method)
        out[method] = (r.W, r.V)
    K, R, b = ferraris_accelerometer(acc[0::2].T, acc[1::2].T)
    W = np.linalg.inv(R) @ np.linalg.inv(K)
    out["ferraris"] = (W, -W @ b)
    return out


def norm_error(W: np.ndarray, V: np.ndarray, acc: np.ndarray) -> np.ndarray:
    return np.linalg.norm(acc @ W.T + V, axis=1) - 1.0


# %% [markdown]
# ## 1. imucal's example session
# The face means over imucal's own sections; the held-out rests are the static intervals of the recording
# that share no sample with a face.

# %%
real: dict[str, dict[str, float]] = {}
if (DATA / "example_ferraris_session.csv").exists():
    loaded = load_with_segmentation(DATA / "example_ferraris_session.csv", rate=102.4)
    seg = loaded.segmentation
    regions = regions_from_section_list(seg.recording, str(DATA / "example_ferraris_session_list.json"), seg)
    rec = seg.recording
    acc = np.array([rec.acc[regions.sections[f].samples].mean(axis=0) for f in FACES])
    sigma = np.array([rec.acc[regions.sections[f].samples].std(axis=0, ddof=1).mean()
                      / np.sqrt(regions.sections[f].samples.size) for f in FACES])
    held = np.array([iv.mean for iv in seg.intervals if iv.number in regions.held_out])
    fits = fit_faces(acc, sigma, rec.units)
    lines += ["## imucal's example session (six faces from imucal's section list; "
              f"{held.shape[0]} rests held out)", "",
              "| method | bias o (m/s²) | scale (m/s² per g) | rms / max \\|a\\|−1 on the faces (mg) | rms / max on the held-out rests (mg) |",
              "|---|---|---|---|---|"]
    for m in METHODS:
        W, V = fits[m]
        o = -np.linalg.solve(W, V)
        scale = np.linalg.norm(np.linalg.inv(W), axis=0)  # raw reading per g along each calibrated axis
        e_in, e_out = norm_error(W, V, acc), norm_error(W, V, held)
        real[m] = {"rms_in_mg": 1e3 * float(np.sqrt(np.mean(e_in**2))), "rms_out_mg": 1e3 * float(np.sqrt(np.mean(e_out**2)))}
        lines.append(f"| {m} | {', '.join(f'{v:.4f}' for v in o)} | {', '.join(f'{v:.4f}' for v in scale)} | "
                     f"{real[m]['rms_in_mg']:.3f} / {1e3 * np.max(np.abs(e_in)):.3f} | "
                     f"{real[m]['rms_out_mg']:.3f} / {1e3 * np.max(np.abs(e_out)):.3f} |")
    nominal_fit = calibrate(PoseTable(acc=acc, sigma=sigma, units=rec.units,
                                      extra={"gx_ref": NOMINAL[:, 0], "gy_ref": NOMINAL[:, 1], "gz_ref": NOMINAL[:, 2]}),
                            method="nominal")
    lines += ["", f"nominal: {nominal_fit.notes[-2]}.", ""]
    print("\n".join(lines))
else:
    lines += ["(imucal's example session is not present: section 1 skipped)", ""]

# %% [markdown]
# ## 2. Monte Carlo
# A sensor `u = C f + o` (C: scales 1 %, cross-axis terms 0.4 %; bias 20-30 mg), six faces each tilted by
# N(0, σ_t²) per axis, pose noise 20 µg; every method fits the same six means; the error of |a| is measured
# on 200 random orientations of the true sensor.

# %%
RUNS = size(200, 12)
SIGMA_G = 2e-5
rng = np.random.default_rng(2014)
check = rng.standard_normal((200, 3))
check /= np.linalg.norm(check, axis=1, keepdims=True)
mc: dict[float, dict[str, dict[str, float]]] = {}
for tilt_deg in (0.1, 0.3, 1.0):
    err: dict[str, list[tuple[float, float, float]]] = {m: [] for m in METHODS}
    for _ in range(RUNS):
        C = np.diag(1 + 0.01 * rng.standard_normal(3)) + 0.004 * rng.standard_normal((3, 3))
        o = 0.025 * rng.standard_normal(3)
        t = np.radians(tilt_deg) * rng.standard_normal((6, 3))
        f = NOMINAL + t - (t * NOMINAL).sum(axis=1, keepdims=True) * NOMINAL
        f /= np.linalg.norm(f, axis=1, keepdims=True)
        u = f @ C.T + o + SIGMA_G * rng.standard_normal((6, 3))
        for m, (W, V) in fit_faces(u, np.full(6, SIGMA_G), "g").items():
            o_hat = -np.linalg.solve(W, V)
            scale_err = np.linalg.norm(np.linalg.inv(W), axis=0) / np.linalg.norm(C, axis=0) - 1
            e = norm_error(W, V, check @ C.T + o)
            err[m].append((float(np.linalg.norm(o_hat - o)), float(np.sqrt(np.mean(scale_err**2))),
                           float(np.sqrt(np.mean(e**2)))))
    mc[tilt_deg] = {m: dict(zip(("bias_mg", "scale_ppm", "norm_mg"),
                                (1e3 * float(np.sqrt(np.mean(np.square([v[0] for v in err[m]])))),
                                 1e6 * float(np.sqrt(np.mean(np.square([v[1] for v in err[m]])))),
                                 1e3 * float(np.sqrt(np.mean(np.square([v[2] for v in err[m]])))))))
                    for m in METHODS}
mc_lines = [f"## Monte Carlo ({RUNS} runs per tilt; rms over the runs)", "",
            "| placement σ_t | method | bias error (mg) | scale error (ppm) | \\|a\\|−1 on 200 orientations (mg) |",
            "|---|---|---|---|---|"]
for tilt_deg, row in mc.items():
    for m in METHODS:
        v = row[m]
        mc_lines.append(f"| {tilt_deg:g}° | {m} | {v['bias_mg']:.3f} | {v['scale_ppm']:.0f} | {v['norm_mg']:.3f} |")
print("\n".join(mc_lines))
lines += mc_lines + [""]

# %% [markdown]
# ## 3. What the poses determine without the nominal orientations
# The information on the 12 calibration numbers (C, o) with every tilt free (its Schur complement), as the
# `nominal` fit reports it: six faces determine six combinations (their six norms); the frame's three
# rotations and three more (the sensor's non-orthogonality against a fixture that is not square) rest on
# the placement. Twelve orientations spread over the sphere determine nine (all but the frame).

# %%
rng = np.random.default_rng(7)
C = np.diag([1.01, 0.99, 1.02]) + 0.004 * rng.standard_normal((3, 3))
spread = rng.standard_normal((12, 3))
spread /= np.linalg.norm(spread, axis=1, keepdims=True)
det_lines = ["## What the poses determine without the nominal orientations", "",
             "| pose set | combinations of (C, o) determined, of 12 | undetermined |", "|---|---|---|"]
for name, n in (("six faces", NOMINAL), ("12 spread orientations", spread)):
    t = np.radians(0.3) * rng.standard_normal(n.shape)
    f = n + t - (t * n).sum(axis=1, keepdims=True) * n
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    u = f @ C.T + SIGMA_G * rng.standard_normal(n.shape)
    r = calibrate(PoseTable(acc=u, sigma=np.full(len(u), SIGMA_G),
                            extra={"gx_ref": n[:, 0], "gy_ref": n[:, 1], "gz_ref": n[:, 2]}), method="nominal")
    det_lines.append(f"| {name} | {r.extra['determined_without_nominal']} | "
                     f"{r.notes[-1].split('undetermined without them: ')[-1]} |")
print("\n".join(det_lines))
lines += det_lines + [""]

# %% [markdown]
# ## Reading
# With hand-placed faces the least squares' bias error grows with the tilt (a tilt of 0.3° puts 5 mg of
# gravity on the other axes; about 3 mg of bias error rms in the Monte Carlo), while the pair-based bias
# (Ferraris) and the tilt-estimating fit (nominal) keep it near the noise level up to 0.3°; on imucal's
# session both cut the held-out error to a third of the least squares'. Ferraris and nominal agree to a few
# µg on the bias; nominal's scale error is the smaller at 1° of tilt. The non-orthogonality is set by the
# placement in all three (six faces cannot tell the sensor's from a fixture that is not square), so the
# error of |a| on other orientations grows with the tilt alike: more orientations, not another estimator,
# fix that.

# %%
(OUT / "known_orientation.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
print(f"written {OUT / 'known_orientation.md'}")
