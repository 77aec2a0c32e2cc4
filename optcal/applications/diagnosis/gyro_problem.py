"""The gyroscope's extended model across the moves and at the rests: residuals, Jacobian, fits.

The paper's model (Tedaldi 2014, eq. 9) corrects a raw rate ``g`` to ``ω = T_g (g − b_g)`` (rad/s, in the
calibrated accelerometer's frame).  The extension adds, per gyro axis ``i``, the effects a real MEMS gyro shows::

    ω_lin,i = [T_g (g − b_g)]_i − k_i · f − d_i (t − t̄) − c_i (θ − θ̄)        (g-sensitivity, drift, temperature)
    ω_i     = ω_lin,i + s_i ω_lin,i²                                         (rate-dependent scale)

with ``f`` the calibrated specific force in g, ``t`` the time and ``θ`` the temperature (``t̄``, ``θ̄`` their means
over the rests).  Two kinds of residual carry the evidence (each over its own noise, measured):

* each move's gravity prediction ``Φᵀ u₀ − u₁`` (Tedaldi 2014, eq. 13-14: the corrected rates integrated across the
  move by the exponential map, :mod:`optcal.families.gyro.propagation`), over the noise model of
  :func:`optcal.families.gyro.consistency.residual_budget` (angle random walk, the rests' bias offsets, the poses'
  direction noise, the time base, the integration);
* each rest's mean rate ``ω_p`` (zero at rest, Earth's rate aside), over the noise of a mean of its samples
  (the angle random walk density over its duration).

The Jacobian is analytic: a move's prediction moves with each step's rotation ``θ_k = ω_k dt_k`` by
``∂(Φᵀu₀)/∂θ_k = Φᵀ [u₀]× P_{k−1} J_r(−θ_k)`` (:mod:`optcal.families.gyro.propagation`), and ``ω_k`` is linear in
every parameter but ``s`` (chain rule through ``1 + 2 s ω_lin``).  The fits: Gauss–Newton in numpy for the
selection's many candidate models (each from the current fit, a few iterations), and the chosen model refitted by
IPOPT in CasADi (:class:`optcal.families.gyro.estimator.GyroProblem`, the paper's fit's own NLP, with ``nx`` the
extended model's size).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import AXES, STANDARD_GRAVITY
from optcal.families.gyro.consistency import ResidualBudget, residual_budget, rest_offsets
from optcal.families.gyro.moves import MoveSet
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows

#: The gyroscope's candidate effects, in the order they are tried.
GYRO_EFFECTS: tuple[str, ...] = ("g_sensitivity", "gyro_scale_nonlinearity", "gyro_temperature_bias",
                                 "gyro_bias_drift", "time_offset")
#: Gauss–Newton iterations of a candidate's fit from the current model (each an integration of every move): the
#: extension is a small change, and two iterations bring the cost within a few per cent of its optimum's reduction.
SCREEN_ITERATIONS: int = 3


@dataclass(frozen=True)
class Term:
    """One candidate term of the extension: an effect on one gyro axis (``axis`` None for the time offset)."""

    effect: str
    axis: int | None

    @property
    def size(self) -> int:
        """Its parameters: the g-sensitivity's row (three), one otherwise."""
        return 3 if self.effect == "g_sensitivity" else 1

    @property
    def label(self) -> str:
        return self.effect if self.axis is None else f"{self.effect}({AXES[self.axis]})"


@dataclass
class GyroData:
    """What the gyro's diagnosis fits: the moves' steps and the rests, with the accelerometer's directions.

    Built by :func:`gyro_data` from a :class:`MoveSet` and the accelerometer calibration (fixed: its gravity
    directions are data).
    """

    moves: MoveSet
    raw: NDArray[np.float64]  # (N, 3) raw rate of each step (trapezoid)
    dt: NDArray[np.float64]
    f_mid: NDArray[np.float64]  # (N, 3) calibrated specific force at each step, g
    t_mid: NDArray[np.float64]
    temp_mid: NDArray[np.float64] | None
    rest_raw: NDArray[np.float64]  # (p, 3)
    rest_f: NDArray[np.float64]
    rest_t: NDArray[np.float64]
    rest_temp: NDArray[np.float64] | None
    rest_duration: NDArray[np.float64]
    u0: NDArray[np.float64]
    u1: NDArray[np.float64]
    starts: NDArray[np.int64]  # first step of each move
    pose_sigma: NDArray[np.float64]  # direction noise of each pose mean, rad
    t_ref: float
    temp_ref: float

    @property
    def n_moves(self) -> int:
        return int(self.u0.shape[0])


def gyro_data(moves: MoveSet, accelerometer: object) -> GyroData:
    """:class:`GyroData` of ``moves`` with the gravity directions of ``accelerometer`` (a calibration result with
    ``correct`` and ``T``)."""
    correct = getattr(accelerometer, "correct")
    f_static = np.asarray(correct(moves.acc_means), dtype=float)
    u = unit_rows(f_static)
    norm = np.linalg.norm(f_static, axis=1)
    pose_sigma = moves.acc_sigma * float(np.mean(np.linalg.norm(np.asarray(getattr(accelerometer, "T")), axis=1))) / norm
    period = moves.noise.period_s if moves.noise is not None else float(np.median(moves.dt))
    t_mid = moves.t_mid if moves.t_mid.size == moves.n_steps else np.cumsum(moves.dt)
    rest_t = moves.rest_t if moves.rest_t.size == moves.gyro_means.shape[0] else np.zeros(moves.gyro_means.shape[0])
    temp_ok = moves.temp_mid is not None and moves.rest_temp is not None and bool(np.all(np.isfinite(moves.rest_temp)))
    return GyroData(
        moves=moves, raw=moves.gyro_mid(), dt=moves.dt, f_mid=np.asarray(correct(moves.acc_mid), dtype=float),
        t_mid=t_mid, temp_mid=moves.temp_mid if temp_ok else None, rest_raw=moves.gyro_means, rest_f=f_static,
        rest_t=rest_t, rest_temp=moves.rest_temp if temp_ok else None, rest_duration=moves.n_static * period,
        u0=u[moves.move_from], u1=u[moves.move_to], starts=np.flatnonzero(moves.first_step).astype(np.int64),
        pose_sigma=pose_sigma, t_ref=float(np.average(rest_t, weights=moves.n_static)),
        temp_ref=float(np.average(moves.rest_temp, weights=moves.n_static)) if temp_ok and moves.rest_temp is not None else 0.0,
    )


@dataclass(frozen=True)
class GyroParams:
    """A point of the extended model: ``T_g``, ``b_g`` and each term's values (rad/s per g, (rad/s)/s, (rad/s)/°C,
    (rad/s)⁻¹)."""

    T: NDArray[np.float64]
    b: NDArray[np.float64]
    terms: tuple[Term, ...]
    values: tuple[NDArray[np.float64], ...]

    def vector(self) -> NDArray[np.float64]:
        return np.concatenate([self.T.ravel(), self.b, *self.values]) if self.values else np.concatenate([self.T.ravel(), self.b])

    def with_vector(self, z: NDArray[np.float64]) -> "GyroParams":
        out, k = [], 12
        for term in self.terms:
            out.append(np.array(z[k:k + term.size], dtype=float))
            k += term.size
        return GyroParams(z[:9].reshape(3, 3).copy(), z[9:12].copy(), self.terms, tuple(out))

    def extend(self, term: Term) -> "GyroParams":
        return GyroParams(self.T, self.b, (*self.terms, term), (*self.values, np.zeros(term.size)))

    def value_of(self, effect: str, axis: int | None) -> NDArray[np.float64] | None:
        for term, value in zip(self.terms, self.values):
            if term.effect == effect and term.axis == axis:
                return value
        return None


def corrected_rates(data: GyroData, p: GyroParams, raw: NDArray[np.float64], f: NDArray[np.float64], t: NDArray[np.float64],
                    temp: NDArray[np.float64] | None, jac: bool) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Corrected rates (n, 3) of raw rates ``raw`` at specific force ``f``, time ``t`` and temperature ``temp``, and
    their derivative (n, 3, nz) by the parameter vector ``p.vector()`` (``jac``)."""
    n = raw.shape[0]
    centred = raw - p.b
    lin = centred @ p.T.T
    nz = 12 + sum(term.size for term in p.terms)
    D = np.zeros((n, 3, nz)) if jac else None
    if D is not None:
        for row in range(3):
            D[:, row, 3 * row:3 * row + 3] = centred  # ∂ω_i/∂T_ij = (g − b)_j
        D[:, :, 9:12] = -p.T  # ∂ω/∂b = −T
    k = 12
    nonlinear: list[tuple[int, int, float]] = []
    for term, value in zip(p.terms, p.values):
        i = term.axis
        if term.effect == "g_sensitivity" and i is not None:
            lin[:, i] -= f @ value
            if D is not None:
                D[:, i, k:k + 3] = -f
        elif term.effect == "gyro_bias_drift" and i is not None:
            lin[:, i] -= value[0] * (t - data.t_ref)
            if D is not None:
                D[:, i, k] = -(t - data.t_ref)
        elif term.effect == "gyro_temperature_bias" and i is not None and temp is not None:
            lin[:, i] -= value[0] * (temp - data.temp_ref)
            if D is not None:
                D[:, i, k] = -(temp - data.temp_ref)
        elif term.effect == "gyro_scale_nonlinearity" and i is not None:
            nonlinear.append((i, k, float(value[0])))
        k += term.size
    omega = lin.copy()
    for row, col, s in nonlinear:  # ω_i = ω_lin,i + s ω_lin,i² (Lu 2017's k₂f² form, for the gyro)
        omega[:, row] = lin[:, row] + s * lin[:, row] ** 2
        if D is not None:
            D[:, row, :] *= (1.0 + 2.0 * s * lin[:, row])[:, None]
            D[:, row, col] = lin[:, row] ** 2
    return omega, D


def predict(data: GyroData, omega: NDArray[np.float64], jacobian: NDArray[np.float64] | None = None
            ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Each move's predicted gravity direction ``Φᵀ u₀`` (m, 3) from the corrected step rates ``omega`` (N, 3), and
    its derivative (m, 3, nz) given the rates' derivative ``jacobian`` (N, 3, nz)
    (:class:`~optcal.families.gyro.propagation.GravityPredictor`)."""
    predictor = GravityPredictor.of_starts(data.starts, omega.shape[0])
    theta = omega * data.dt[:, None]
    if jacobian is None:
        return predictor.directions(theta, data.u0), None
    v, A = predictor.step_sensitivities(theta, data.u0)
    G = np.matmul(A, jacobian * data.dt[:, None, None])  # (N, 3, nz)
    return v, np.add.reduceat(G, data.starts, axis=0)


@dataclass(frozen=True)
class Noise:
    """The measured noise of the two residual kinds: each move's expected squared gravity-prediction angle (rad²,
    split over the two directions across gravity) and each rest mean's variance per axis ((rad/s)²)."""

    move_rad2: NDArray[np.float64]
    rest_var: NDArray[np.float64]


def move_budget(data: GyroData, p: GyroParams) -> ResidualBudget:
    """The moves' noise budget under the paper's model ``p`` by source
    (:func:`~optcal.families.gyro.consistency.residual_budget`)."""
    moves = data.moves
    offsets = rest_offsets(moves, p.b, None, data.rest_f)
    rates = (moves.gyro_pairs - p.b) @ p.T.T
    return residual_budget(moves, p.T, offsets, data.pose_sigma, rates, data.u0)


def measured_noise(data: GyroData, p: GyroParams) -> Noise:
    """:class:`Noise` of the data under the paper's model ``p`` (its ``T_g`` and bias): the moves' budget
    (:func:`move_budget`) and the rests' angle random walk over their duration, rounded at the quantum."""
    moves = data.moves
    budget = move_budget(data, p)
    assert moves.noise is not None
    arw2 = np.diag(p.T @ np.diag(moves.noise.arw2) @ p.T.T)  # (rad/s)² s per axis
    return Noise(budget.total, arw2[None, :] / np.maximum(data.rest_duration, 1e-9)[:, None])


@dataclass
class Evaluation:
    """Residuals of a model: the moves' (m, 3) and the rests' (p, 3), both over their noise, and the Jacobian."""

    moves: NDArray[np.float64]
    rests: NDArray[np.float64]
    J: NDArray[np.float64] | None

    def vector(self, moves: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
        mv = self.moves if moves is None else self.moves[moves]
        return np.concatenate([mv.ravel(), self.rests.ravel()])

    def rss(self, moves: NDArray[np.bool_] | None = None) -> tuple[float, float]:
        """The residual sums of squares of the moves and of the rests."""
        mv = self.moves if moves is None else self.moves[moves]
        return float(np.sum(mv**2)), float(np.sum(self.rests**2))


def evaluate(data: GyroData, noise: Noise, p: GyroParams, jac: bool = True) -> Evaluation:
    """The residuals (over their noise) of ``p`` and their Jacobian by ``p.vector()``."""
    omega, D = corrected_rates(data, p, data.raw, data.f_mid, data.t_mid, data.temp_mid, jac)
    v, Jv = predict(data, omega, D)
    move_sd = np.sqrt(noise.move_rad2 / 2.0)[:, None]  # per direction across gravity
    rest_omega, Dr = corrected_rates(data, p, data.rest_raw, data.rest_f, data.rest_t, data.rest_temp, jac)
    rest_sd = np.sqrt(noise.rest_var)
    moves_r = (v - data.u1) / move_sd
    rests_r = rest_omega / rest_sd
    J = None
    if jac and Jv is not None and Dr is not None:
        J = np.concatenate([(Jv / move_sd[:, :, None]).reshape(-1, Jv.shape[-1]),
                            (Dr / rest_sd[:, :, None]).reshape(-1, Dr.shape[-1])])
    return Evaluation(moves_r, rests_r, J)


def gauss_newton(data: GyroData, noise: Noise, p: GyroParams, iterations: int = SCREEN_ITERATIONS,
                 train: NDArray[np.bool_] | None = None, train_rests: NDArray[np.bool_] | None = None) -> GyroParams:
    """``p`` refined by Gauss–Newton steps (Levenberg's damping where a step does not lower the cost) on the moves
    ``train`` and the rests ``train_rests`` (all by default); the Jacobian at each accepted point only."""
    z = p.vector()
    current = evaluate(data, noise, p)
    rows = None
    if train is not None or train_rests is not None:
        moves_ok = np.ones(current.moves.shape[0], dtype=bool) if train is None else train
        rests_ok = np.ones(current.rests.shape[0], dtype=bool) if train_rests is None else train_rests
        rows = np.concatenate([np.repeat(moves_ok, 3), np.repeat(rests_ok, 3)])
    damping = 0.0
    for iteration in range(iterations):
        assert current.J is not None
        r, J = current.vector(), current.J
        if rows is not None:
            r, J = r[rows], J[rows]
        cost = float(r @ r)
        H = J.T @ J
        g = J.T @ r
        scale = np.sqrt(np.maximum(np.diag(H), 1e-300))
        Hs = H / np.outer(scale, scale)
        for _ in range(6):
            try:
                step = -np.linalg.solve(Hs + damping * np.eye(z.size), g / scale) / scale
            except np.linalg.LinAlgError:
                step = -np.linalg.lstsq(Hs + (damping + 1e-9) * np.eye(z.size), g / scale, rcond=None)[0] / scale
            trial = p.with_vector(z + step)
            e = evaluate(data, noise, trial, jac=False)
            rt = e.vector() if rows is None else e.vector()[rows]
            if float(rt @ rt) <= cost:
                p, z = trial, z + step
                damping = damping / 10.0
                if iteration + 1 < iterations:
                    current = evaluate(data, noise, p)
                break
            damping = max(1e-6, damping * 10.0)
        else:
            break
    return p


def screen(data: GyroData, noise: Noise, p: GyroParams, terms: list[Term]
           ) -> list[tuple[Term, tuple[float, float]]]:
    """Each term's residual sums of squares (moves, rests) after one Gauss–Newton step from ``p`` with the term
    added (``p`` at its optimum, so the step's reduction is the term's score: exact for a term the residuals are
    linear in, first order otherwise); one integration for all of them."""
    wide = p
    for term in terms:
        wide = wide.extend(term)
    e = evaluate(data, noise, wide)
    assert e.J is not None
    r, J = e.vector(), e.J
    n_moves = e.moves.size
    base = 12 + sum(t.size for t in p.terms)
    out = []
    k = base
    for term in terms:
        cols = np.r_[np.arange(base), np.arange(k, k + term.size)]
        k += term.size
        Jc = J[:, cols]
        scale = np.sqrt(np.maximum(np.sum(Jc * Jc, axis=0), 1e-300))
        step = np.linalg.lstsq(Jc / scale, -r, rcond=None)[0]
        new = r + (Jc / scale) @ step
        out.append((term, (float(np.sum(new[:n_moves] ** 2)), float(np.sum(new[n_moves:] ** 2)))))
    return out


def casadi_fit(data: GyroData, noise: Noise, p: GyroParams, solver: str | None = None) -> tuple[GyroParams, dict]:
    """``p`` refitted by IPOPT (or ``solver``) in CasADi: the least squares of every residual, with the analytic
    Jacobian and the Gauss–Newton Hessian (:class:`optcal.families.gyro.estimator.GyroProblem`)."""
    from optcal.families.gyro.estimator import GYRO_PROBLEMS
    from optcal.solvers.registry import choose_nlp_solver

    z0 = p.vector()
    scale = np.maximum(np.abs(z0), 1e-12)
    scale[12:] = 1.0
    # the unknowns relative to the start's magnitudes (T and b) and absolute for the extension's terms, whose
    # natural size the Jacobian's columns carry
    col = np.sqrt(np.maximum(np.sum(evaluate(data, noise, p).J ** 2, axis=0), 1e-300))  # type: ignore[operator]
    col_scale = np.where(np.arange(z0.size) < 12, scale, 1.0 / col)

    def residuals(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        e = evaluate(data, noise, p.with_vector(z0 + x * col_scale))
        assert e.J is not None
        return e.vector(), e.J * col_scale[None, :]

    solution = GYRO_PROBLEMS.get(z0.size, choose_nlp_solver(solver, {})).solve(residuals, np.zeros(z0.size))
    return p.with_vector(z0 + solution.x * col_scale), solution.stats


def move_angles(data: GyroData, p: GyroParams, moves: NDArray[np.bool_] | None = None) -> NDArray[np.float64]:
    """Each move's gravity-prediction angle under ``p``, degrees."""
    omega, _ = corrected_rates(data, p, data.raw, data.f_mid, data.t_mid, data.temp_mid, False)
    v, _ = predict(data, omega)
    angles = angles_deg(v, data.u1)
    return angles if moves is None else angles[moves]
