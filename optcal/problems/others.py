"""The gyroscope's problem, the fleet's problem with a population prior and the pose planner's refinement as formulations."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.fleet.prior import PopulationPrior, PriorMLProblem
from optcal.applications.plan.candidates import Cap
from optcal.applications.plan.information import Criterion
from optcal.applications.plan.rounding import REFINE_IPOPT_TUNING, refine_problem
from optcal.core.model import PARAM_NAMES
from optcal.core.poses import PoseTable
from optcal.data.units import GyroUnitsDecision
from optcal.families.accel.base import Normaliser
from optcal.families.accel.mle import MaximumLikelihood, NormResidualCost
from optcal.families.accel.result import CalibrationResult
from optcal.families.gyro.estimator import GYRO_IPOPT_TOL, initial_scale, least_squares_objective, static_gyro
from optcal.families.gyro.moves import MoveSet
from optcal.families.gyro.propagation import GravityPredictor, unit_rows
from optcal.problems.accel import NORMALISED
from optcal.solvers.formulation import Formulation
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, CallbackNLP, cost_scale


def _symbols(n: int, constraints: Callable[[Any], Any] | None = None) -> dict[str, Any]:
    """The variables (and constraints) of a callback formulation, for its description and suitability."""
    import casadi as ca

    x = ca.MX.sym("x", n)
    out: dict[str, Any] = {"x": x}
    if constraints is not None:
        out["g"] = constraints(x)
    return out


def gyroscope(moves: MoveSet, accelerometer: CalibrationResult, units: GyroUnitsDecision,
              g_sensitivity: bool = False) -> Formulation:
    """The gyroscope's problem with the accelerometer held (Tedaldi 2014, eq. 20-22), evaluated in numpy.

    ``min_x ½ c Σ_j ‖v_j(T_g(x)) − u_j‖²``: gravity at the start of move j rotated by the
    integrated, calibrated rates ``T_g (ω − b)`` (``T_g = s₀ (I + X)``, x = vec X) against gravity
    measured at its end; bias (and g-sensitivity) from the still intervals, as
    :func:`optcal.families.gyro.estimator.calibrate_gyro` does.  Cost, gradient ``Jᵀr`` and the
    Gauss–Newton Hessian ``JᵀJ`` are numpy callbacks.

    Parameters
    ----------
    moves : MoveSet
        The recording's rests and the moves between them, with the gyroscope's samples.
    accelerometer : CalibrationResult
        The accelerometer's calibration, held fixed: it gives the measured gravity directions.
    units : GyroUnitsDecision
        The gyroscope's units (its nominal scale in rad/s per unit, when known).
    g_sensitivity : bool
        Also estimate the gyroscope's g-sensitivity ``G_g`` from the still intervals.

    Returns
    -------
    Formulation
        The NLP with numpy callbacks for cost, gradient and Gauss–Newton Hessian.
    """
    f_static = accelerometer.correct(moves.acc_means)
    u = unit_rows(f_static)
    static = static_gyro(moves, f_static, g_sensitivity)
    w = moves.gyro_mid() - static.bias
    if static.g_sensitivity is not None:
        w = w - accelerometer.correct(moves.acc_mid) @ static.g_sensitivity.T
    nominal = units.rad_per_unit
    scale0 = nominal if nominal is not None else initial_scale(moves, w, u)
    predictor = GravityPredictor(moves.first_step, moves.last_step)
    u0, u1 = u[moves.move_from], u[moves.move_to]
    m = moves.n_moves

    def residuals(x: NDArray) -> tuple[NDArray, NDArray]:
        v, S, _ = predictor.evaluate(scale0 * (np.eye(3) + x.reshape(3, 3)), w, moves.dt, u0)
        return (v - u1).ravel(), scale0 * S.reshape(3 * m, 9)

    x0 = np.zeros(9)
    objective, _, _ = least_squares_objective(residuals, x0)
    tuning = {**SCALED_COST_IPOPT_OPTIONS, "ipopt.tol": GYRO_IPOPT_TOL}
    return Formulation(
        name="gyroscope",
        equation="min_x ½ c Σ_j ‖v_j(s₀(I + X)) − u_j‖² over the moves between still poses (Tedaldi 2014, eq. 20-22)",
        variables=[f"X_{a}{b}" for a in "xyz" for b in "xyz"],
        parameters={"moves": f"{m} moves: rates (bias removed), time steps, gravity at both ends (held in the callbacks)"},
        scaling=f"T_g = s₀ (I + X), s₀ = {scale0:.6g} rad/s per raw unit; cost scaled by c = 1/(n s₀) of the start",
        nlp_dict=_symbols(9),
        values={"x0": x0},
        tuning=tuning,
        callback=lambda choice: CallbackNLP("gyro_calibration", 9, hessian_block_size=9, tuning=tuning, solver=choice),
        objective=objective,
    )


def fleet_prior(poses: PoseTable, prior: PopulationPrior, start: NDArray | None = None) -> Formulation:
    """One unit's ML problem with the population prior (eq. 14 plus −2 log of the prior), first pass.

    ``min_θ' c [Σ_k w_k r_k(θ')² + ‖L(θ' − μ')‖²]`` in normalised coordinates, ``LᵀL = D P⁻¹ D``
    (:class:`optcal.applications.fleet.prior.PriorMLProblem`, padded to its size class with
    zero-weight poses).

    Parameters
    ----------
    poses : PoseTable
        One unit's static poses (raw units).
    prior : PopulationPrior
        The population's mean and precision of θ.
    start : ndarray, optional
        θ in raw units to start from.

    Returns
    -------
    Formulation
        The penalised NLP in normalised coordinates.
    """
    poses.validate(min_poses=3)
    norm = Normaliser.of(poses.acc)
    u = norm.forward(poses.acc)
    D = norm.jacobian()
    mu_n = np.linalg.solve(D, prior.mean - norm.theta_to_raw(np.zeros(9)))
    L = np.linalg.cholesky(D @ prior.precision @ D).T
    theta_n = norm.theta_to_normalised(prior.mean if start is None else np.asarray(start, float))
    w = (MaximumLikelihood().weights(poses, norm, u, theta_n) if poses.sigma is not None
         else np.full(poses.n, prior.noise_g**-2))
    problem = PriorMLProblem.get(poses.n)
    n_p = problem.n
    w_mean = float(np.mean(w))
    w, L = w / w_mean, L / np.sqrt(w_mean)
    u_p = np.vstack([u, np.repeat(u[:1], n_p - poses.n, axis=0)])
    w_p = np.concatenate([w, np.zeros(n_p - poses.n)])
    start_cost = NormResidualCost(u, w).value(theta_n) + float(np.sum((L @ (theta_n - mu_n)) ** 2))
    scale = cost_scale(poses.n, np.sqrt(start_cost / poses.n))
    return Formulation(
        name="ML with population prior",
        equation="min_θ' c [Σ_k w_k (‖T'(u_k − o')‖ − 1)² + ‖L(θ' − μ')‖²] (Lu 2017, eq. 14 plus −2 log prior)",
        variables=[f"{name}'" for name in PARAM_NAMES],
        parameters={"a": f"normalised measurements, padded to {n_p} poses", "w": "weights (mean one; zero on the padding)",
                    "mu": "prior mean μ'", "L": "factor of the prior precision, LᵀL = D P⁻¹ D", "scale": "cost scale c"},
        scaling=NORMALISED + f"; cost scaled by c = {scale:.4g}",
        nlp_dict=dict(problem.nlp),
        values={"x0": theta_n, "p": np.concatenate([u_p.ravel(), w_p, mu_n, L.ravel(order="F"), [scale]])},
        tuning=dict(SCALED_COST_IPOPT_OPTIONS),
    )


def pose_refinement(vectors: Callable[[NDArray], NDArray], directions: NDArray, criterion: Criterion = Criterion.D,
                    base: NDArray | None = None, cap: Cap | None = None) -> Formulation:
    """The pose planner's refinement on the sphere: ``max Φ(M₀ + Σ_k h(d_k) h(d_k)ᵀ)`` s.t. ``‖d_k‖ = 1`` (and the cap).

    ``vectors(d)`` gives the information vectors ``h`` of directions (K, 3) (the plan's
    ``information_vectors``); Φ the criterion (D: log det, A: −tr M⁻¹, E: λ_min), scaled by its
    value at the start; objective and gradient in numpy, constraints in CasADi.

    Parameters
    ----------
    vectors : callable
        ``vectors(d)``: the information vectors ``h`` of directions of shape (K, 3).
    directions : ndarray, shape (K, 3)
        The start: the rounded plan's gravity directions.
    criterion : Criterion
        D (log det), A (−tr M⁻¹) or E (λ_min).
    base : ndarray, optional
        The information ``M₀`` of poses already taken.
    cap : Cap, optional
        Orientations restricted to a cap about an axis.

    Returns
    -------
    Formulation
        The NLP over the K unit directions.
    """
    directions = np.asarray(directions, dtype=float)
    problem = refine_problem(vectors, directions, criterion, base, cap)
    K = len(directions)
    return Formulation(
        name="pose refinement",
        equation=f"max Φ_{criterion.name}(M₀ + Σ_k h(d_k) h(d_k)ᵀ) s.t. ‖d_k‖² = 1"
                 + (" and d_k · axis ≥ cos(half-angle)" if cap is not None else ""),
        variables=[f"d_k (3 per pose, {K} poses)"],
        parameters={"information": "information vectors h(d) of the prior calibration and the base information M₀ "
                                   "(held in the callbacks)"},
        scaling=f"criterion divided by max(|Φ(start)|, 1) = {max(abs(problem.start_value), 1.0):.4g}",
        nlp_dict=_symbols(problem.n, problem.constraints),
        values={"x0": directions.ravel(), "lbg": problem.lbg, "ubg": problem.ubg},
        constraints=[f"‖d_k‖² = 1 ({K})"] + ([f"d_k · axis ≥ {cap.cos_half_angle:.6g} ({K})"] if cap is not None else []),
        tuning=dict(REFINE_IPOPT_TUNING),
        callback=lambda choice: CallbackNLP("plan_refine", problem.n, constraints=problem.constraints,
                                            tuning=REFINE_IPOPT_TUNING, solver=choice),
        objective=problem.objective,
    )


__all__ = ["fleet_prior", "gyroscope", "pose_refinement"]
