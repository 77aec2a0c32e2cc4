"""The magnetometer's maximum-likelihood refinement, kept only inside the physical set.

:func:`refine_ml` refines the convex start (Lu 2017, eq. 18-30) by the accelerometer's maximum likelihood
(:mod:`optcal.families.accel.mle`, eq. 13-14), which minimises ``Σ (‖T(m − o)‖ − 1)²``: the residual is a share
of the fitted field.  On samples that cover part of the sphere that likelihood keeps falling as the ellipsoid grows
along the poorly covered axis, and the refinement ends in a degenerate ellipsoid (or IPOPT fails).  So a refinement
is kept only inside the physical set (:func:`refinement_departure`: the field strength within :data:`FIELD_FACTOR`
of the start's, no axis stretched beyond :data:`AXIS_STRETCH`, the rms not above the start's); otherwise the full
form is refined again with the noise in the sensor's units, and where that too leaves the set the start is kept.

With the noise in the sensor's units: a magnetometer's noise is in its own units (its ADC's counts), about
``F · (‖T(m − o)‖ − 1)`` with ``F = det(T)^(−1/3)`` the field strength, so under white noise in those units the
likelihood is ``Σ F² (‖T(m − o)‖ − 1)²`` (:class:`FieldUnitsCost`): growing the ellipsoid no longer shrinks the
residuals for free, and from the convex start it stays at the local optimum next to it where the samples determine
one (generated half spheres with 3-5 % noise: the field within 2.6-4.1 % of the truth; caps of 60° still run away).
Solved by IPOPT in CasADi with numpy callbacks (:class:`optcal.solvers.nlp.CallbackNLP`), as
:class:`optcal.families.accel.mle.VectorisedMLProblem` does the share's.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import theta_from, unpack_theta
from optcal.core.poses import PoseTable
from optcal.errors import FitError, SolverError
from optcal.families.accel.base import Normaliser
from optcal.families.accel.mle import NormResidualCost
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, CallbackNLP, cost_scale
from optcal.solvers.registry import choose_nlp_solver

#: θ's entries on T's diagonal (T lower-triangular: T_xx, T_yy, T_zz), whose product is det(T).
DIAGONAL = np.array([0, 2, 5])


class FieldUnitsCost(NormResidualCost):
    """``c Σ_k (F(θ) r_k(θ))²``: the norm residual ``r_k = ‖T(u_k − o)‖ − 1`` (Lu 2017, eq. 13) times the field
    strength ``F = det(T)^(−1/3) = (T_xx T_yy T_zz)^(−1/3)`` (module docstring), one unit, squared loss."""

    def field(self, x: NDArray) -> float:
        """``F(θ)``, in the units of the data the cost holds."""
        return float(np.prod(np.asarray(x, dtype=float).ravel()[DIAGONAL]) ** (-1.0 / 3.0))

    def residuals(self, x: NDArray) -> NDArray[np.float64]:
        """``F(θ) r_k(θ)``."""
        return self.field(x) * super().residuals(x)

    def jacobian(self, x: NDArray) -> NDArray[np.float64]:
        """``F ∂r_k/∂θ + r_k ∂F/∂θ`` (∂F/∂T_ii = −F/(3 T_ii)), shape (9, n)."""
        theta = np.asarray(x, dtype=float).ravel()
        F = self.field(theta)
        dF = np.zeros(9)
        dF[DIAGONAL] = -F / (3.0 * theta[DIAGONAL])
        return F * super().jacobian(x) + dF[:, None] * super().residuals(x)[None, :]


def refine_in_sensor_units(m: NDArray[np.float64], T0: NDArray[np.float64], o0: NDArray[np.float64],
                           est: dict[str, Any], diagonal_range: float) -> tuple[NDArray[np.float64], NDArray[np.float64], str]:
    """Minimise :class:`FieldUnitsCost` from ``(T0, o0)`` (T0 lower-triangular, the convex start) by IPOPT in CasADi.

    ``est`` gives the solver (``solver``, ``solver_options``, ``ipopt_options``).  T's diagonal entries are bounded
    within ``diagonal_range`` times the start's field's reciprocal, either way: a triangular T's diagonal lies
    between its smallest and largest singular values, so a bound implied by the physical set (the caller's) never
    cuts a physical fit and keeps F finite.  Returns the lower-triangular ``T``, ``o`` and the solver's status.
    """
    norm = Normaliser.of(m)
    u = norm.forward(m)
    theta0 = norm.theta_to_normalised(theta_from(T0, o0))
    cost = FieldUnitsCost(u, np.ones(len(u)))
    cost.scale = cost_scale(cost.n, np.sqrt(cost.unit_values(theta0) / cost.n))
    choice = choose_nlp_solver(est.get("solver"), {**dict(est.get("ipopt_options") or {}),
                                                   **dict(est.get("solver_options") or {})})
    nlp = CallbackNLP("mag_ml_sensor_units", 9, hessian_block_size=9, tuning=SCALED_COST_IPOPT_OPTIONS, solver=choice)
    F0 = cost.field(theta0)  # normalised units
    lbx, ubx = np.full(9, -np.inf), np.full(9, np.inf)
    lbx[DIAGONAL], ubx[DIAGONAL] = 1.0 / (diagonal_range * F0), diagonal_range / F0
    theta_n, stats = nlp.solve(cost.objective(), x0=np.clip(theta0, lbx, ubx), lbx=lbx, ubx=ubx)
    T, o = unpack_theta(norm.theta_to_raw(theta_n))
    return T, o, str(stats.get("return_status", "unknown"))


#: The physical set the maximum-likelihood refinement must end in, relative to its convex start.  The residual
#: ``‖T(m − o)‖ − 1`` is a share of the fitted field, so on samples that cover part of the sphere (a cap) the
#: likelihood keeps falling as the ellipsoid grows along the poorly covered axis: generated half spheres with 3 %
#: noise end at 8 times the field, 5 % at 38 times (ybabs/MagCalib's 12 of 26 cells: 28 times, or IPOPT fails).
#: The field the samples trace is the Earth's: ArduPilot (CompassCalibrator.h, COMPASS_MAX_SCALE_FACTOR) accepts
#: a fitted radius within a factor 1.5 of the field it expects, so a refinement that moves the field strength by
#: more than that factor from its start has left the field, not refined it.
FIELD_FACTOR: float = 1.5
#: A soft iron and a sensor's scale mismatch stretch an axis by at most this factor against the field
#: (ArduPilot's CompassCalibrator.cpp fit_acceptable: each COMPASS_DIA within 0.2-5): a singular value of
#: ``T`` times the field strength outside [1/5, 5] is a degenerate ellipsoid, not a soft iron.
AXIS_STRETCH: float = 5.0
#: The two noise models' fits of the full form (the share of the fitted field, Lu 2017 eq. 14, and the sensor's
#: units, :class:`FieldUnitsCost`) agree on a covered sphere (Magneto's mag.txt, ckexplorer, tomisuarez2: 0.03-0.6 %
#: of the field rms over the directions); where they calibrate the field differently by more than a tenth of it
#: (the error of an uncalibrated phone compass, about 6° of heading) the noise model decides the answer, and the
#: share's fit has slid along a poorly covered axis (generated half spheres, 2 % soft iron, 3 % noise: 12-14 % of the
#: field against the truth, while the sensor units' fit is within 1.3 %), so the sensor units' model (the
#: magnetometer's noise is in its own units) is the one kept.
NOISE_MODEL_SHARE: float = 0.1
#: The two noise models' fits are compared on at most this many samples, evenly spaced in time: the share's slide is
#: systematic (measured: the same disagreement at 5,000 samples as at 25,599), and the check stays cheap at 10⁶.
NOISE_MODEL_SAMPLES: int = 5000
#: Directions over which the two fits' calibrated fields are compared (a fixed, even spread over the sphere).
_DIRECTIONS = np.random.default_rng(0).normal(size=(2000, 3))
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1, keepdims=True)


def _noise_model_departure(m: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64],
                           T0: NDArray[np.float64], o0: NDArray[np.float64], est: dict[str, Any]) -> str | None:
    """Why the share's maximum-likelihood fit ``(T, o)`` of the full or diagonal form is not kept although inside the
    physical set: it calibrates a unit field in every direction differently from the full form's fit with the noise
    in the sensor's units (from the same start, on at most :data:`NOISE_MODEL_SAMPLES` samples; it nests the diagonal
    form) by more than :data:`NOISE_MODEL_SHARE` rms."""
    stride = max(1, -(-len(m) // NOISE_MODEL_SAMPLES))
    try:
        Tu, ou, _ = refine_in_sensor_units(np.ascontiguousarray(m[::stride]), T0, o0, est, FIELD_FACTOR * AXIS_STRETCH)
    except SolverError:  # no second opinion: the share's fit stands on the physical set's test alone
        return None
    raw = np.linalg.solve(T, _DIRECTIONS.T).T + o  # the raw samples the share's fit calibrates to a unit field
    gap = float(np.sqrt(np.mean((np.linalg.norm((raw - ou) @ Tu.T, axis=1) - 1.0) ** 2)))
    if not gap > NOISE_MODEL_SHARE:
        return None
    return (f"it calibrates the field differently from the fit with the noise in the sensor's units by {100 * gap:.3g} % "
            f"rms over the directions (beyond {100 * NOISE_MODEL_SHARE:g} %: the share of the fitted field shrank by "
            f"growing the ellipsoid along a poorly covered axis)")


#: The solver's name of a fit that is the convex start kept because no maximum likelihood stayed in the physical set.
START_SOLVER: str = "the maximum-likelihood refinement's start"
#: The methods that refine the convex start by maximum likelihood (Lu 2017, eq. 14, from eq. 18-30's fit).
ML_METHODS: tuple[str, ...] = ("default", "mle")


def _mean_square(m: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]) -> float:
    """Mean of ``(‖T(m − o)‖ − 1)²`` (T d per row by einsum: numpy's matmul of (n, 3) by (3, 3) is several times slower)."""
    v = np.einsum("kj,ij->ki", m - o, T)
    r = np.sqrt(np.einsum("ki,ki->k", v, v)) - 1.0
    return float(r @ r) / len(r)


def refinement_departure(T: NDArray[np.float64], o: NDArray[np.float64], start_T: NDArray[np.float64],
                         start_o: NDArray[np.float64], m: NDArray[np.float64], loss: str) -> str | None:
    """Why a maximum-likelihood refinement ``(T, o)`` of the convex start ``(start_T, start_o)`` is not kept, or None.

    Not kept when it leaves the physical set (the field strength moved by more than :data:`FIELD_FACTOR`
    from the start's, or an axis stretched by more than :data:`AXIS_STRETCH` against the field), or when,
    under the squared loss (``loss="squared"``; any other value skips this test), its objective
    Σ (‖T(m − o)‖ − 1)² (Lu 2017, eq. 14) is larger than the start's (a solver stopped early at a worse point).
    """
    F = float(np.linalg.det(T) ** (-1.0 / 3.0)) if np.linalg.det(T) > 0 else np.inf
    F0 = float(np.linalg.det(start_T) ** (-1.0 / 3.0))
    if not F0 / FIELD_FACTOR <= F <= FIELD_FACTOR * F0:
        return (f"its field strength {F:.4g} is {F / F0:.3g} times the convex start's {F0:.4g} (beyond a factor "
                f"{FIELD_FACTOR:g}: the ellipsoid grew along a poorly covered axis)")
    sv = np.linalg.svd(T, compute_uv=False) * F
    if sv.max() > AXIS_STRETCH or sv.min() < 1.0 / AXIS_STRETCH:
        return (f"it stretches an axis by {max(sv.max(), 1.0 / sv.min()):.3g} against the field (a soft iron: at most "
                f"{AXIS_STRETCH:g})")
    if loss == "squared":
        mse, mse0 = _mean_square(m, T, o), _mean_square(m, start_T, start_o)
        if mse > mse0:
            return f"its rms {np.sqrt(mse):.6g} is above the convex start's {np.sqrt(mse0):.6g}"
    return None


@dataclass(frozen=True)
class SensorUnitsFit:
    """The full form refined with the noise in the sensor's units (:func:`refine_in_sensor_units`), or the convex
    start kept: ``T`` lower-triangular, ``o``, the method's name and the solver's."""

    T: NDArray[np.float64]
    o: NDArray[np.float64]
    method: str
    solver: str


def solver_name(result: Any) -> str:
    """The solver's name of a refinement's result (a :class:`SensorUnitsFit` or a calibration result)."""
    return result.solver if isinstance(result, SensorUnitsFit) else str(result.solver.name)


def refine_ml(poses: PoseTable, form: str, method: str, est: dict[str, Any]) -> tuple[Any, str | None]:
    """The maximum-likelihood refinement of the convex start; where it fails or is not kept
    (:func:`refinement_departure`), the full form's refinement with the noise in the sensor's units
    (:func:`optcal.families.mag.refine.refine_in_sensor_units`, squared loss, no ``fix``/``bounds``) when that one is
    kept, else the start, with the note that says so.  The diagonal form (no start of its own) raises
    :class:`SolverError` instead, so that the other forms are tried."""
    from optcal.families.accel.calibration import calibrate, make_estimator

    ml = make_estimator("mle", allow_degenerate=True, **est)
    norm = Normaliser.of(poses.acc)
    theta_n, start_method = ml.initial_normalised(poses, norm, norm.forward(poses.acc))  # the ML's own start
    T0, o0 = unpack_theta(norm.theta_to_raw(theta_n))
    why: str | None
    # the objective is compared with the start's only where both are fits of the same model: a fixed or bounded
    # entry (the diagonal form's off-diagonals, the user's --fix/--bound) makes the refinement's a smaller one
    same_model = form == "full" and not est.get("fix") and not est.get("bounds")
    try:
        with warnings.catch_warnings(record=True) as caught:  # a solver's warning stands only where its result is kept
            warnings.simplefilter("always")
            result = calibrate(poses, method=method, allow_degenerate=True, **est)
        why = refinement_departure(result.T, np.asarray(result.o, float), T0, o0, poses.acc, str(est.get("loss") or "squared") if same_model else "")
    except (SolverError, FitError) as exc:  # FitError: the fit collapsed to a singular T (a cap grown without bound)
        why = f"it failed ({exc})"
    # the diagonal form's own constraint (its off-diagonal entries fixed at 0) and nothing the user fixed or bounded
    unconstrained = not est.get("bounds") and set(dict(est.get("fix") or {})) <= ({"T_yx", "T_zx", "T_zy"} if form == "diagonal" else set())
    if why is None and unconstrained and str(est.get("loss") or "squared") == "squared":
        why = _noise_model_departure(poses.acc, result.T, np.asarray(result.o, float), T0, o0, est)
    if why is None:
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return result, None
    if form != "full":
        raise SolverError(f"the maximum-likelihood refinement is not kept: {why}")
    head = f"the maximum-likelihood refinement of the full form is not kept: {why}"
    if same_model and str(est.get("loss") or "squared") == "squared":
        try:
            # the physical set bounds T's diagonal within FIELD_FACTOR · AXIS_STRETCH of 1/F0 either way
            T, o, status = refine_in_sensor_units(poses.acc, T0, o0, est, FIELD_FACTOR * AXIS_STRETCH)
            why2 = refinement_departure(T, o, T0, o0, poses.acc, "squared")
        except SolverError as exc:
            why2 = f"it failed ({exc})"
        if why2 is None:
            return (SensorUnitsFit(T, o, "mle (noise in the sensor's units)", f"CasADi nlpsol, {status}"),
                    f"{head}; refined instead with the noise in the sensor's units (the residual times the field "
                    f"strength), which stays in the physical set (--method convex keeps the convex start)")
        head += f"; nor with the noise in the sensor's units ({why2})"
    return SensorUnitsFit(T0, o0, start_method, START_SOLVER), (
        f"{head}; the convex start is kept (--method convex gives it directly; --bound T_..=LOW:HIGH, "
        f"o_..=LOW:HIGH confines the refinement)")
