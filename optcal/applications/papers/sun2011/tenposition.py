"""Sun & Cao 2011: four-step ten-position accelerometer calibration from alignment misalignments.

Derivation (the parts lost or garbled in the extracted text are re-derived here)
-------------------------------------------------------------------------------
Conventions are those of :mod:`optcal.applications.papers.sun2011.turntable` (ENU, body x right/y forward/z up,
``C = C_b^n = R_z(−ψ) R_x(θ) R_y(γ)``, which reproduces eq. 14) and of
:mod:`optcal.applications.papers.sun2011.alignment`.

*Eq. 3-6, 12-13.*  With ``f^b = g [C31, C32, C33]ᵀ`` (eq. 1) and
``V̄^b = b_a + ΔC_b^a f^b`` (eq. 2 without the scale factors, which eq. 11 makes
unidentifiable), the horizontal errors are ``[V̄_e, V̄_n] = C[0:2, :] V̄^b`` (eq. 4), i.e.
linear in the nine parameters p = [b_x, b_y, b_z, τ_xy, τ_yx, τ_xz, τ_zx, τ_yz, τ_zy]:
``[V̄_e, V̄_n]ᵀ = D(C) p`` (:func:`horizontal_design`).

*Eq. 7-10.*  After fine alignment ``φ̂_e = φ_e + V̄_n/g`` and ``φ̂_n = φ_n − V̄_e/g``
(:mod:`optcal.applications.papers.sun2011.alignment` explains why).  If the true misalignment φ is the same at two
positions, the differences of φ̂ depend on p only (eq. 9-10)::

    g (φ̂_e(t2) − φ̂_e(t1)) = V̄_n(t2) − V̄_n(t1),    −g (φ̂_n(t2) − φ̂_n(t1)) = V̄_e(t2) − V̄_e(t1)

*Step 1* (z vertical; positions 1a-1d = (0,0,0), (0,0,π), (π,0,0), (0,π,0), the paper's
t3-t6).  ``V̄_e = ±(b_x ∓ g τ_xy)``, ``V̄_n = ±(b_y ± g τ_yx)``; explicitly
V̄_e = (b_x − gτ_xy, −b_x + gτ_xy, b_x + gτ_xy, −b_x − gτ_xy) and
V̄_n = (b_y + gτ_yx, −b_y − gτ_yx, −b_y + gτ_yx, b_y − gτ_yx), hence (eq. 29)::

    b_x  = −g/4 (φ̂_n1a − φ̂_n1b + φ̂_n1c − φ̂_n1d)
    τ_xy = −1/4 (φ̂_n1c − φ̂_n1d − φ̂_n1a + φ̂_n1b)
    b_y  =  g/4 (φ̂_e1a − φ̂_e1b − φ̂_e1c + φ̂_e1d)
    τ_yx =  1/4 (φ̂_e1a − φ̂_e1b + φ̂_e1c − φ̂_e1d)

The first two lines are the printed eq. 29.  In the printed last two lines the signs of
the t5 and t6 terms are exchanged; taken literally they return ``g τ_yx`` for b_y and
``b_y/g`` for τ_yx, because pitching by π turns the y axis over while rolling by π turns x
over (the printed lines are the x pattern copied).  The lines above follow from eq. 12-13
and are checked in the tests against the least-squares solution.

*Step 2* (y vertical; 2a = (π/2, 0, 0), 2b = (−π/2, 0, 0), the paper's t7, t8).  After
compensating step 1: ``V̄_e(2a) − V̄_e(2b) = 2 g τ_xz``, so (eq. 30, first line)
``τ_xz = ½ (φ̂_n2b − φ̂_n2a)``.  (The north channel of the same pair gives
``b_z = g/2 (φ̂_e2b − φ̂_e2a)``, which the paper does not use; the least-squares check does.)

*Step 3* (y vertical, z horizontal; 3a = (π/2, π/2, β1), 3b = (−π/2, π/2, β2), eq. 14).
After compensating b_x and τ_xz, eq. 15-17 (b_x, τ_xx of the extracted text are b_z, τ_zx)::

    Δφ̂_e = φ̂_e3b − φ̂_e3a = k11 b_z + k12 τ_zx,   k11 = −(sin β2 − sin β1)/g,  k12 = −(sin β2 + sin β1)
    Δφ̂_n = φ̂_n3b − φ̂_n3a = k21 b_z + k22 τ_zx,   k21 = −(cos β2 − cos β1)/g,  k22 = −(cos β2 + cos β1)

(eq. 18).  Each equation determines one coefficient only if k12 = k21 = 0 (eq. 19-21; the
paper's "orthogonality"): sin β2 = −sin β1 and cos β2 = cos β1, i.e. **β1 + β2 = 0**, with
β ≠ kπ/2 so that k11 ∝ sin β and k22 ∝ cos β do not vanish (eq. 22).  Otherwise the
decoupled read-out ``b̂_z = Δφ̂_e/k11`` carries ``(k12/k11) τ_zx`` and ``τ̂_zx = Δφ̂_n/k22``
carries ``(k21/k22) b_z`` (:func:`coupling_bias`): for (30°, 50°), k12/k11 = 4.8 g, i.e. a
bias of 1.4·10⁻³ m/s² in b_z from τ_zx = 0.1′ alone, larger than b_z itself.  With
β1 = β, β2 = −β (eq. 23)::

    Δφ̂_e = (2 sin β / g) b_z,    Δφ̂_n = −2 cos β τ_zx

and a turntable angle error Δβ scales the two read-outs by (1 + cot β Δβ) and
(1 − tan β Δβ) (eq. 24-26); equal error rates need |cot β| = |tan β|: β = ±45°.  The
extracted text writes "β1 = −45°, β2 = 45°" but eq. 27 (Δφ̂_e = +√2 b_z/g) and Table 4
(path 4 = "45, −45") need β1 = 45°, β2 = −45°, which gives eq. 28::

    b_z = (√2/2) g Δφ̂_e,    τ_zx = −(√2/2) Δφ̂_n

*Step 4* (x vertical, pointing down; 4a = (0, π/2, β3), 4b = (π, −π/2, β4) ≡ (0, π/2, β4 + π)).
After compensating b_y and b_z::

    φ̂_e4a − φ̂_e4b = (cos β3 + cos β4) τ_yz + (sin β3 + sin β4) τ_zy
    φ̂_n4a − φ̂_n4b = −(sin β3 + sin β4) τ_yz + (cos β3 + cos β4) τ_zy

so again β3 + β4 = 0 decouples, and with β3 = 45° = −β4 (eq. 30, second and third lines,
where τ_yx, τ_xy of the extracted text are τ_yz, τ_zy)::

    τ_yz = (φ̂_e4a − φ̂_e4b)/√2,    τ_zy = (φ̂_n4a − φ̂_n4b)/√2

Unlike step 3, both read-outs of step 4 scale with cos β, so the equal-error-rate argument
does not apply there and β = 0 would give the larger signal (2 instead of √2); we keep the
paper's ±45° to reproduce eq. 30.

*Least-squares check.*  Eq. 10, 12, 13 over all ten positions at once, on uncompensated
data: ``φ̂_e(k) = c_e + V̄_n(k)/g``, ``φ̂_n(k) = c_n − V̄_e(k)/g`` with the common
misalignment (c_e, c_n) as two extra unknowns (differencing eliminates it in the paper):
20 equations, 11 unknowns (:func:`least_squares`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.applications.papers.sun2011.alignment import AlignmentResult, FilterTuning, align
from optcal.errors import InputError
from optcal.applications.papers.sun2011.turntable import (
    PARAM_NAMES,
    TAU_ENTRIES,
    AccelerometerErrors,
    PositionData,
    TurntablePosition,
    TurntableRun,
    step3_positions,
    ten_position_scheme,
)

#: Parameters determined by each step of Table 1 (the note: compensate before the next step).
STEP_PARAMS: dict[int, tuple[str, ...]] = {
    1: ("b_x", "tau_xy", "b_y", "tau_yx"),
    2: ("tau_xz",),
    3: ("b_z", "tau_zx"),
    4: ("tau_yz", "tau_zy"),
}
#: Table 4 of Sun 2011: step-3 paths (β1, β2) in degrees.
TABLE4_PATHS_DEG: tuple[tuple[float, float], ...] = ((30, 50), (20, 60), (30, -30), (45, -45), (60, -60))


def body_error_design(f_b: ArrayLike) -> NDArray[np.float64]:
    """``∂V̄^b/∂p`` (3×9) at specific force ``f^b`` (eq. 2-3)."""
    f = np.asarray(f_b, dtype=float).reshape(3)
    J = np.zeros((3, len(PARAM_NAMES)))
    J[:, :3] = np.eye(3)
    for name, (i, j, sign) in TAU_ENTRIES.items():
        J[i, PARAM_NAMES.index(name)] = sign * f[j]
    return J


def horizontal_design(C_bn: ArrayLike, gravity: float) -> NDArray[np.float64]:
    """``D`` (2×9) with ``[V̄_e, V̄_n]ᵀ = D p`` at attitude ``C_b^n`` (eq. 12-13)."""
    C = np.asarray(C_bn, dtype=float).reshape(3, 3)
    f_b = C.T @ np.array([0.0, 0.0, gravity])  # eq. 1
    return C[0:2, :] @ body_error_design(f_b)  # eq. 4


def misalignment_design(C_bn: ArrayLike, gravity: float) -> NDArray[np.float64]:
    """``M`` (2×9) with ``[Δφ_e, Δφ_n]ᵀ = M p``: eq. 7, ``Δφ_e = V̄_n/g``, ``Δφ_n = −V̄_e/g``."""
    D = horizontal_design(C_bn, gravity)
    return np.vstack([D[1], -D[0]]) / gravity


# --------------------------------------------------------------------------- closed forms


def step1_closed_form(phi: NDArray, gravity: float) -> dict[str, NDArray]:
    """Eq. 29 (corrected, module docstring).  ``phi``: (..., 4, 2) = φ̂_e, φ̂_n at 1a-1d."""
    e, n = phi[..., 0], phi[..., 1]
    return {
        "b_x": -gravity / 4 * (n[..., 0] - n[..., 1] + n[..., 2] - n[..., 3]),
        "tau_xy": -0.25 * (n[..., 2] - n[..., 3] - n[..., 0] + n[..., 1]),
        "b_y": gravity / 4 * (e[..., 0] - e[..., 1] - e[..., 2] + e[..., 3]),
        "tau_yx": 0.25 * (e[..., 0] - e[..., 1] + e[..., 2] - e[..., 3]),
    }


def step2_closed_form(phi: NDArray) -> dict[str, NDArray]:
    """Eq. 30, first line: ``τ_xz = ½ (φ̂_n2b − φ̂_n2a)``.  ``phi``: (..., 2, 2) at 2a, 2b."""
    return {"tau_xz": 0.5 * (phi[..., 1, 1] - phi[..., 0, 1])}


def step3_closed_form(phi: NDArray, beta: float, gravity: float) -> dict[str, NDArray]:
    """Eq. 23/28 for β1 = β, β2 = −β: ``b_z = g Δφ̂_e/(2 sin β)``, ``τ_zx = −Δφ̂_n/(2 cos β)``.

    ``phi``: (..., 2, 2) at 3a, 3b; Δ = 3b − 3a.  β = 45° gives eq. 28.
    """
    d = phi[..., 1, :] - phi[..., 0, :]
    return {"b_z": gravity * d[..., 0] / (2 * np.sin(beta)), "tau_zx": -d[..., 1] / (2 * np.cos(beta))}


def step4_closed_form(phi: NDArray, beta: float) -> dict[str, NDArray]:
    """Eq. 30 for β3 = β, β4 = −β: ``τ_yz = (φ̂_e4a − φ̂_e4b)/(2 cos β)``, same for τ_zy with φ̂_n.

    ``phi``: (..., 2, 2) at 4a, 4b.  β = 45° gives the paper's 1/√2.
    """
    d = phi[..., 0, :] - phi[..., 1, :]
    return {"tau_yz": d[..., 0] / (2 * np.cos(beta)), "tau_zy": d[..., 1] / (2 * np.cos(beta))}


# --------------------------------------------------------------------------- least squares


@dataclass(frozen=True)
class LeastSquaresSolution:
    """Eq. 10, 12, 13 solved over all positions at once.

    Attributes
    ----------
    params : ndarray, shape (runs, 9)
    common : ndarray, shape (runs, 2)
        Common misalignment (c_e, c_n), rad.
    rank : int
        Rank of the 2n×11 design (11 when every parameter is determined).
    """

    params: NDArray[np.float64]
    common: NDArray[np.float64]
    rank: int


def least_squares_design(attitudes: list[NDArray], gravity: float) -> NDArray[np.float64]:
    """Stacked design (2n × 11): ``[φ̂_e(k), φ̂_n(k)] = [c_e, c_n] + M(C_k) p``."""
    rows = []
    for C in attitudes:
        rows.append(np.hstack([np.eye(2), misalignment_design(C, gravity)]))
    return np.vstack(rows)


def least_squares(attitudes: list[NDArray], phi: NDArray, gravity: float) -> LeastSquaresSolution:
    """Solve eq. 10, 12, 13 for all parameters at once (``phi``: (runs, n, 2) = φ̂_e, φ̂_n)."""
    A = least_squares_design(attitudes, gravity)
    y = np.asarray(phi, dtype=float).reshape(phi.shape[0], -1)
    if A.shape[0] != y.shape[1]:
        raise InputError(f"{len(attitudes)} attitudes but {y.shape[1] // 2} positions of misalignment estimates")
    s = np.linalg.svd(A, compute_uv=False)
    rank = int(np.sum(s > s[0] * 1e-10))
    x = y @ np.linalg.pinv(A).T
    return LeastSquaresSolution(x[:, 2:], x[:, :2], rank)


# --------------------------------------------------------------------------- path analysis


def path_coefficients(beta1: float, beta2: float, gravity: float) -> NDArray[np.float64]:
    """``K`` of eq. 18: ``[Δφ̂_e, Δφ̂_n]ᵀ = K [b_z, τ_zx]ᵀ`` for the step-3 path (β1, β2), radians."""
    s1, s2, c1, c2 = np.sin(beta1), np.sin(beta2), np.cos(beta1), np.cos(beta2)
    return np.array([[-(s2 - s1) / gravity, -(s2 + s1)], [-(c2 - c1) / gravity, -(c2 + c1)]])


def decoupled_estimate(beta1: float, beta2: float, dphi: NDArray, gravity: float) -> NDArray[np.float64]:
    """The paper's read-out: one coefficient per equation, ``b_z = Δφ̂_e/k11``, ``τ_zx = Δφ̂_n/k22``.

    Exact only on decoupled paths (β1 + β2 = 0, eq. 22); equals eq. 23/28 there.
    ``dphi``: (..., 2) = Δφ̂_e, Δφ̂_n (3b − 3a).  Returns (..., 2) = b_z, τ_zx.
    """
    K = path_coefficients(beta1, beta2, gravity)
    return np.stack([dphi[..., 0] / K[0, 0], dphi[..., 1] / K[1, 1]], axis=-1)


def joint_estimate(beta1: float, beta2: float, dphi: NDArray, gravity: float) -> NDArray[np.float64]:
    """Both coefficients from both equations of eq. 18 (``K⁻¹ Δφ̂``); unbiased on any path
    with sin(β2 − β1) ≠ 0, its noise amplified by 1/|sin(β2 − β1)|."""
    K = path_coefficients(beta1, beta2, gravity)
    return np.asarray(dphi, float) @ np.linalg.inv(K).T


def coupling_bias(beta1: float, beta2: float, b_z: float, tau_zx: float, gravity: float) -> tuple[float, float]:
    """Bias of :func:`decoupled_estimate` from the cross terms of eq. 18: ``(k12/k11) τ_zx``, ``(k21/k22) b_z``."""
    K = path_coefficients(beta1, beta2, gravity)
    return float(K[0, 1] / K[0, 0] * tau_zx), float(K[1, 0] / K[1, 1] * b_z)


def error_rates(beta0: ArrayLike, dbeta: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Eq. 26: relative errors ``|Δb_z/b_z| = |cot β0 Δβ|`` and ``|Δτ_zx/τ_zx| = |tan β0 Δβ|``."""
    b = np.asarray(beta0, dtype=float)
    return np.abs(dbeta / np.tan(b)), np.abs(np.tan(b) * dbeta)


def equal_error_rate_angle() -> float:
    """β0 in (0, π/2) where the two rates of eq. 26 are equal: |cot β0| = |tan β0| → 45° (rad)."""
    return float(np.arctan(1.0))


# --------------------------------------------------------------------------- the scheme


@dataclass
class SchemeResult:
    """The four-step scheme run on one simulated session (every Monte Carlo run at once).

    Attributes
    ----------
    positions : tuple of TurntablePosition
    estimates : ndarray, shape (runs, 9)
        Closed-form estimates (eq. 28-30), step by step with compensation.
    phi_hat : dict of str to ndarray (runs, 3)
        Final φ̂ (e, n, u) at each position, compensated data.
    alignments : dict of str to AlignmentResult
        Filter runs at each position (compensated data).
    """

    positions: tuple[TurntablePosition, ...]
    estimates: NDArray[np.float64]
    phi_hat: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    alignments: dict[str, AlignmentResult] = field(default_factory=dict)

    def estimate(self, name: str) -> NDArray[np.float64]:
        return self.estimates[:, PARAM_NAMES.index(name)]


def align_position(
    session: TurntableRun, position: TurntablePosition, tuning: FilterTuning, compensation: AccelerometerErrors | None
) -> tuple[PositionData, AlignmentResult]:
    """Fine alignment at one position with the accelerometer output compensated by ``compensation``."""
    s = session.settings
    d = session.position(position)
    res = align(
        d.C_nominal, d.C_true, d.phi0, d.accel_error_b(compensation), d.gyro_error_b(),
        s.latitude, s.gravity, s.dt_s, tuning,
    )
    return d, res


def run_scheme(
    session: TurntableRun,
    tuning: FilterTuning,
    step3_beta: tuple[float, float] = (np.pi / 4, -np.pi / 4),
    step4_beta: tuple[float, float] = (np.pi / 4, -np.pi / 4),
) -> SchemeResult:
    """The four steps of Table 1, compensating what is known before each next step.

    Steps 3 and 4 use the closed forms for symmetric paths (β2 = −β1, β4 = −β3).
    """
    if not np.isclose(step3_beta[0], -step3_beta[1]) or not np.isclose(step4_beta[0], -step4_beta[1]):
        raise InputError("the closed forms of eq. 28-30 need β2 = −β1 and β4 = −β3; use path_estimates for other paths")
    g = session.settings.gravity
    positions = ten_position_scheme(step3_beta, step4_beta)
    est = np.zeros((session.turntable.runs, len(PARAM_NAMES)))
    result = SchemeResult(positions, est)
    for step in (1, 2, 3, 4):
        compensation = AccelerometerErrors(est.copy())
        phis = []
        for p in (q for q in positions if q.step == step):
            _, res = align_position(session, p, tuning, compensation)
            result.alignments[p.label] = res
            result.phi_hat[p.label] = res.final_misalignment
            phis.append(res.final_misalignment[:, :2])
        phi = np.stack(phis, axis=1)  # (runs, positions of the step, 2)
        if step == 1:
            found = step1_closed_form(phi, g)
        elif step == 2:
            found = step2_closed_form(phi)
        elif step == 3:
            found = step3_closed_form(phi, step3_beta[0], g)
        else:
            found = step4_closed_form(phi, step4_beta[0])
        for name, value in found.items():
            est[:, PARAM_NAMES.index(name)] = value
    return result


def least_squares_check(session: TurntableRun, tuning: FilterTuning, positions: tuple[TurntablePosition, ...]) -> LeastSquaresSolution:
    """All positions aligned on uncompensated data, then eq. 10, 12, 13 solved at once."""
    phis, attitudes = [], []
    for p in positions:
        d, res = align_position(session, p, tuning, None)
        phis.append(res.final_misalignment[:, :2])
        attitudes.append(d.C_nominal)
    return least_squares(attitudes, np.stack(phis, axis=1), session.settings.gravity)


@dataclass(frozen=True)
class PathEstimate:
    """Step 3 on one path (β1, β2), after the scheme's steps 1-2 compensation.

    Attributes
    ----------
    beta1, beta2 : float
        Radians.
    decoupled : ndarray, shape (runs, 2)
        The paper's read-out (b_z, τ_zx), :func:`decoupled_estimate`.
    joint : ndarray, shape (runs, 2)
        Both equations solved together, :func:`joint_estimate`.
    """

    beta1: float
    beta2: float
    decoupled: NDArray[np.float64]
    joint: NDArray[np.float64]


def path_estimates(
    session: TurntableRun, tuning: FilterTuning, scheme: SchemeResult, beta1: float, beta2: float
) -> PathEstimate:
    """Run step 3 on the path (β1, β2) with the scheme's step-1 and step-2 estimates compensated."""
    known = np.zeros_like(scheme.estimates)
    for step in (1, 2):
        for name in STEP_PARAMS[step]:
            k = PARAM_NAMES.index(name)
            known[:, k] = scheme.estimates[:, k]
    compensation = AccelerometerErrors(known)
    phis = [align_position(session, p, tuning, compensation)[1].final_misalignment[:, :2] for p in step3_positions(beta1, beta2)]
    dphi = phis[1] - phis[0]
    g = session.settings.gravity
    return PathEstimate(beta1, beta2, decoupled_estimate(beta1, beta2, dphi, g), joint_estimate(beta1, beta2, dphi, g))
