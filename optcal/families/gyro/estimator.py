"""Gyroscope calibration by IPOPT nonlinear least squares in CasADi (Tedaldi, Pretto, Menegatti, ICRA 2014).

1. **Bias** from the still intervals (Tedaldi 2014, section IV-B: the mean rate at rest):
   the sample-weighted mean of the interval means, or, with the g-sensitivity, the linear
   regression ``ḡ_i = b_g + G_g f_i`` of the interval means on the calibrated specific force.
2. **Scale and misalignment**: ``T_g = s₀ (I + X)`` (nine free numbers in ``X``, ``s₀`` the
   nominal scale) minimises ``½ Σ_i ‖Φ_i(T_g)ᵀ u_i − u_{i+1}‖²`` over the moves (eq. 13),
   ``Φ_i`` the rotation integrated from the corrected gyro across move ``i`` (eq. 14, by
   the exponential map of :mod:`optcal.families.gyro.propagation`) and ``u_i`` the gravity direction
   of the calibrated accelerometer at pose ``i``.  The integrator and its analytic
   sensitivities ``∂u/∂T_g`` are vectorised numpy (:class:`GravityPredictor`); IPOPT, through
   a CasADi NLP built once per problem size (:data:`GYRO_PROBLEMS`), solves the problem with
   the Gauss–Newton Hessian ``JᵀJ`` (``hess_lag``), as imu_tk solves it by
   Levenberg–Marquardt in Ceres.
3. **Accelerometer**: fixed (its gravity directions as data), or ``joint``: its nine
   parameters re-estimated with the gyro's, the norm residuals of the poses (Lu 2017,
   eq. 13) and the gravity-prediction residuals each scaled to unit variance.
4. **Covariance** ``σ̂² (JᵀJ)⁻¹`` with ``σ̂²`` from the residuals (two effective degrees of
   freedom per move: the component along the gravity direction is second order); the
   identifiability from the excited rotation axes and the rank of ``JᵀJ``
   (:mod:`optcal.families.gyro.identifiability`).
5. **Fit check** (:mod:`optcal.families.gyro.consistency`): the residual against the noise
   model of the moves (angle random walk, bias between the rests, pose noise, time base,
   integration), a gyro that sees the moves, axes and scale that are a sensor's, not a
   column mapping, unit or time base; a calibration that cannot be right is refused
   (:class:`~optcal.errors.InputError`) unless ``accept_gyro_fit``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import IdentifiabilityError, InputError
from optcal.families.gyro.consistency import (GyroFitCheck, check_gyro_fit, refusal_line, residual_test,
                                              signal_to_noise, unseen_moves_finding)
from optcal.families.gyro.identifiability import excitation, fisher_rank, gyro_identifiability
from optcal.core.gyro_model import BIAS_NAMES, G_NAMES, T_NAMES, GyroModel
from optcal.families.gyro.moves import MoveSet
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows
from optcal.families.gyro.result import ImuCalibration
from optcal.data.units import GyroUnitsDecision
from optcal.core.norm_residual import norm_residuals
from optcal.core.model import TRIL_INDEX, theta_from
from optcal.solvers.cache import ProblemCache, problem_cache
from optcal.solvers.convergence import plugin_iterations, solver_record
from optcal.solvers.registry import SolverChoice, choose_nlp_solver
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, CallbackNLP, NumpyObjective, cost_scale
from optcal.core.fit_result import chi_square
from optcal.core.identifiability import RankReport
from optcal.families.accel.result import CalibrationResult
from optcal.core.stats import rms

if TYPE_CHECKING:
    from optcal.data import LoadedData

ACCELEROMETER_MODES: tuple[str, ...] = ("fixed", "joint")
#: IPOPT's tolerance on the gyro problem's scaled cost: the accelerometer's ML problem asks for
#: 1e-10 so that a fleet batch reproduces a single fit, but here every iterate integrates every
#: move, and 1e-7 already puts the gyro parameters within ~1e-7·√n standard errors of the optimum.
GYRO_IPOPT_TOL: float = 1e-7
#: What a residual above the noise model's bound suggests when the g-sensitivity is not modelled: the rate it adds
#: changes with the specific force along a move, which the rests' bias offsets do not follow.
G_SENSITIVITY_HINT: str = "the gyro's g-sensitivity is not modelled (g_sensitivity=True models it)"
#: The solver as the gyroscope's record names it.
GYRO_SOLVER_NAME: str = "ipopt (CasADi, Gauss-Newton Hessian)"


def gyro_solver_name(settings: "GyroSettings") -> str:
    """The solver record's name: :data:`GYRO_SOLVER_NAME` for IPOPT, the catalogue's name of another."""
    name = settings.choice().name
    return GYRO_SOLVER_NAME if name == "ipopt" else f"{name} (CasADi, Gauss-Newton Hessian)"

@dataclass(frozen=True)
class GyroSettings:
    """Settings of :func:`calibrate_gyro`.

    Attributes
    ----------
    accelerometer : {"fixed", "joint"}
        Keep the accelerometer calibration, or re-estimate it jointly with the gyro.
    g_sensitivity : bool
        Model the gyro's g-sensitivity ``G_g`` (9 more parameters, from the still intervals).
    allow_degenerate : bool
        Proceed (with a note) when the moves do not excite three rotation axes.
    accept_gyro_fit : bool
        Keep a calibration the moves do not support (:mod:`optcal.families.gyro.consistency`:
        a residual far beyond the noise model, a gyro that does not see the moves, axes or a
        scale that are a column mapping, unit or time base), with a warning, instead of
        refusing it.
    ipopt_options : dict
        Extra CasADi/IPOPT options of the gyro problem (:class:`GyroProblem`); options IPOPT
        refuses are an :class:`~optcal.errors.InputError`.
    solver : str, optional
        The NLP solver by name (:data:`optcal.solvers.registry.NLP_SOLVERS`; IPOPT by default),
        ``ipopt_options`` then being that solver's options.
    """

    accelerometer: str = "fixed"
    g_sensitivity: bool = False
    allow_degenerate: bool = False
    accept_gyro_fit: bool = False
    ipopt_options: dict[str, Any] = field(default_factory=dict)
    solver: str | None = None

    @classmethod
    def from_flags(
        cls, *, joint: bool = False, g_sensitivity: bool = False, allow_degenerate: bool = False,
        accept_gyro_fit: bool = False, solver: str | None = None, solver_options: dict[str, Any] | None = None,
    ) -> GyroSettings:
        """The settings ``optcal calibrate --imu``'s flags and :func:`optcal.calibrate_imu`'s keywords name.

        Parameters
        ----------
        joint : bool
            Re-estimate the accelerometer jointly with the gyro (``accelerometer="joint"``).
        g_sensitivity, allow_degenerate, accept_gyro_fit : bool
            As the attributes of the same names.
        solver, solver_options : optional
            The NLP solver by CasADi's name and its options (``ipopt_options``).

        Returns
        -------
        GyroSettings
        """
        return cls(accelerometer="joint" if joint else "fixed", g_sensitivity=g_sensitivity,
                   allow_degenerate=allow_degenerate, accept_gyro_fit=accept_gyro_fit,
                   solver=solver, ipopt_options=dict(solver_options or {}))

    def choice(self) -> SolverChoice:
        """The solver and its options, resolved (an unavailable one is an :class:`InputError`)."""
        return choose_nlp_solver(self.solver, self.ipopt_options)

    def __post_init__(self) -> None:
        if self.accelerometer not in ACCELEROMETER_MODES:
            raise InputError(f"accelerometer must be one of {', '.join(ACCELEROMETER_MODES)}, got {self.accelerometer!r}")


@dataclass(frozen=True)
class StaticGyro:
    """Bias (and g-sensitivity) from the still intervals, with covariance."""

    bias: NDArray[np.float64]
    g_sensitivity: NDArray[np.float64] | None
    covariance: NDArray[np.float64]  # of (bias, row-major G)


def static_gyro(moves: MoveSet, f_static: NDArray, g_sensitivity: bool) -> StaticGyro:
    """Tedaldi 2014 section IV-B: the gyro at rest reads its bias (plus ``G_g f`` if modelled).

    Weighted least squares over the interval means (weights: sample counts); the
    covariance from the within-interval noise (white, ``σ²/n`` per mean).
    """
    n = moves.n_static
    var_mean = moves.gyro_static_std**2 / n[:, None]  # (p, 3)
    if not g_sensitivity:
        w = n / n.sum()
        bias = w @ moves.gyro_means
        cov = np.diag(np.sum(w[:, None] ** 2 * var_mean, axis=0))
        return StaticGyro(bias, None, cov)
    X = np.column_stack([np.ones(len(n)), f_static])
    if np.linalg.matrix_rank(X) < 4:
        raise InputError("the g-sensitivity needs still poses with gravity along at least three non-coplanar directions")
    sw = np.sqrt(n)
    coef, *_ = np.linalg.lstsq(X * sw[:, None], moves.gyro_means * sw[:, None], rcond=None)  # (4, 3)
    XtWX_inv = np.linalg.inv((X * n[:, None]).T @ X)
    s2 = np.mean(var_mean * n[:, None], axis=0)  # per-axis sample variance
    cov = np.zeros((12, 12))
    for axis in range(3):  # bias_axis = coef[0, axis], G[axis, :] = coef[1:, axis]
        idx = [axis] + [3 + 3 * axis + j for j in range(3)]
        cov[np.ix_(idx, idx)] = s2[axis] * XtWX_inv
    return StaticGyro(coef[0], coef[1:].T.copy(), cov)


@lru_cache(maxsize=1)
def accelerometer_directions() -> Any:
    """CasADi ``(y, a, T_a0, o₀, r₀) → (u, ‖v‖ − 1, ∂u/∂y, ∂(‖v‖ − 1)/∂y)`` for one pose.

    ``v = T_a (a − o)`` with ``T_a = T_a0 (I + lower(y₀..y₅))`` and ``o = o₀ + r₀ (y₆, y₇, y₈)``
    (Lu 2017, eq. 6 and 13), ``u = v / ‖v‖`` the gravity direction.
    """
    import casadi as ca

    from optcal.core.norm_residual import casadi_lower_triangular as lower_triangular

    y, a, o0 = ca.SX.sym("y", 9), ca.SX.sym("a", 3), ca.SX.sym("o0", 3)
    Ta0, r0 = ca.SX.sym("Ta0", 3, 3), ca.SX.sym("r0")
    v = Ta0 @ (ca.SX.eye(3) + lower_triangular(y[:6])) @ (a - o0 - r0 * y[6:9])
    norm = ca.norm_2(v)
    u = v / norm
    return ca.Function("accelerometer_directions", [y, a, Ta0, o0, r0],
                       [u, norm - 1, ca.jacobian(u, y), ca.jacobian(norm, y)])


class GyroProblem:
    """The NLP ``min_x ½‖r(x)‖²`` of one recording layout, solved by IPOPT with ``hess_lag = JᵀJ``.

    ``x = vec(X)`` (9, row-major) with ``T_g = s₀ (I + X)`` for a fixed accelerometer; jointly
    ``x = (vec X, y)`` with the accelerometer's ``y`` of :func:`accelerometer_directions`.
    Residuals and Jacobian come from the integrator :class:`GravityPredictor` (numpy, analytic
    sensitivities) through the ``evaluate`` given to :meth:`solve` and are handed to IPOPT as
    the callbacks of a :class:`optcal.solvers.nlp.CallbackNLP` (cost, gradient ``Jᵀr``,
    Gauss–Newton Hessian), evaluated once per iterate, with the cost scaling of
    :func:`optcal.solvers.nlp.cost_scale` and its IPOPT tuning
    (:data:`optcal.solvers.nlp.SCALED_COST_IPOPT_OPTIONS`) but its own tolerance
    (:data:`GYRO_IPOPT_TOL`).  The problem depends on ``nx`` and the options only, so it is built
    once and kept in :data:`GYRO_PROBLEMS`; each solve holds its lock.
    """

    def __init__(self, nx: int, solver: SolverChoice) -> None:
        self.nx = nx
        self.nlp = CallbackNLP("gyro_calibration", nx, hessian_block_size=nx,
                               tuning={**SCALED_COST_IPOPT_OPTIONS, "ipopt.tol": GYRO_IPOPT_TOL},
                               solver=solver)

    def solve(self, evaluate: Any, x0: NDArray) -> "GyroSolution":
        """Solve from ``x0`` with ``evaluate(x) -> (r, J)``.

        The cost is scaled by :func:`optcal.solvers.nlp.cost_scale` (one tolerance for any
        number of moves, noise level or units, as in the accelerometer's ML problem).  The
        residuals at the start and at the solution are returned with it (each integration
        of the recording is done once).
        """
        x0 = np.asarray(x0, float)
        objective, start, last = least_squares_objective(evaluate, x0)
        t0 = time.perf_counter()
        x, stats = self.nlp.solve(objective, x0=x0)
        final = (last[0][1], last[0][2]) if last[0][0] == x.tobytes() else evaluate(x)
        return GyroSolution(x, stats, time.perf_counter() - t0, start[0], final[0], final[1])


def least_squares_objective(evaluate: Any, x0: NDArray) -> tuple[NumpyObjective, tuple[NDArray, NDArray], list[Any]]:
    """``½ c ‖r(x)‖²`` with its gradient ``c Jᵀr`` and Gauss–Newton Hessian ``c JᵀJ`` from ``evaluate(x) -> (r, J)``.

    ``c`` is :func:`optcal.solvers.nlp.cost_scale` at ``x0``; the integration at the last x is
    kept (``last[0]``: x's bytes, r, J), so cost, gradient and Hessian at one iterate integrate once.
    Returns the objective, ``evaluate(x0)`` and that memory.
    """
    start = evaluate(x0)
    scale = cost_scale(start[0].size, rms(start[0]))
    last: list[tuple[bytes, NDArray, NDArray]] = [(x0.tobytes(), *start)]  # the integration at the last x

    def residuals(x: NDArray) -> tuple[NDArray, NDArray]:
        key = np.asarray(x, float).tobytes()
        if last[0][0] != key:
            last[0] = (key, *evaluate(np.array(x, dtype=float).ravel()))
        return last[0][1], last[0][2]

    def gradient(x: NDArray) -> tuple[float, NDArray]:
        r, J = residuals(x)
        return 0.5 * scale * float(r @ r), scale * (J.T @ r)

    def hessian(x: NDArray, lam_f: float) -> NDArray:
        _, J = residuals(x)
        return J.T @ J * (scale * lam_f)

    objective = NumpyObjective(lambda x: 0.5 * scale * float(np.sum(residuals(x)[0] ** 2)), gradient, hessian)
    return objective, start, last


#: Built gyro NLPs keyed by ``(nx, frozen IPOPT options)``: 9 (accelerometer fixed) and 18 (joint).
GYRO_PROBLEMS: ProblemCache[GyroProblem] = problem_cache(lambda nx, choice: GyroProblem(nx, choice), maxsize=8)


@dataclass(frozen=True)
class GyroSolution:
    """IPOPT's solution of a :class:`GyroProblem`: ``x``, stats, seconds, residuals at the start and at ``x``, Jacobian at ``x``."""

    x: NDArray[np.float64]
    stats: dict[str, Any]
    seconds: float
    r_start: NDArray[np.float64]
    r: NDArray[np.float64]
    J: NDArray[np.float64]


def initial_scale(moves: MoveSet, w: NDArray, u: NDArray) -> float:
    """Overall rad/s per raw unit that best matches the turn angles of the moves.

    Each move turns gravity by ``α_i = ∠(u_i, u_{i+1})`` and the bias-free raw rate by
    ``β_i = ‖Σ_k w_k dt_k‖``; for a turn about one axis perpendicular to gravity
    ``α_i = s β_i``; a turn partly about gravity makes ``α`` smaller, never larger, so the
    90th percentile of the ratio over moves turned by 20°-160° is the start the fit refines.
    """
    ends = np.concatenate([[0], moves.last_step + 1])
    beta = np.array([np.linalg.norm((w[a:b] * moves.dt[a:b, None]).sum(axis=0)) for a, b in zip(ends[:-1], ends[1:])])
    alpha = np.radians(angles_deg(u[moves.move_from], u[moves.move_to]))
    keep = (alpha > np.radians(20)) & (alpha < np.radians(160)) & (beta > 0)
    if not np.any(keep):
        keep = beta > 0
    if not np.any(keep):
        raise InputError("the gyro reads the same in every move: the sensor was not rotated between the poses")
    return float(np.percentile((alpha / np.where(beta > 0, beta, np.inf))[keep], 90))


def calibrate_gyro(
    moves: MoveSet,
    accelerometer: CalibrationResult,
    units: GyroUnitsDecision,
    settings: GyroSettings | None = None,
) -> ImuCalibration:
    """Calibrate the gyro from the moves of a recording, given its accelerometer calibration.

    Parameters
    ----------
    moves : MoveSet
        From :func:`optcal.families.gyro.moves.moves_from_segmentation` (or ``moves_from_arrays``).
    accelerometer : CalibrationResult
        The accelerometer calibration of the same recording (raw units → g).
    units : GyroUnitsDecision
        Units of the raw gyro samples.
    settings : GyroSettings, optional

    Returns
    -------
    ImuCalibration

    Raises
    ------
    IdentifiabilityError
        The moves excite fewer than three rotation axes (unless ``allow_degenerate``).
    InputError
        The calibration cannot be right (:mod:`optcal.families.gyro.consistency`), unless
        ``accept_gyro_fit``: then kept, its ``fit_check`` carrying the findings and the warning.
    """
    settings = settings or GyroSettings()
    notes: list[str] = []
    degenerate = False  # moves that leave part of T_g undetermined, allowed through
    f_static = accelerometer.correct(moves.acc_means)
    u = unit_rows(f_static)
    f_mid = accelerometer.correct(moves.acc_mid)
    static = static_gyro(moves, f_static, settings.g_sensitivity)
    w = moves.gyro_mid() - static.bias
    if static.g_sensitivity is not None:
        w = w - f_mid @ static.g_sensitivity.T
    exc = excitation(w, moves.dt)
    if not exc.sufficient:
        msg = exc.describe()
        if not settings.allow_degenerate:
            report = gyro_identifiability(RankReport(0, 9, float("inf")), exc, [])
            raise IdentifiabilityError(msg + ". Record moves that also turn the sensor about that axis "
                                       "(or pass allow_degenerate=True: the combination is then arbitrary)", report)
        notes.append("DEGENERATE MOVES: " + msg)
        degenerate = True
    if not settings.accept_gyro_fit:
        # Test 2 of the fit check reads the bias-free raw rates and the rests' noise, not the fit, and a gyro that
        # does not see the moves is refused whatever T_g the fit finds; so it is refused before the NLP. On noise
        # the NLP wanders a flat objective (T_g grows to hundreds of times its nominal, each direction's residual
        # then a random rotation): 180 IPOPT iterations, about 5 CPU s, on the Xsens log's gyro replaced by noise.
        S, level = signal_to_noise(moves, w)
        unseen = unseen_moves_finding(moves, S, level)
        if unseen is not None:
            raise InputError(refusal_line([f"{unseen}; refused before the fit, whose axes and scale are then not "
                                           "tested"]))
    nominal = units.rad_per_unit
    s_fit = initial_scale(moves, w, u)
    scale0 = nominal if nominal is not None else s_fit
    before = (f"bias removed, nominal {units.units} scale" if nominal is not None
              else f"bias removed, one scale {s_fit:.6g} rad/s per count from the turn angles")
    predictor = GravityPredictor(moves.first_step, moves.last_step)
    u0, u1 = u[moves.move_from], u[moves.move_to]
    m = moves.n_moves

    def fixed_residuals(x: NDArray) -> tuple[NDArray, NDArray]:
        v, S, _ = predictor.evaluate(scale0 * (np.eye(3) + x.reshape(3, 3)), w, moves.dt, u0)
        return (v - u1).ravel(), scale0 * S.reshape(3 * m, 9)

    sol = GYRO_PROBLEMS.get(9, settings.choice()).solve(fixed_residuals, np.zeros(9))
    x, stats, seconds, r, J = sol.x, sol.stats, sol.seconds, sol.r, sol.J
    angles_before = angles_deg(sol.r_start.reshape(m, 3) + u1, u1)  # x = 0: T_g = s₀ I
    iterations = plugin_iterations(stats)
    dof = 2 * m - 9
    sigma_g = float(np.sqrt(np.sum(r**2) / dof)) if dof > 0 else float("nan")
    acc_result = accelerometer
    predicted = r.reshape(m, 3) + u1
    if settings.accelerometer == "joint":
        acc_result, x, J, stats, extra_s, predicted = _joint(moves, accelerometer, w, scale0, x, sigma_g, predictor, settings)
        seconds += extra_s
        iterations += plugin_iterations(stats)
        u = unit_rows(acc_result.correct(moves.acc_means))
        u1 = u[moves.move_to]
        cov_x = np.linalg.pinv(J.T @ J, rcond=1e-12, hermitian=True)[:9, :9]
    else:
        cov_x = sigma_g**2 * np.linalg.pinv(J.T @ J, rcond=1e-12, hermitian=True)
    Tg = scale0 * (np.eye(3) + x[:9].reshape(3, 3))
    ident = fisher_rank(J[: 3 * m, :9], list(T_NAMES), exc)
    if not ident.identifiable and ident.rank < ident.n_params:
        msg = ident.describe()
        if not settings.allow_degenerate:
            raise IdentifiabilityError(msg + ". Record moves about more axes", ident)
        notes.append("DEGENERATE MOVES: " + msg)
        degenerate = True
    model = GyroModel(Tg, static.bias, static.g_sensitivity)
    angles_after = angles_deg(predicted, u1)
    check = fit_check(moves, acc_result, model, w, units, angles_after, settings.accept_gyro_fit,
                      determined=not degenerate)
    if check.refused and not settings.accept_gyro_fit:
        raise InputError(check.refusal())
    notes.append(check.note())
    names = list(T_NAMES) + list(BIAS_NAMES) + (list(G_NAMES) if static.g_sensitivity is not None else [])
    params = np.concatenate([Tg.ravel(), static.bias] + ([static.g_sensitivity.ravel()] if static.g_sensitivity is not None else []))
    k = len(names)
    cov = np.zeros((k, k))
    cov[:9, :9] = scale0**2 * cov_x
    cov[9:, 9:] = static.covariance
    notes.append("bias from the still intervals with white-noise standard errors; the Earth rate "
                 "(≤ 7.3e-5 rad/s) is part of the bias")
    bridged = moves.bridging_note()
    if bridged is not None:
        notes.append(bridged)
    return ImuCalibration(
        accelerometer=acc_result,
        gyro=model,
        gyro_units=units.units,
        gyro_units_reason=units.reason,
        param_names=names,
        params=params,
        covariance=cov,
        angles_before_deg=angles_before,
        angles_after_deg=angles_after,
        before=before,
        accelerometer_mode=settings.accelerometer,
        solver=solver_record(stats, seconds, gyro_solver_name(settings), iterations=iterations),
        identifiability=ident,
        exclusions=dict(moves.exclusions),
        notes=notes,
        units=accelerometer.units,
        fitted_on=accelerometer.calibration.fitted_on,
        fit_check=check.to_dict(),
    )


def fit_check(
    moves: MoveSet, accelerometer: CalibrationResult, model: GyroModel, w: NDArray, units: GyroUnitsDecision,
    angles_after_deg: NDArray, accepted: bool, fitted: int = 9, determined: bool = True,
) -> GyroFitCheck:
    """The tests of :mod:`optcal.families.gyro.consistency` on a fitted gyro (``fitted`` parameters of the residual).

    Parameters
    ----------
    moves : MoveSet
    accelerometer : CalibrationResult
        Gives the gravity directions (the joint one when re-estimated).
    model : GyroModel
        The fitted gyro.
    w : ndarray, shape (N, 3)
        Bias-free raw rates of the steps (g-sensitivity removed).
    units : GyroUnitsDecision
    angles_after_deg : ndarray, shape (m,)
        The fit's gravity-prediction angles.
    accepted : bool
        The caller keeps the calibration whatever the findings.
    fitted : int
        Parameters fitted to the residual (nine; none when a saved calibration is checked).
    determined : bool
        The moves determine ``T_g`` (not a degenerate set allowed through): its axes and scales are tested.
    """
    residual = residual_test(moves, accelerometer, model, angles_after_deg, fitted)
    hint = "" if model.g_sensitivity is not None else G_SENSITIVITY_HINT
    return check_gyro_fit(residual, moves, w, model.T, units.units, units.rad_per_unit, accepted, determined, hint)


def _joint(
    moves: MoveSet, acc: CalibrationResult, w: NDArray, scale0: float, x_gyro: NDArray, sigma_g: float,
    predictor: GravityPredictor, settings: GyroSettings,
) -> tuple[CalibrationResult, NDArray, NDArray, dict[str, Any], float, NDArray]:
    """Re-estimate the accelerometer with the gyro (both residual kinds at unit variance).

    Returns the accelerometer result, ``x``, the Jacobian scaled so that ``(JᵀJ)⁻¹`` is the
    covariance of ``x``, IPOPT's stats, the solve time and the predicted gravity directions.
    """
    P = moves.acc_means.shape[0]
    # per-pose noise of the norm residual, from the accelerometer fit (scaled by its reduced chi-square)
    redchi = acc.redchi if acc.dof > 0 and np.isfinite(acc.redchi) and acc.redchi > 0 else 1.0
    w_acc = acc.weights if acc.weights.size == P else np.ones(P)
    sig_a = np.sqrt(redchi / w_acc)
    r0 = float(np.mean(1.0 / np.abs(np.diag(acc.T))))
    directions = accelerometer_directions().map(P)
    m = moves.n_moves
    frm, to = moves.move_from, moves.move_to

    def joint_residuals(x: NDArray) -> tuple[NDArray, NDArray]:
        u, rn, du, drn = (np.asarray(z) for z in directions(x[9:], moves.acc_means.T, acc.T, acc.o, r0))
        u = u.T  # (P, 3)
        du = du.reshape(3, P, 9).transpose(1, 0, 2)  # (P, 3, 9)
        v, S, Phi = predictor.evaluate(scale0 * (np.eye(3) + x[:9].reshape(3, 3)), w, moves.dt, u[frm])
        Jy = np.einsum("mji,mjk->mik", Phi, du[frm]) - du[to]  # ∂(Φᵀu₀ − u₁)/∂y
        r = np.concatenate([(v - u[to]).ravel() / sigma_g, rn.ravel() / sig_a])
        J = np.block([[scale0 * S.reshape(3 * m, 9) / sigma_g, Jy.reshape(3 * m, 9) / sigma_g],
                      [np.zeros((P, 9)), drn.reshape(P, 9) / sig_a[:, None]]])
        return r, J

    sol = GYRO_PROBLEMS.get(18, settings.choice()).solve(joint_residuals,
                                                                         np.concatenate([x_gyro, np.zeros(9)]))
    x, stats, seconds, r, J = sol.x, sol.stats, sol.seconds, sol.r, sol.J
    dof = 2 * m + P - 18
    chi2 = float(np.sum(r**2))
    L = np.zeros((3, 3))
    for k, (i, j) in enumerate(TRIL_INDEX):
        L[i, j] = x[9 + k]
    Ta = acc.T @ (np.eye(3) + L)
    o = acc.o + r0 * x[15:18]
    factor = chi2 / dof if dof > 0 and chi2 > 0 else 1.0
    cov = np.linalg.pinv(J.T @ J, rcond=1e-12, hermitian=True) * factor
    D = np.zeros((9, 9))  # ∂θ_acc/∂y: T_a entries change by T_a0 E_ij, o by r₀
    for k, (i, j) in enumerate(TRIL_INDEX):
        E = np.zeros((3, 3))
        E[i, j] = 1.0
        dT = acc.T @ E
        D[:6, k] = [dT[p, q] for p, q in TRIL_INDEX]
    D[6:, 6:] = r0 * np.eye(3)
    residuals = norm_residuals(Ta, o, moves.acc_means)
    acc_joint = replace(
        acc, method=f"{acc.method}+gyro-joint", T=Ta, o=o, params=theta_from(Ta, o),
        covariance=D @ cov[9:, 9:] @ D.T, residuals=residuals, chisqr=chi_square(residuals, acc.weights),
        notes=[*acc.notes, "re-estimated jointly with the gyroscope (gravity directions across the moves)"],
    )
    u = unit_rows(acc_joint.correct(moves.acc_means))
    predicted = r[: 3 * m].reshape(m, 3) * sigma_g + u[to]
    return acc_joint, x, J / np.sqrt(factor), stats, seconds, predicted


def calibrate_imu_loaded(
    loaded: LoadedData,
    *,
    gyro_units: str | None = None,
    method: str = "default",
    settings: GyroSettings | None = None,
    acc_settings: dict[str, Any] | None = None,
) -> ImuCalibration:
    """Calibrate accelerometer and gyroscope from one raw recording with gyro channels, as read.

    The estimator reads no file: the caller reads the recording with
    :func:`optcal.data.load_with_segmentation` (columns, units, rate, static-detection settings)
    and hands over what it read.

    Parameters
    ----------
    loaded : optcal.data.LoadedData
        The pose table and the static detection of a raw recording.
    gyro_units : {"counts", "rad/s", "deg/s"}, optional
        Units of the gyro samples (decided from the file and the data when omitted).
    method : str
        Accelerometer estimator (:func:`optcal.calibrate`).
    settings : GyroSettings, optional
    acc_settings : dict, optional
        Settings of the accelerometer estimator (e.g. ``allow_degenerate=True``).

    Raises
    ------
    InputError
        The data were read as a pose table (no moves between the poses).
    """
    from optcal.families.accel.calibration import calibrate
    from optcal.families.gyro.moves import moves_from_segmentation
    from optcal.data.units import decide_gyro_units

    if loaded.segmentation is None:
        raise InputError(f"DATA was read as a pose table ({loaded.kind.reason}); a gyro calibration needs the raw "
                         "recording with the moves between the poses (kind='raw')")
    seg = loaded.segmentation
    moves = moves_from_segmentation(seg)
    acc = calibrate(loaded.poses, method=method, **(acc_settings or {}))
    rec = seg.recording
    if rec.gyro is None:  # impossible: moves_from_segmentation refuses a recording without gyro columns
        raise AssertionError(f"{rec.path}: no gyro columns")
    decision = decide_gyro_units(rec.gyro[rec.gyro_usable], moves.gyro_means.mean(axis=0), gyro_units, rec.gyro_units)
    return calibrate_gyro(moves, acc, decision, settings)
