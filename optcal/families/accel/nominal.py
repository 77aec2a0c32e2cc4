"""Known orientations taken as nominal: maximum likelihood with each pose's small tilt estimated.

Six hand-placed faces or a turntable's steps give each pose a *nominal* direction of gravity
``n_k`` (unit, in the frame of the fixture), true only to the placement: the pose was tilted by a
small angle.  Yin 2014's least squares (:mod:`optcal.families.accel.sixpos`) takes ``n_k`` as exact,
so a tilt common to a pair of opposite faces reads as bias.  Here the gravity direction of pose k is
``f_k = (n_k + δ_k1 t_k1 + δ_k2 t_k2) / ‖·‖`` (``t_k1``, ``t_k2`` an orthonormal basis of the plane
normal to ``n_k``; a rotation about ``n_k`` itself, the vertical, leaves gravity unchanged and has
no parameter) and the mean reading is::

    u_k = C f_k + o + e_k,      e_k ~ N(0, σ_k² I),      δ_k ~ N(0, σ_t² I₂)

with ``C`` the full 3×3 sensitivity (raw units per g) and ``o`` the bias; the placement error is a
random effect of variance σ_t² (the nominal orientation is a measurement of the pose with that
error).  The fit:

1. ``σ_t`` (and σ, when the poses carry no ``sigma``) by restricted maximum likelihood (REML,
   Patterson & Thompson 1971) of the model linearised in δ: ``u_k = C n_k + o + ε_k`` with
   ``Cov ε_k = σ_t² C P_k Cᵀ + σ_k² I``, ``P_k = I − n_k n_kᵀ`` (generalised least squares for
   C, o at each σ_t; C in the covariance iterated to its fixed point);
2. ``C``, ``o`` and every ``δ_k`` jointly by maximum likelihood (IPOPT in CasADi, from the GLS
   calibration and the nominal directions, ``δ = 0``): minimise
   ``Σ ‖u_k − C f_k − o‖²/σ_k² + Σ ‖δ_k‖²/σ_t²``;
3. the covariance from the Gauss–Newton information of that problem; the calibration is
   ``ā = W a + V`` with ``W = C⁻¹``, ``V = −W o`` (the full form of Yin 2014, eq. 3).

What the pose set determines
----------------------------
Without the nominal orientations (every δ free) the poses determine only what their norms do:
the information on (C, o) with the tilts profiled out (its Schur complement) has a null space
that always holds the three rotations of the frame (the fixture's frame is defined by the nominal
orientations) and, for six faces, more: the combinations that rest on the placement.  They are
listed in the result's notes, and the tilt prior is what fixes them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.fit_result import SolverInfo
from optcal.core.identifiability import RankReport
from optcal.core.model import AXES
from optcal.core.norm_residual import norm_residuals
from optcal.core.poses import PoseTable
from optcal.errors import InputError
from optcal.families.accel.base import Stopwatch
from optcal.families.accel.exact_profile import tangent_bases
from optcal.families.accel.result import CalibrationResult
from optcal.families.accel.sixpos import PARAM_NAMES as WV_NAMES
from optcal.families.accel.sixpos import REFERENCE_COLUMNS, ANGLE_COLUMNS, reference_specific_force
from optcal.solvers.convergence import Remedy, check_solver, solver_record
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, cost_scale, nlp_solver

__all__ = ["NominalOrientationML", "nominal_directions"]

#: A pose further than this from every axis is not a face (with no orientation columns, the
#: nominal direction is the nearest axis; hand-placed faces sit within a few degrees of it).
FACE_MAX_ANGLE_DEG: float = 20.0
#: Fixed-point iterations of C in the covariance of the linearised model (C changes by < 1e-6 after 3).
GLS_ITERATIONS: int = 5
#: Search range of the placement scatter σ_t (degrees): from far below any placement to a crude one.
TILT_SIGMA_RANGE_DEG: tuple[float, float] = (1e-4, 20.0)
#: Smallest pose noise the REML search takes when the poses carry no sigma, relative to 1 g: far below any
#: accelerometer's noise, far above rounding (noise-free data would drive it to zero).
NOISE_FLOOR: float = 1e-9
#: Relative eigenvalue below which a combination counts as undetermined by the data alone.
RANK_TOL: float = 1e-9
IPOPT_REMEDY = Remedy(stopped_early="raise ipopt.max_iter", failed="use --method sixpos (the tilts taken as zero)")


def nominal_directions(poses: PoseTable) -> tuple[NDArray[np.float64], str, list[str]]:
    """The nominal gravity direction of each pose (unit), where it came from, and notes.

    From the orientation columns when the table has them (:func:`optcal.families.accel.sixpos.reference_specific_force`),
    else the axis nearest to each pose's reading (six faces), refused beyond :data:`FACE_MAX_ANGLE_DEG`.
    """
    extra = poses.extra
    if all(c in extra for c in REFERENCE_COLUMNS) or all(c in extra for c in ANGLE_COLUMNS):
        ref, source, notes = reference_specific_force(poses)
        return ref / np.linalg.norm(ref, axis=1, keepdims=True), source, notes
    from optcal.data.units import nominal_conversion

    zero = nominal_conversion(poses.units, poses.acc).offset
    d = poses.acc - zero
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    k = np.argmax(np.abs(d), axis=1)
    angle = np.degrees(np.arccos(np.clip(np.abs(d[np.arange(d.shape[0]), k]), 0.0, 1.0)))
    if np.any(angle > FACE_MAX_ANGLE_DEG):
        bad = int(np.argmax(angle))
        raise InputError(
            f"pose {int(poses.rows[bad])} reads {angle[bad]:.0f}° from every axis: not one of the six faces "
            f"(at most {FACE_MAX_ANGLE_DEG:g}°); give each pose's known orientation (roll_deg, pitch_deg or "
            f"{', '.join(REFERENCE_COLUMNS)}) for the known-orientation fit"
        )
    n = np.zeros_like(d)
    n[np.arange(d.shape[0]), k] = np.sign(d[np.arange(d.shape[0]), k])
    faces = ", ".join(f"{'+' if s > 0 else '-'}{AXES[j]}" for j, s in zip(k, n[np.arange(d.shape[0]), k]))
    return n, f"the axis nearest each reading (faces {faces}; largest angle {angle.max():.1f}°)", []


def _tangent_basis(n: NDArray[np.float64]) -> NDArray[np.float64]:
    """(k, 2, 3): two unit vectors normal to each ``n_k`` and to each other (:func:`tangent_bases`)."""
    return np.stack(tangent_bases(n), axis=1)


def _design(n: NDArray[np.float64]) -> NDArray[np.float64]:
    """(k, 3, 12): ``u_k = X_k β`` with β = (C row-major, o)."""
    X = np.zeros((n.shape[0], 3, 12))
    for i in range(3):
        X[:, i, 3 * i:3 * i + 3] = n
        X[:, i, 9 + i] = 1.0
    return X


def _gls(u: NDArray, n: NDArray, s2: NDArray, t2: float, beta: NDArray) -> tuple[NDArray, float]:
    """GLS of β at tilt variance ``t2`` (C in the covariance iterated), and the restricted log-likelihood."""
    X = _design(n)
    P = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    for _ in range(GLS_ITERATIONS):
        C = beta[:9].reshape(3, 3)
        S = t2 * np.einsum("ij,kjl,ml->kim", C, P, C) + s2[:, None, None] * np.eye(3)[None]
        Si = np.linalg.inv(S)
        A = np.einsum("kji,kjl,klm->im", X, Si, X)
        b = np.einsum("kji,kjl,kl->i", X, Si, u)
        beta = np.linalg.solve(A, b)
    r = u - np.einsum("kij,j->ki", X, beta)
    loglik = -0.5 * (np.sum(np.linalg.slogdet(S)[1]) + np.einsum("ki,kij,kj->", r, Si, r) + np.linalg.slogdet(A)[1])
    return beta, float(loglik)


class NominalOrientationML:
    """Calibration from poses of nominal orientation with their tilts estimated (module docstring).

    Parameters
    ----------
    tilt_sigma_deg : float, optional
        The placement scatter σ_t; default: estimated (REML).
    allow_degenerate : bool
        Accepted for ``optcal calibrate``'s uniform interface; the tilt prior makes every pose set
        that spans three dimensions determined, and the notes say what rests on it.
    """

    def __init__(self, tilt_sigma_deg: float | None = None, allow_degenerate: bool = False) -> None:
        if tilt_sigma_deg is not None and not tilt_sigma_deg > 0:
            raise InputError(f"tilt_sigma_deg must be positive, got {tilt_sigma_deg}")
        self.tilt_sigma_deg = tilt_sigma_deg

    def fit(self, poses: PoseTable) -> CalibrationResult:
        """Fit ``u_k = C f_k(δ_k) + o`` with the tilts as random effects; the result is ``ā = W a + V``."""
        if not isinstance(poses, PoseTable):
            raise InputError("fit() takes a PoseTable")
        poses.validate(min_poses=6)
        nominal, source, notes = nominal_directions(poses)
        if np.linalg.matrix_rank(nominal, tol=1e-6) < 3:
            raise InputError("the nominal orientations lie in one plane: they cannot determine a 3-axis calibration")
        from optcal.data.units import nominal_conversion

        # normalised readings (≈ g, zero at zero force): one IPOPT tolerance for g, m/s² and counts
        conv = nominal_conversion(poses.units, poses.acc)
        zero, per_g = np.asarray(conv.offset, dtype=float), float(conv.sensitivity)
        u = (poses.acc - zero) / per_g
        known = poses.sigma is not None
        with Stopwatch() as watch:
            beta0 = np.linalg.lstsq(_design(nominal).reshape(-1, 12), u.ravel(), rcond=None)[0]
            sigma, t_sigma, why = self._variances(u, nominal, None if poses.sigma is None else poses.sigma / per_g, beta0)
            beta_gls, _ = _gls(u, nominal, sigma**2, t_sigma**2, beta0)
            x, J_data, J_prior, cost, stats = _joint_fit(u, nominal, sigma, t_sigma, beta_gls)
        solver = solver_record(stats, watch.seconds, "IPOPT",
                               f"CasADi nlpsol, {poses.n} poses, 12 calibration + {2 * poses.n} tilt parameters")
        check_solver("nominal", solver, x, IPOPT_REMEDY)
        J = np.vstack([J_data, J_prior])
        cov_x = np.linalg.pinv(J.T @ J)
        # back to raw units: C = per_g C', o = per_g o' + zero
        to_raw = np.full(12, per_g)
        beta = x[:12] * to_raw + np.concatenate([np.zeros(9), zero])
        C, o = beta[:9].reshape(3, 3), beta[9:12]
        W: NDArray[np.float64] = np.asarray(np.linalg.inv(C), dtype=float)
        V = -W @ o
        G = _wv_jacobian(beta) * to_raw
        cov = G @ cov_x[:12, :12] @ G.T
        tilts = x[12:].reshape(-1, 2)
        tilt_se = np.sqrt(np.clip(np.diag(cov_x)[12:], 0.0, None)).reshape(-1, 2)
        f = _directions(nominal, tilts)
        residual = poses.acc @ W.T + V - f
        weights = 1.0 / (sigma * float(np.mean(np.abs(np.diag(W)))) * per_g) ** 2
        rank, words = _data_alone(J_data, x[:9].reshape(3, 3), poses.n)
        u = poses.acc
        tilt_deg = np.degrees(np.linalg.norm(tilts, axis=1))
        notes += [
            f"nominal orientations: {source}; each pose's tilt estimated (2 angles; a turn about the vertical does not "
            "change gravity and has no parameter)",
            f"placement scatter σ_t = {np.degrees(t_sigma):.3g}° ({why}); estimated tilts {np.sqrt(np.mean(tilt_deg**2)):.3g}° "
            f"rms, largest {tilt_deg.max():.3g}° (pose {int(poses.rows[int(np.argmax(tilt_deg))])})",
            f"without the nominal orientations the poses determine {rank} of 12 calibration combinations; " + words,
        ]
        return CalibrationResult(
            method="nominal",
            T=W, o=np.array(o, dtype=float), units=poses.units,
            params=np.concatenate([W.ravel(), V]), param_names=list(WV_NAMES), covariance=cov,
            residuals=norm_residuals(W, o, u), weights=np.full(poses.n, 1.0) * weights,
            chisqr=cost,
            n_observations=3 * poses.n, sigma_known=known, solver=solver,
            rows=[int(r) for r in poses.rows], exclusions=dict(poses.exclusions),
            identifiability=RankReport(rank=12, n_params=12, condition_number=float(np.linalg.cond(J.T @ J))),
            notes=notes,
            extra={"nominal": nominal, "tilts_deg": np.degrees(tilts), "tilts_stderr_deg": np.degrees(tilt_se),
                   "tilt_basis": _tangent_basis(nominal), "tilt_sigma_deg": float(np.degrees(t_sigma)),
                   "vector_residuals_g": residual, "determined_without_nominal": rank},
            W=W, V=V,
        )

    def _variances(self, u: NDArray, n: NDArray, sigma_given: NDArray | None, beta0: NDArray
                   ) -> tuple[NDArray[np.float64], float, str]:
        """σ_k and σ_t: given, or by REML (module docstring, step 1)."""
        from scipy.optimize import minimize

        lo, hi = np.log(np.radians(TILT_SIGMA_RANGE_DEG))
        if self.tilt_sigma_deg is not None and sigma_given is not None:
            return sigma_given, float(np.radians(self.tilt_sigma_deg)), "given"
        if sigma_given is not None:
            def negll(p: NDArray) -> float:
                return -_gls(u, n, sigma_given**2, float(np.exp(2 * np.clip(p[0], lo, hi))), beta0)[1]
            grid = np.linspace(lo, hi, 25)
            start = grid[int(np.argmin([negll(np.array([g])) for g in grid]))]
            res = minimize(negll, np.array([start]), method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-9})
            return sigma_given, float(np.exp(np.clip(res.x[0], lo, hi))), "REML, the poses' sigma given"
        scale = float(np.mean(np.abs(np.diag(beta0[:9].reshape(3, 3)))))

        def negll2(p: NDArray) -> float:
            t = float(np.exp(2 * np.clip(p[0], lo, hi))) if self.tilt_sigma_deg is None else np.radians(self.tilt_sigma_deg) ** 2
            noise = scale * np.exp(max(p[1], np.log(NOISE_FLOOR)))  # noise-free data: the likelihood grows without bound
            return -_gls(u, n, np.full(u.shape[0], noise**2), t, beta0)[1]
        res = minimize(negll2, np.array([np.log(np.radians(1.0)), np.log(1e-4)]), method="Nelder-Mead",
                       options={"xatol": 1e-4, "fatol": 1e-9, "maxiter": 2000})
        t_sigma = float(np.exp(np.clip(res.x[0], lo, hi))) if self.tilt_sigma_deg is None else float(np.radians(self.tilt_sigma_deg))
        noise = scale * float(np.exp(max(res.x[1], np.log(NOISE_FLOOR))))
        return np.full(u.shape[0], noise), t_sigma, "REML, with the pose noise σ (no sigma column)"


def _directions(n: NDArray, tilts: NDArray) -> NDArray[np.float64]:
    B = _tangent_basis(n)
    f = n + tilts[:, :1] * B[:, 0] + tilts[:, 1:] * B[:, 1]
    return f / np.linalg.norm(f, axis=1, keepdims=True)


def _joint_fit(u: NDArray, n: NDArray, sigma: NDArray, t_sigma: float, beta0: NDArray
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, dict[str, Any]]:
    """IPOPT on the joint problem (step 2): the solution, the Jacobians of the standardised data and prior
    residuals (``r_k/σ_k``, ``δ_k/σ_t``), the cost ``Σ ‖r_k/σ_k‖² + Σ ‖δ_k/σ_t‖²`` at the solution, the
    solver's statistics.

    IPOPT sees the cost times ``σ̄²`` (σ̄ the rms pose noise): the data residuals in g with weights of order
    one and the prior with weight ``(σ̄/σ_t)²``, so that its curvature is of order one whatever the noise
    (standardised by a tiny σ, noise-free data put the rounding of the start far outside any tolerance).
    """
    import casadi as ca

    k = u.shape[0]
    B = _tangent_basis(n)
    s_ref = float(np.sqrt(np.mean(sigma**2)))
    x = ca.SX.sym("x", 12 + 2 * k)
    C = ca.reshape(x[:9], 3, 3).T  # row-major
    o = x[9:12]
    res_data = []
    for j in range(k):
        d = n[j] + x[12 + 2 * j] * B[j, 0] + x[13 + 2 * j] * B[j, 1]
        f = d / ca.norm_2(d)
        res_data.append((ca.DM(u[j]) - ca.mtimes(C, f) - o) * (s_ref / float(sigma[j])))
    r_data = ca.vertcat(*res_data)  # g, weighted by σ̄/σ_k
    r_prior = x[12:] * (s_ref / t_sigma)
    start = np.concatenate([beta0, np.zeros(2 * k)])
    r0 = ca.Function("r0", [x], [ca.vertcat(r_data, r_prior)])(start)
    c = cost_scale(5 * k, float(np.sqrt(np.mean(np.square(np.asarray(r0))))))
    f_cost = c * (ca.sumsqr(r_data) + ca.sumsqr(r_prior))
    solver = nlp_solver("nominal_orientation_ml", {"x": x, "f": f_cost}, SCALED_COST_IPOPT_OPTIONS)
    sol, stats = solver.solve(x0=start)
    jac = ca.Function("nominal_residual_jacobians", [x], [ca.jacobian(r_data, x), ca.jacobian(r_prior, x), r_data, r_prior])
    Jd, Jp, rd, rp = (np.asarray(v, dtype=float) / s_ref for v in jac(sol))
    return sol, Jd, Jp, float(np.sum(rd**2) + np.sum(rp**2)), stats


def _wv_jacobian(beta: NDArray) -> NDArray[np.float64]:
    """d(W row-major, V)/d(C row-major, o) at β."""
    C, o = beta[:9].reshape(3, 3), beta[9:12]
    W = np.linalg.inv(C)
    G = np.zeros((12, 12))
    for a in range(9):
        E = np.zeros(9)
        E[a] = 1.0
        dW = -W @ E.reshape(3, 3) @ W
        G[:9, a] = dW.ravel()
        G[9:, a] = -dW @ o
    G[9:, 9:] = -W
    return G


def _data_alone(J_data: NDArray, C: NDArray, k: int) -> tuple[int, str]:
    """Rank of the calibration's information with every tilt free, and its null space in words."""
    Jb, Jt = J_data[:, :12], J_data[:, 12:]
    info = Jb.T @ Jb - Jb.T @ Jt @ np.linalg.pinv(Jt.T @ Jt) @ Jt.T @ Jb
    d = 1.0 / np.sqrt(np.clip(np.diag(Jb.T @ Jb), 1e-300, None))
    eigval, eigvec = np.linalg.eigh(info * np.outer(d, d))
    null = eigvec[:, eigval < RANK_TOL * eigval.max()]
    rank = 12 - null.shape[1]
    # the frame's rotations: C → C (I + [ω]×), o fixed, in the same normalised coordinates
    rot = []
    for w in np.eye(3):
        dC = C @ np.cross(np.eye(3), w)  # C [ω]× (columns e_j × ω = −[ω]× e_j; the span is what counts)
        rot.append(np.concatenate([dC.ravel(), np.zeros(3)]) / d)
    R = np.linalg.qr(np.column_stack(rot))[0]
    rest = null - R @ (R.T @ null)
    rest_u, s, _ = np.linalg.svd(rest, full_matrices=False)
    rest_u = rest_u[:, s > 1e-6]
    names = [f"C_{a}{b}" for a in AXES for b in AXES] + [f"o_{a}" for a in AXES]
    words = [f"the frame's 3 rotations (set by the nominal orientations)"]
    for v in rest_u.T:
        top = np.argsort(-np.abs(v))[:3]
        words.append("a combination of " + ", ".join(f"{v[i]:+.2f}·{names[i]}" for i in top))
    if rest_u.shape[1]:
        words[-1] += (f" ({rest_u.shape[1]} beyond the frame, with {k} poses: the sensor's non-orthogonality against "
                      "a fixture that is not square, which only the placement fixes)")
    return rank, "undetermined without them: " + "; ".join(words)


def known_orientation_hint(poses: PoseTable, raw_with_gyro: bool = False) -> str | None:
    """What to run when a self-calibration refuses poses that are faces of a cube (every pose near an axis,
    all three axes among them, at least six poses), or ``None`` when they are not.

    Parameters
    ----------
    poses : PoseTable
    raw_with_gyro : bool
        DATA is a raw recording with gyro columns (Ferraris' method applies).
    """
    if poses.n < 6 or not np.all(np.isfinite(poses.acc)):
        return None
    try:
        nominal, _, _ = nominal_directions(PoseTable(acc=poses.acc, units=poses.units, rows=poses.rows))
    except InputError:
        return None
    if np.linalg.matrix_rank(nominal, tol=1e-6) < 3:
        return None
    faces = sorted({f"{'+' if v[int(np.argmax(np.abs(v)))] > 0 else '-'}{AXES[int(np.argmax(np.abs(v)))]}" for v in nominal})
    ways = [
        "--method nominal (maximum likelihood with each face's small tilt estimated; no extra columns)",
        "--method sixpos (Yin 2014 least squares; needs each pose's orientation: roll_deg, pitch_deg or gx_ref, gy_ref, gz_ref)",
    ]
    if raw_with_gyro and len(faces) == 6:
        ways.insert(0, "--method ferraris (the six faces and a full turn about each axis of this raw recording: "
                       "accelerometer and gyroscope; --sections FILE for imucal's section list)")
    return (f"these poses lie on the faces {', '.join(faces)} of a cube: with their orientations known, they calibrate "
            "with " + "; or ".join(ways))
