"""The extended fit: norm residuals with the model inverted inside, vectorised, solved by least squares.

Every term of :class:`~optcal.core.extended_model.ExtendedModel` is inverted in closed form per
axis (:func:`optcal.core.extended_model.invert_axis`, the same function the extended calibration
applies), and the residual is Lu 2017's norm residual of the recovered linear output,
``r = ‖T y(a)‖ − 1`` (eq. 13), weighted by ``1/(σ_k ‖Tᵀ ā_k‖)²`` (eq. 14).  Why this and not
the errors-in-variables problem with a latent direction per pose
(:mod:`optcal.families.accel.exact`)?  Eliminating the latent unit direction from eq. 8 leaves, to
first order in the noise, exactly this weighted norm residual (the distance of the measurement
to the ellipsoid along its normal, :mod:`optcal.core.identifiability`); the difference is of relative
order σ² (≈1e-6 for mg noise), far below any effect worth reporting.  The norm-residual problem
has ``9 + P`` unknowns instead of ``9 + P + 3n``, so the hundreds of re-solves of a bootstrap and
a k-fold selection stay fast, and the held-out residual of a pose (the model inverted at its own
measurement) is the same formula.

Speed (issue 13): the residuals of all poses are evaluated in whole-array numpy operations, and
their Jacobian by the complex step (``∂r/∂x_k = Im r(x + i h e_k)/h``, exact to rounding for this
analytic residual; Squire & Trapp 1998), all free parameters in one broadcast evaluation.  The
problem is a small dense nonlinear least-squares problem (``9 + P`` unknowns, ``n`` residuals),
solved by scipy's Levenberg–Marquardt (MINPACK) or, for the robust Cauchy loss of the outlier
search, its trust-region reflective method, warm-started from the previous fit.  Nothing is built
per data set or per n: the bootstrap, the k-fold and the selection only re-solve.  An effect set
is chosen by keeping the unused coefficients at zero (they are not variables of the solve).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.effects import BIAS_STEP, FITTED, MAX_ORDER, SESSION_BIAS
from optcal.applications.diagnosis.regressors import Regressors
from optcal.core.extended_model import PARAMETRIC, ExtendedModel, inverse_lower, invert_axis
from optcal.core.model import LumpedModel


def _beta_layout() -> dict[tuple[str, int, int], int]:
    index: dict[tuple[str, int, int], int] = {}
    for effect in FITTED:
        for axis in range(3):
            for order in range(1, MAX_ORDER[effect] + 1):
                index[(effect, axis, order)] = len(index)
    return index


#: (effect, axis number, order) → index of its coefficient in β (after the nine entries of θ).  For
#: the session offsets, "order" k is session k's offset from session 0 (its regressor the indicator).
BETA_INDEX: dict[tuple[str, int, int], int] = _beta_layout()
N_BETA: int = len(BETA_INDEX)
N_X: int = 9 + N_BETA


#: Complex-step size (any tiny number: no subtraction, so no cancellation).
COMPLEX_STEP: float = 1e-30
#: Least-squares tolerances: relative change of the cost and of x.  The norm residual ``‖v‖ − 1``
#: loses about 1e-16 absolutely to cancellation, so the cost is known to ~1e-13 relatively near the
#: optimum; 1e-12 stops there, with the parameters within ~1e-10 of their size of the optimum, far
#: inside any standard error.
TOLERANCE: float = 1e-12
#: Largest number of residual evaluations of one solve.
MAX_EVALUATIONS: int = 400


def _real_floor(v: Any, low: float) -> Any:
    """``max(v, low)`` on the real part, keeping the complex step's imaginary part."""
    return np.where(np.real(v) > low, v, low)


def session_indicators(session: NDArray[np.intp] | None, n: int) -> list[NDArray[np.float64]]:
    """Indicator of sessions 1, 2, ... of each pose: the regressors of the session offsets (session 0 is the reference)."""
    if session is None:
        return [np.zeros(n)] * MAX_ORDER[SESSION_BIAS]
    return [(session == k).astype(float) for k in range(1, MAX_ORDER[SESSION_BIAS] + 1)]


def step_indicator(step: NDArray[np.float64] | None, n: int) -> list[NDArray[np.float64]]:
    """The regressors of the bias steps, one per order of ``bias_step``: step k's is 1 for the poses after it, 0
    before (``step`` of shape (n,) for one step or (n, m) for m; zeros for the steps not placed)."""
    columns = [] if step is None else ([step] if step.ndim == 1 else list(step.T))
    return columns + [np.zeros(n)] * (MAX_ORDER[BIAS_STEP] - len(columns))


def regressor_rows(tau: NDArray, s: NDArray, session: NDArray[np.intp] | None = None,
                   step: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Each coefficient's regressor, shape (N_BETA, n): row ``b`` of β's coefficient ``b`` multiplies it.

    The powers of the normalised temperature ``τ`` (temperature bias and scale) and time ``s`` (bias drift), the
    sessions' indicators (:func:`session_indicators`) and the steps' (:func:`step_indicator`); the nonlinearity's row
    is zero (its term is not linear in a regressor).
    """
    n = tau.shape[0]
    values = {"temperature_bias": [tau**p for p in range(1, 4)], "temperature_scale": [tau**p for p in range(1, 4)],
              "bias_drift": [s**p for p in range(1, 4)], SESSION_BIAS: session_indicators(session, n),
              BIAS_STEP: step_indicator(step, n)}
    rows = np.zeros((N_BETA, n))
    for (effect, _, p), b in BETA_INDEX.items():
        if effect in values:
            rows[b] = values[effect][p - 1]
    return rows


def extended_residuals(x: NDArray, u: NDArray, tau: NDArray, s: NDArray,
                       used: NDArray[np.intp] | None = None, session: NDArray[np.intp] | None = None,
                       step: NDArray[np.float64] | None = None,
                       rows: NDArray[np.float64] | None = None) -> NDArray:
    """``r = ‖T y(a)‖ − 1`` of every pose, for one or several parameter vectors (normalised units).

    Parameters
    ----------
    x : ndarray, shape (N_X,) or (m, N_X)
        ``[θ (9), β (N_BETA)]``, real or complex (complex step); β multiplies powers of the
        normalised temperature ``τ`` and time ``s`` (:class:`Regressors`), so each is a number in
        g (bias terms), a relative scale (temperature scale) or g/g² (nonlinearity).
    u : ndarray, shape (n, 3)
        Normalised measurements.
    tau, s : ndarray, shape (n,)
    used : ndarray of int, optional
        Indices into β of the coefficients to include (default every one); the others are zero.
    session : ndarray of int, shape (n,), optional
        Session of each pose (0, 1, ...; default all 0): the session offsets are biases of the
        sessions after the first.
    step : ndarray, shape (n,) or (n, m), optional
        1 for the poses after each bias step, 0 before (default: no step).
    rows : ndarray, shape (N_BETA, n), optional
        :func:`regressor_rows` of ``tau, s, session, step`` when the caller keeps them (a solve's many evaluations).

    Returns
    -------
    ndarray, shape (n,) or (m, n)
    """
    x = np.asarray(x)
    single = x.ndim == 1
    X = x[None, :] if single else x
    col = [X[:, k : k + 1] for k in range(9)]
    L: list[list[NDArray | int]] = [[col[0], 0, 0], [col[1], col[2], 0], [col[3], col[4], col[5]]]  # T, lower-triangular
    C = inverse_lower(L)
    used_set = set(range(N_BETA)) if used is None else {int(b) for b in used}
    R = regressor_rows(tau, s, session, step) if rows is None else rows
    zero = np.zeros((1, 1))

    def poly(effect: str, axis: int) -> Any:
        total: Any = zero
        for p in range(1, MAX_ORDER[effect] + 1):
            b = BETA_INDEX[(effect, axis, p)]
            if b in used_set:
                total = total + X[:, 9 + b : 10 + b] * R[b][None, :]
        return total

    y = []
    for i in range(3):
        S = np.sqrt(sum(C[i][j] ** 2 for j in range(i + 1)))
        bias = (poly("temperature_bias", i) + poly("bias_drift", i) + poly(SESSION_BIAS, i) + poly(BIAS_STEP, i))
        scale = poly("temperature_scale", i)
        b2 = BETA_INDEX[("scale_nonlinearity", i, 1)]
        k2 = X[:, 9 + b2 : 10 + b2] if b2 in used_set else zero
        y.append(invert_axis(u[None, :, i] - col[6 + i], S, bias, scale, k2, np.sqrt, _real_floor))
    v = [sum(L[i][j] * y[j] for j in range(i + 1)) for i in range(3)]
    r = np.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2) - 1.0  # Lu 2017, eq. 13
    return r[0] if single else r


#: The last :func:`sensitivity_jacobian` asked for: ``L``'s six entries (bytes) and its read-only result (speed only:
#: a third of the diagnosis's Jacobians are taken again at the ``L`` of the one before, a fit's covariance after it).
_LAST_SENSITIVITY: dict[bytes, tuple[NDArray, NDArray]] = {}


def sensitivity_jacobian(theta_L: NDArray) -> tuple[NDArray, NDArray]:
    """``S_i = ‖row i of L⁻¹‖`` and ``∂S_i/∂x_k`` for the six entries of ``L`` (complex step on a 3×3).

    The result is read-only and the last one is kept: the same six entries give it back without recomputing.
    """
    key = np.asarray(theta_L[:6], dtype=float).tobytes()
    last = _LAST_SENSITIVITY.get(key)
    if last is not None:
        return last
    X = np.tile(np.asarray(theta_L[:6], dtype=complex), (7, 1))
    X[np.arange(1, 7), np.arange(6)] += 1j * COMPLEX_STEP
    col = [X[:, k] for k in range(6)]
    C = inverse_lower([[col[0], 0, 0], [col[1], col[2], 0], [col[3], col[4], col[5]]])
    S = np.stack([np.sqrt(sum(C[i][j] ** 2 for j in range(i + 1))) for i in range(3)])  # (3, 7)
    value, gradient = np.real(S[:, 0]).copy(), np.imag(S[:, 1:]) / COMPLEX_STEP
    value.setflags(write=False)
    gradient.setflags(write=False)
    _LAST_SENSITIVITY.clear()  # one entry: threads that share the module see a result or recompute it
    _LAST_SENSITIVITY[key] = (value, gradient)
    return value, gradient


#: The bias terms' coefficients in β (the bias of a pose is their sum, a number in g): their index, axis, and
#: whether their regressor is a session's or a step's indicator (zero rows of the Jacobian without sessions or steps).
_BIASES: tuple[tuple[str, str], ...] = (("temperature_bias", "temp"), ("bias_drift", "t"), (SESSION_BIAS, "session"),
                                        (BIAS_STEP, "step"))
_BIAS_B = np.array(sorted(BETA_INDEX[(e, i, p)] for e, _ in _BIASES for i in range(3)
                          for p in range(1, MAX_ORDER[e] + 1)), dtype=np.intp)
_BETA_AXIS = np.array([key[1] for key in sorted(BETA_INDEX, key=BETA_INDEX.__getitem__)], dtype=np.intp)
_BETA_EFFECT = [key[0] for key in sorted(BETA_INDEX, key=BETA_INDEX.__getitem__)]
#: the bias terms' indices whose regressor is not zero (by whether the data have sessions and steps)
_BIAS_ROWS: dict[tuple[bool, bool], NDArray[np.intp]] = {
    (sessions, steps): _BIAS_B[[(sessions or _BETA_EFFECT[b] != SESSION_BIAS) and (steps or _BETA_EFFECT[b] != BIAS_STEP)
                                for b in _BIAS_B.tolist()]]
    for sessions in (False, True) for steps in (False, True)}
_SCALE_B = np.array([BETA_INDEX[("temperature_scale", i, p)] for i in range(3)
                     for p in range(1, MAX_ORDER["temperature_scale"] + 1)], dtype=np.intp)
_NONLINEAR_B = np.array([BETA_INDEX[("scale_nonlinearity", i, 1)] for i in range(3)], dtype=np.intp)


def residuals_and_jacobian(x: NDArray[np.float64], d: "PoseData",
                           free: NDArray[np.intp] | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Residuals of :func:`extended_residuals` and their Jacobian w.r.t. ``x[free]`` (default all), (n, len(free)).

    The chain rule through the closed-form inversion, in whole-array operations: with
    ``ā = v/‖v‖`` and ``g = Lᵀ ā`` (``∂r/∂y``), the root ``y`` of ``y + k2 y²/S = w`` has
    ``dy = (dw + k2 y²/S² dS − y²/S dk2)/(1 + 2 k2 y/S)`` and
    ``dw = (dz − bias dS − S dbias − w dscale)/(1 + scale)``; ``∂r/∂L_ij = ā_i y_j`` plus the
    path through ``S`` (``L⁻¹``'s row norms).  Checked against the complex step in the tests.
    The three axes are one (3, n) array and the coefficients' regressors one (N_BETA, n) array built
    once per data set (:meth:`PoseData.regressor_rows`): a solve of a few dozen poses costs Python
    calls, not arithmetic.
    """
    n = d.n
    Lm = np.array([[x[0], 0.0, 0.0], [x[1], x[2], 0.0], [x[3], x[4], x[5]]])
    S, dS = sensitivity_jacobian(x)
    R = d.regressor_rows()
    beta = x[9:]
    # each axis's bias (g) and temperature scale: the sum of its nonzero coefficients times their regressors,
    # added in β's order (the order the terms were always added in)
    bias = np.zeros((3, n))
    scale = np.zeros((3, n))
    for b in np.flatnonzero(beta).tolist():
        effect = _BETA_EFFECT[b]
        if effect == "temperature_scale":
            scale[_BETA_AXIS[b]] += beta[b] * R[b]
        elif effect != "scale_nonlinearity":
            bias[_BETA_AXIS[b]] += beta[b] * R[b]
    k2 = beta[_NONLINEAR_B][:, None]
    z = d.u.T - x[6:9, None]
    Sc = S[:, None]
    y = invert_axis(z, Sc, bias, scale, k2, np.sqrt, np.maximum)
    w = (z - Sc * bias) / (1 + scale)
    v = Lm @ y
    norm = np.sqrt(np.sum(v * v, axis=0))
    r = norm - 1.0  # Lu 2017, eq. 13
    abar = v / norm
    g = Lm.T @ abar  # ∂r/∂y
    JT = np.zeros((N_X, n))  # one contiguous row per parameter
    JT[:6] = abar[[0, 1, 1, 2, 2, 2]] * y[[0, 0, 1, 0, 1, 2]]  # ∂r/∂L_ij = ā_i y_j, (i, j) in θ's order
    den = 1 + 2 * k2 * y / Sc
    dy_dw = g / den  # ∂r/∂w
    dr_dS = dy_dw * (-bias / (1 + scale)) + g * k2 * y ** 2 / Sc ** 2 / den
    for m in range(3):
        JT[:6] += dS[m][:, None] * dr_dS[m][None, :]
    JT[6:9] = -dy_dw / (1 + scale)
    rows = _BIAS_B
    if d.session is None or d.step is None:  # one session, no step: the offsets' regressors are zero
        rows = _BIAS_ROWS[(d.session is not None, d.step is not None)]
    wanted = None
    if free is not None:
        wanted = np.zeros(N_X, dtype=bool)
        wanted[free] = True
        rows = rows[wanted[9 + rows]]
    JT[9 + rows] = (-dy_dw * Sc / (1 + scale))[_BETA_AXIS[rows]] * R[rows]
    rows = _SCALE_B if wanted is None else _SCALE_B[wanted[9 + _SCALE_B]]
    JT[9 + rows] = (-dy_dw * w / (1 + scale))[_BETA_AXIS[rows]] * R[rows]
    JT[9 + _NONLINEAR_B] = -g * y ** 2 / Sc / den
    return r, (JT if free is None else JT[free]).T


@dataclass
class PoseData:
    """The data of an extended fit in normalised units (built once per data set).

    Attributes
    ----------
    u : ndarray, shape (n, 3)
        Normalised measurements ``(a − centre)/scale`` (:class:`optcal.families.accel.base.Normaliser`).
    tau, s : ndarray, shape (n,)
        Normalised temperature and time.
    session : ndarray of int, shape (n,), optional
        Session of each pose (``None``: one session).
    step : ndarray, shape (n,) or (n, m), optional
        1 for the poses after each bias step, 0 before (``None``: no step).
    """

    u: NDArray[np.float64]
    tau: NDArray[np.float64]
    s: NDArray[np.float64]
    session: NDArray[np.intp] | None = None
    step: NDArray[np.float64] | None = None

    @classmethod
    def of(cls, u: NDArray[np.float64], reg: Regressors, step: NDArray[np.float64] | None = None) -> "PoseData":
        """Normalised measurements ``u`` with the temperature, time and session of ``reg`` (and a bias step's indicator)."""
        return cls(u, reg.tau, reg.s, reg.session if reg.n_sessions > 1 else None, step)

    @property
    def n(self) -> int:
        return int(self.u.shape[0])

    def regressor_rows(self) -> NDArray[np.float64]:
        """:func:`regressor_rows` of these poses, shape (N_BETA, n) (built on first use, then kept)."""
        rows: NDArray[np.float64] | None = self.__dict__.get("_regressor_rows")
        if rows is None:
            rows = self.__dict__["_regressor_rows"] = regressor_rows(self.tau, self.s, self.session, self.step)
        return rows

    def parameters(self, w: NDArray, delta: float = 1.0) -> "ProblemData":
        """The data of one solve of :class:`ExtendedProblem`: these poses with weights ``w``."""
        return ProblemData(self, np.sqrt(w), float(delta))


@dataclass(frozen=True)
class ProblemData:
    """Poses, their square-root weights and the robust loss's scale: everything one solve needs."""

    poses: PoseData
    sqrt_w: NDArray[np.float64]
    delta: float = 1.0


class ExtendedProblem:
    """``min_x Σ_k ρ(√w_k r_k(x))`` over θ and the active coefficients (module docstring).

    Holds no data (each call gets its :class:`ProblemData`), so one instance per loss serves
    every data set and thread.

    Parameters
    ----------
    loss : {"squared", "cauchy"}
    """

    def __init__(self, loss: str = "squared") -> None:
        if loss not in ("squared", "cauchy"):
            raise ValueError(f"unknown loss {loss!r}")
        self.loss = loss

    @classmethod
    def get(cls, n: int = 0, loss: str = "squared") -> "ExtendedProblem":
        """The problem of ``loss`` (``n`` is accepted for symmetry with the estimators; nothing depends on it)."""
        return cls(loss)

    @staticmethod
    def residuals_and_jacobian(x: NDArray, data: ProblemData, free: NDArray[np.intp]) -> tuple[NDArray, NDArray]:
        """Unweighted residuals (n,) and their Jacobian (n, len(free)) w.r.t. ``x[free]``."""
        return residuals_and_jacobian(np.asarray(x, float), data.poses, free)

    def solve(self, x0: NDArray, data: ProblemData, active: NDArray[np.bool_]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``x0`` with the coefficients ``active`` free (the others fixed at zero)."""
        from scipy.optimize import least_squares

        free = np.concatenate([np.arange(9), 9 + np.flatnonzero(active)])
        x = np.zeros(N_X)
        x[free] = np.asarray(x0, float)[free]
        sqrt_w = data.sqrt_w
        d = data.poses
        used = free[9:] - 9
        rows = d.regressor_rows()

        def residuals(z: NDArray) -> NDArray:
            x[free] = z
            return sqrt_w * extended_residuals(x, d.u, d.tau, d.s, used, d.session, d.step, rows)

        def jacobian(z: NDArray) -> NDArray:
            x[free] = z
            return sqrt_w[:, None] * residuals_and_jacobian(x, d, free)[1]

        robust = self.loss == "cauchy"
        result = least_squares(
            residuals, x[free].copy(), jac=jacobian,
            method="trf" if robust else "lm", loss="cauchy" if robust else "linear", f_scale=data.delta,
            x_scale="jac", ftol=TOLERANCE, xtol=TOLERANCE, gtol=TOLERANCE, max_nfev=MAX_EVALUATIONS,
        )
        x[free] = result.x
        return x.copy(), {"success": bool(result.success), "evaluations": int(result.nfev), "message": result.message}

    def residual_values(self, x: NDArray, data: ProblemData) -> NDArray[np.float64]:
        """Unweighted residuals of every pose at ``x``."""
        d = data.poses
        return np.asarray(extended_residuals(np.asarray(x, float), d.u, d.tau, d.s, np.flatnonzero(x[9:]), d.session,
                                             d.step, d.regressor_rows()))

    def jacobian_values(self, x: NDArray, data: ProblemData) -> NDArray[np.float64]:
        """Unweighted Jacobian of every pose's residual w.r.t. every entry of ``x``, shape (n, N_X)."""
        return residuals_and_jacobian(np.asarray(x, float), data.poses)[1]


def active_mask(terms: Mapping[tuple[str, int], int]) -> NDArray[np.bool_]:
    """β mask of the coefficients of ``{(effect, axis): order}`` (orders 1..order)."""
    mask = np.zeros(N_BETA, dtype=bool)
    for (effect, axis), order in terms.items():
        for p in range(1, order + 1):
            mask[BETA_INDEX[(effect, axis, p)]] = True
    return mask


def to_model(x: NDArray, centre: NDArray, scale: float, reg: Regressors) -> ExtendedModel:
    """The physical :class:`ExtendedModel` of a solution ``x`` in normalised units.

    Its bias ``o`` is the first session's; the session offsets are not a term of the model
    (:func:`session_offsets_g` gives them).
    """
    from optcal.core.model import canonicalise, unpack_theta

    T_n, o_n = unpack_theta(x[:9])
    T = canonicalise(T_n / scale)
    o = centre + scale * o_n
    coefficients = {}
    for effect in PARAMETRIC:
        c = np.zeros((3, MAX_ORDER[effect]))
        h = reg.half_span(effect)
        for i in range(3):
            for p in range(1, MAX_ORDER[effect] + 1):
                value = x[9 + BETA_INDEX[(effect, i, p)]]
                c[i, p - 1] = value / h**p if value != 0 else 0.0
        coefficients[effect] = c
    temp_ref = reg.temp_ref if np.isfinite(reg.temp_ref) else 25.0
    t_ref = reg.t_ref if np.isfinite(reg.t_ref) else 0.0
    return ExtendedModel(LumpedModel.from_T(T, o), coefficients, temp_ref, t_ref)


def session_offsets_g(x: NDArray, n_sessions: int) -> NDArray[np.float64]:
    """Bias of every session relative to the first, shape (3, n_sessions), g (bias terms are per g)."""
    out = np.zeros((3, n_sessions))
    for i in range(3):
        for k in range(1, n_sessions):
            out[i, k] = x[9 + BETA_INDEX[(SESSION_BIAS, i, k)]]
    return out


def session_shift(x: NDArray, C: NDArray, session: NDArray[np.intp], n_sessions: int) -> NDArray[np.float64]:
    """Raw bias of each pose's session relative to the first session's, shape (n, 3) (zeros for one session).

    Bias terms are per g, so the raw offset of axis i is ``S_i δ_i`` with ``S_i`` the row norm of
    ``C`` (:mod:`optcal.core.extended_model`).
    """
    if n_sessions < 2:
        return np.zeros((len(session), 3))
    return (session_offsets_g(x, n_sessions) * np.linalg.norm(C, axis=1)[:, None])[:, session].T


def step_shift(x: NDArray, C: NDArray, step: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """Raw bias of each pose relative to the bias before the first step, shape (n, 3) (zeros without a step).

    Each step is a bias term per g, as the session offsets (:func:`session_shift`): axis i's raw offset is
    ``S_i δ_ik`` after step k, the steps' offsets adding up.
    """
    if step is None:
        return np.zeros((0, 3))
    S = np.linalg.norm(C, axis=1)
    shift = np.zeros((step.shape[0], 3))
    for k, column in enumerate(step_indicator(step, step.shape[0]), start=1):
        delta = np.array([x[9 + BETA_INDEX[(BIAS_STEP, i, k)]] for i in range(3)])
        shift += column[:, None] * (delta * S)[None, :]
    return shift
