"""Is a gyro calibration supported by the moves?  The gravity-prediction residual against a noise model.

After the fit, each move leaves an angle ``θ_i`` between the gravity direction the
calibrated gyro carries across it and the one the accelerometer measures at the next pose
(Tedaldi 2014, eq. 13).  A gyro calibration that is right leaves only what the sensors'
noise and the integration make; :func:`residual_budget` states that, per move, as the
expected squared angle ``σ_i²`` (radians², the two components across gravity; the
component along it is second order), the sum of

* **angle random walk** — the gyro's white noise integrated over the move,
  ``⅔ tr(T_g N² T_gᵀ) T_i`` (``N²`` per axis from the rests' Allan variance,
  :class:`~optcal.families.gyro.moves.RestNoise`, at least the quantisation's ``q²/12 Δt``;
  ``⅔``: the share of an isotropic rotation error that tilts gravity);
* **bias between the rests** — one bias serves every move, the rests on either side of a
  move read ``o = ḡ − b − G f`` off it (drift, turn-on changes, the rests' own noise):
  ``⅔ |T_g ō_i|² T_i²`` with ``ō_i`` the mean offset of the move's two rests;
* **accelerometer pose noise** — the direction error of the two pose means,
  ``2 (σ_a,i² + σ_a,i+1²)`` with ``σ_a`` the standard deviation of a pose mean in g over
  ``|f|``;
* **time base** — stamps off a regular clock by ``σ_ε`` (jitter, quantised stamps) move the
  rate's samples in time, ``⅔ σ_ε² Σ_k |ω_k − ω_{k−1}|²`` over the move;
* **integration** — the trapezoid's and the exponential map's own error, by Richardson's
  extrapolation: the direction integrated at half the rate differs from the one at the full
  rate by three times the error of the latter (second-order rule), ``(∠/3)²``; and the
  bound of any hole bridged in the move (:mod:`optcal.families.gyro.moves`),
  ``⅔ (‖T_g‖ e_i)²``.

Not modelled: the sensor's motion during the rests (a hand's tremor, the pose mean not the
pose at the rest's ends), the accelerometer's model error, a g-sensitivity left out of the
fit (it changes with the specific force along a move), a rate beyond the gyro's range.
They are why a residual beyond the noise model is first flagged, and refused only far
beyond it.

Tests (:func:`check_gyro_fit`)
------------------------------
1. **Residual** (:class:`ResidualTest`): ``X = 2 Σ θ_i² / σ_i²`` is χ² with ``ν = 2m − 9``
   degrees of freedom (two per move, nine parameters fitted; ``2m`` when a saved
   calibration is checked on other data).  Beyond its :data:`BOUND_LEVEL` quantile the
   residual is *flagged*; with ``√(X / χ²_ν(level))`` beyond :data:`REFUSAL_MARGIN` it is
   *far beyond* the noise model: the errors the model leaves out would have to be
   :data:`REFUSAL_MARGIN`² − 1 (eight) times as large as all it states.  Significance is not
   relevance: a real gyro's effects the model leaves out (g-sensitivity along the moves, a
   bias that moves during them, stamps off the sampling instants) make a good calibration's
   residual far beyond the model on a long recording.  A fit is *refused* on its residual only
   when, far beyond the model, the residual is also more than :data:`MAX_UNEXPLAINED_FRACTION`
   of the angle gravity turns through across the moves (``φ_i``, the angle between the
   accelerometer's directions at the move's two rests): then the fit explains little of the
   moves and cannot be a calibration.  Otherwise it is kept, with a warning that states the
   excess and points to ``optcal diagnose --imu``.
2. **Signal**: the raw rotation ``β_i`` the gyro integrates across each move against the
   angle random walk of its noise over the move, ``S = Σ_i Σ_a β_ia² / (N_a² T_i)``, which
   is χ² with ``3m`` degrees of freedom when the columns hold noise only.  Refused below
   :data:`REFUSAL_MARGIN`² times its :data:`BOUND_LEVEL` quantile: the gyro does not see the
   moves (with a scale free to grow, a fit on noise explains itself through test 1).
3. **Axes**: the gyro's sensing axes (rows of ``T_g⁻¹``) against the accelerometer's.  An
   axis more than :data:`AXIS_MATCH_DEG` from the accelerometer axis of its name, half-way to
   another axis or further, is no mounting error (those are a few degrees) but a column
   mapping or a sign.
4. **Scale** (gyro units with a nominal scale, rad/s and °/s): the fitted scale of each axis
   more than :data:`MAX_SCALE_ERROR` off the nominal is a unit, a full-scale setting or a
   time base, not a sensitivity error.

Tests 2-4 are what the residual cannot see: a pure-noise gyro, and a linear mix of the
right rates (permuted columns, a flipped sign, a wrong time base or unit), which ``T_g``
absorbs exactly.  A wrong time base of a gyro in counts, which have no nominal scale, is
absorbed into ``T_g`` unseen.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core import quantiles
from optcal.core.gyro_model import GyroModel
from optcal.core.model import AXES
from optcal.families.gyro.moves import MoveSet
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows

#: Level of the bound on the residual (and on a noise-only gyro's integrated rotation) under the noise model.
BOUND_LEVEL: float = 0.999
#: How far beyond the bound (in angle, a factor on the rms) a residual is refused rather than flagged: at 3 the
#: errors the noise model leaves out would have to carry 3² − 1 = 8 times its variance.
REFUSAL_MARGIN: float = 3.0
#: A gyro sensing axis further than this from the accelerometer axis of the same name is half-way to another axis or
#: beyond: a column mapping or sign, where mounting misalignments are a few degrees.
AXIS_MATCH_DEG: float = 45.0
#: Largest relative departure of a fitted gyro scale from the nominal of its units: a MEMS gyro's sensitivity is
#: within a few % of nominal (InvenSense MPU-6050/9150: ±3 % at 25 °C, ±2 % more over temperature); 20 % is four
#: times their sum, while a wrong unit or time base is a factor of 57 (°/s for rad/s), 1000 (ms for s) or the ratio
#: of two sampling rates.
MAX_SCALE_ERROR: float = 0.2
#: Largest share of the moves' gravity turn (rms of φ_i) a calibration's residual can leave unexplained: a gyro whose
#: scale is :data:`MAX_SCALE_ERROR` off (the largest error of a sensitivity) would leave about that share of each turn;
#: a residual beyond it is more than any sensor's calibration error (a column that is not the moves' rate, a time
#: base or unit off by a factor), and a good calibration leaves well under it (0.5° on 90° turns is 0.6 %).
MAX_UNEXPLAINED_FRACTION: float = MAX_SCALE_ERROR
#: Where a kept calibration's excess residual is looked into.
DIAGNOSE_POINTER: str = "optcal diagnose --imu names its cause and the model term that removes it"
#: What the override assumes, for its warning.
OVERRIDE_ASSUMES: str = ("assumes the gyro columns are this sensor's body rates, in the units and on the time base "
                         "read, and that the moves' residual comes from an error the noise model leaves out")
#: What a refusal names as the likely causes, and the override.
LIKELY_CAUSES: str = ("likely causes: the gyro columns (mapping, order or sign: columns=), their units (gyro_units=), "
                      "the time base (rate= or the time column); pass accept_gyro_fit=True to keep it anyway")
#: The two components of a rotation error that tilt gravity, out of three (an isotropic error).
ACROSS_GRAVITY: float = 2.0 / 3.0
#: Smallest expected angle of a move, radians (0.02″): below any gyro's angle random walk over a second (a
#: navigation-grade 0.002 °/√h makes 6e-7 rad), the floor a noise-free simulation meets at the solver's tolerance.
NUMERICAL_FLOOR_RAD: float = 1e-7


@dataclass(frozen=True)
class ResidualBudget:
    """Expected squared gravity-prediction angle of each move, by source (radians², shape (m,) each)."""

    random_walk: NDArray[np.float64]
    bias: NDArray[np.float64]
    accelerometer: NDArray[np.float64]
    time_base: NDArray[np.float64]
    integration: NDArray[np.float64]

    @property
    def total(self) -> NDArray[np.float64]:
        """The expected squared angle, at least :data:`NUMERICAL_FLOOR_RAD` squared."""
        parts = self.random_walk + self.bias + self.accelerometer + self.time_base + self.integration
        return np.maximum(parts, NUMERICAL_FLOOR_RAD**2)

    def rms_deg(self) -> dict[str, float]:
        """Rms over the moves of each source, and of the total, degrees."""
        parts = {"random_walk": self.random_walk, "bias": self.bias, "accelerometer": self.accelerometer,
                 "time_base": self.time_base, "integration": self.integration, "total": self.total}
        return {k: float(np.degrees(np.sqrt(np.mean(v)))) for k, v in parts.items()}


def rest_offsets(
    moves: MoveSet, bias: NDArray, g_sensitivity: NDArray | None, f_static: NDArray
) -> NDArray[np.float64]:
    """Each move's mean offset of the bias at its two rests from the model's, raw units, shape (m, 3)."""
    model = np.broadcast_to(np.asarray(bias, float), moves.gyro_means.shape)
    if g_sensitivity is not None:
        model = model + f_static @ np.asarray(g_sensitivity, float).T
    offsets = moves.gyro_means - model
    return 0.5 * (offsets[moves.move_from] + offsets[moves.move_to])


def half_rate_directions(moves: MoveSet, rates_at_ends: NDArray, u0: NDArray) -> NDArray[np.float64]:
    """Gravity carried across each move by the trapezoid over every other sample (rates_at_ends: (N, 2, 3) rad/s)."""
    position = GravityPredictor(moves.first_step, moves.last_step).position
    starts = np.flatnonzero(position % 2 == 0)  # each pair of steps (a move's odd last step alone)
    stops = np.concatenate([starts[1:], [moves.n_steps]]) - 1
    dt = np.add.reduceat(moves.dt, starts)
    rate = 0.5 * (rates_at_ends[starts, 0] + rates_at_ends[stops, 1])
    last = np.searchsorted(starts, moves.last_step, side="right") - 1
    return GravityPredictor(moves.first_step[starts], last)(rate, dt, u0)


def residual_budget(
    moves: MoveSet,
    Tg: NDArray,
    offsets: NDArray,
    pose_sigma_rad: NDArray,
    rates_at_ends: NDArray,
    u0: NDArray,
) -> ResidualBudget:
    """The noise model of the gravity-prediction residual (module docstring), per move.

    Parameters
    ----------
    moves : MoveSet
        With its rests' noise (:attr:`MoveSet.noise`).
    Tg : ndarray, shape (3, 3)
        rad/s per raw unit.
    offsets : ndarray, shape (m, 3)
        :func:`rest_offsets`, raw units.
    pose_sigma_rad : ndarray, shape (p,)
        Direction error of each pose mean, radians per component.
    rates_at_ends : ndarray, shape (N, 2, 3)
        Calibrated rate at both ends of every step, rad/s.
    u0 : ndarray, shape (m, 3)
        Gravity direction at the start of each move.
    """
    if moves.noise is None:
        raise ValueError("the moves carry no rest noise (build them with moves_from_arrays)")
    Tg = np.asarray(Tg, float)
    T = moves.durations()
    random_walk = ACROSS_GRAVITY * float(np.trace(Tg @ np.diag(moves.noise.arw2) @ Tg.T)) * T
    bias = ACROSS_GRAVITY * np.sum((offsets @ Tg.T) ** 2, axis=1) * T**2
    accelerometer = 2.0 * (pose_sigma_rad[moves.move_from] ** 2 + pose_sigma_rad[moves.move_to] ** 2)
    mid = rates_at_ends.mean(axis=1)
    change = np.sum(np.diff(mid, axis=0) ** 2, axis=1)
    change[moves.first_step[1:]] = 0.0  # no difference across two moves
    ends = moves.step_bounds()
    per_move_change = np.add.reduceat(np.concatenate([[0.0], change]), ends[:-1])
    time_base = ACROSS_GRAVITY * moves.noise.stamp_jitter_s**2 * per_move_change
    full = GravityPredictor(moves.first_step, moves.last_step)(mid, moves.dt, u0)
    richardson = np.radians(angles_deg(full, half_rate_directions(moves, rates_at_ends, u0))) / 3.0
    bridge = np.zeros(moves.n_moves) if moves.bridge_bound.size != moves.n_moves else moves.bridge_bound
    integration = richardson**2 + ACROSS_GRAVITY * (np.linalg.norm(Tg, 2) * bridge) ** 2
    return ResidualBudget(random_walk, bias, accelerometer, time_base, integration)


@dataclass(frozen=True)
class ResidualTest:
    """The gravity-prediction residual against its noise model (module docstring, test 1).

    Attributes
    ----------
    angles_deg : ndarray, shape (m,)
        Measured angle of each move, degrees.
    expected_rad2 : ndarray, shape (m,)
        Expected squared angle of each move (:attr:`ResidualBudget.total`), radians².
    dof : int
        Degrees of freedom of the statistic.
    parts_deg : dict
        Rms over the moves of each source of the budget, degrees.
    turn_deg : ndarray, shape (m,)
        Angle gravity turns through across each move (between the accelerometer's directions at
        its two rests), degrees; empty when unknown (then the residual is refused far beyond the
        noise model alone).
    """

    angles_deg: NDArray[np.float64]
    expected_rad2: NDArray[np.float64]
    dof: int
    parts_deg: dict[str, float] = field(default_factory=dict)
    turn_deg: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @property
    def statistic(self) -> float:
        """``X = 2 Σ θ² / σ²`` (χ² with :attr:`dof` under the model)."""
        theta2 = np.radians(self.angles_deg) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            terms = np.where(theta2 > 0, 2.0 * theta2 / self.expected_rad2, 0.0)
        return float(np.sum(terms))

    @property
    def bound(self) -> float:
        """The :data:`BOUND_LEVEL` quantile of χ² with :attr:`dof` degrees of freedom."""
        return quantiles.chi2_isf(1.0 - BOUND_LEVEL, max(self.dof, 1))

    @property
    def ratio(self) -> float:
        """``√(X / bound)``: the residual's rms over the bound's, in angle (≤ 1 within the bound)."""
        return float(np.sqrt(self.statistic / self.bound))

    @property
    def rms_deg(self) -> float:
        return float(np.sqrt(np.mean(self.angles_deg**2)))

    @property
    def expected_rms_deg(self) -> float:
        return float(np.degrees(np.sqrt(np.mean(self.expected_rad2))))

    @property
    def bound_rms_deg(self) -> float:
        """The rms angle at the bound (the expected rms scaled by the quantile over its mean)."""
        return self.expected_rms_deg * float(np.sqrt(self.bound / max(self.dof, 1)))

    @property
    def flagged(self) -> bool:
        return self.ratio > 1.0

    @property
    def far_beyond(self) -> bool:
        """Beyond :data:`REFUSAL_MARGIN` times the bound (significance, not yet relevance)."""
        return self.ratio > REFUSAL_MARGIN

    @property
    def turn_rms_deg(self) -> float:
        """Rms angle gravity turns through across the moves, degrees (NaN when unknown)."""
        return float(np.sqrt(np.mean(self.turn_deg**2))) if self.turn_deg.size else float("nan")

    @property
    def unexplained_fraction(self) -> float:
        """The residual's rms over the moves' rms gravity turn (NaN when the turns are unknown)."""
        turn = self.turn_rms_deg
        return self.rms_deg / turn if turn > 0 else float("nan") if np.isnan(turn) else float("inf")

    @property
    def refused(self) -> bool:
        """Cannot be a calibration: far beyond the noise model and leaving more than
        :data:`MAX_UNEXPLAINED_FRACTION` of the moves' turn unexplained (far beyond alone when the turns are unknown)."""
        share = self.unexplained_fraction
        return self.far_beyond and (np.isnan(share) or share > MAX_UNEXPLAINED_FRACTION)

    def describe(self) -> str:
        """One line: measured, expected, bound, verdict."""
        share = self.unexplained_fraction
        of_turn = (f"; {share:.1%} of the moves' {self.turn_rms_deg:.3g}° rms gravity turn"
                   if np.isfinite(share) else "")
        if self.refused:
            verdict = ("beyond what the gyro noise and the moves explain" if np.isnan(share) else
                       f"the fit explains little of the moves (more than {MAX_UNEXPLAINED_FRACTION:.0%} of their turn "
                       "left)")
        elif self.far_beyond:
            verdict = (f"{self.rms_deg - self.bound_rms_deg:.3f}° rms beyond the bound, far beyond the noise model "
                       f"but under {MAX_UNEXPLAINED_FRACTION:.0%} of the moves' turn: kept; {DIAGNOSE_POINTER}")
        elif self.flagged:
            verdict = ("above the bound: an error the noise model leaves out (bias drift within the moves, motion "
                       "during the rests, g-sensitivity)")
        else:
            verdict = "within the noise model"
        return (f"gravity prediction {self.rms_deg:.3f}° rms over {self.angles_deg.size} moves{of_turn}; the noise "
                f"model expects {self.expected_rms_deg:.3f}° ({BOUND_LEVEL:.1%} bound {self.bound_rms_deg:.3f}°, "
                f"χ² {self.statistic:.1f} for {self.dof} dof, {self.ratio:.2f}× the bound): {verdict}")

    def to_dict(self) -> dict[str, Any]:
        return {"rms_deg": self.rms_deg, "expected_rms_deg": self.expected_rms_deg, "bound_rms_deg": self.bound_rms_deg,
                "chi2": self.statistic, "dof": self.dof, "bound_level": BOUND_LEVEL, "ratio_to_bound": self.ratio,
                "flagged": self.flagged, "far_beyond": self.far_beyond, "refused": self.refused,
                "turn_rms_deg": self.turn_rms_deg, "unexplained_fraction": self.unexplained_fraction,
                "expected_parts_deg": dict(self.parts_deg)}


def residual_test(moves: MoveSet, accelerometer: Any, model: GyroModel, angles: NDArray, fitted: int,
                  bias: NDArray | None = None) -> ResidualTest:
    """Test 1 (:class:`ResidualTest`) of the angles ``model`` leaves on ``moves``.

    Parameters
    ----------
    moves : MoveSet
    accelerometer : CalibrationResult
        Corrects raw specific force to g (``correct``), with ``T`` (g per raw unit).
    model : GyroModel
        The gyro calibration whose angles are tested.
    angles : ndarray, shape (m,)
        Its gravity-prediction angle of each move, degrees.
    fitted : int
        Parameters fitted to these angles (9 for the fit; 0 when a saved calibration is checked on other data).
    bias : ndarray, shape (3,), optional
        The bias the rests' offsets are read from (the model's by default; a check on other data passes that
        data's own, so that a bias the calibration got wrong is not taken for noise).
    """
    f_static = accelerometer.correct(moves.acc_means)
    norm = np.linalg.norm(f_static, axis=1)
    pose_sigma = moves.acc_sigma * float(np.mean(np.linalg.norm(np.asarray(accelerometer.T), axis=1))) / norm
    f_mid = accelerometer.correct(moves.acc_mid)
    G = model.g_sensitivity
    offsets = rest_offsets(moves, model.bias if bias is None else bias, G, f_static)
    raw = moves.gyro_pairs - model.bias
    if G is not None:
        raw = raw - (f_mid @ G.T)[:, None, :]
    rates = raw @ model.T.T
    u = unit_rows(f_static)
    budget = residual_budget(moves, model.T, offsets, pose_sigma, rates, u[moves.move_from])
    turn = angles_deg(u[moves.move_from], u[moves.move_to])  # what the moves turn gravity through
    return ResidualTest(np.asarray(angles, float), budget.total, 2 * moves.n_moves - fitted, budget.rms_deg(), turn)


def signal_to_noise(moves: MoveSet, w: NDArray) -> tuple[float, float]:
    """Test 2: ``S = Σ_i Σ_a β_ia² / (N_a² T_i)`` of the bias-free raw rates ``w`` (N, 3), and its level."""
    if moves.noise is None:
        raise ValueError("the moves carry no rest noise (build them with moves_from_arrays)")
    ends = moves.step_bounds()
    beta = np.add.reduceat(w * moves.dt[:, None], ends[:-1], axis=0)
    arw2 = np.where(moves.noise.arw2 > 0, moves.noise.arw2, np.inf)
    S = float(np.sum(beta**2 / (arw2[None, :] * moves.durations()[:, None])))
    level = REFUSAL_MARGIN**2 * quantiles.chi2_isf(1.0 - BOUND_LEVEL, 3 * moves.n_moves)
    return S, level


def unseen_moves_finding(moves: MoveSet, S: float, level: float) -> str | None:
    """Test 2's finding: the gyro does not see the moves when ``S`` of :func:`signal_to_noise` is below its level.

    Parameters
    ----------
    moves : MoveSet
    S, level : float
        :func:`signal_to_noise`'s statistic and level.

    Returns
    -------
    str or None
        The finding, or ``None`` when the moves' rotation stands out of the noise.
    """
    if S >= level:
        return None
    ratio = np.sqrt(S / (3 * moves.n_moves))
    return (f"the gyro does not see the moves (their rotation is {ratio:.3g}× the random walk its noise makes over "
            "them, noise alone gives about 1)")


def refusal_line(findings: list[str] | tuple[str, ...]) -> str:
    """The one-line refusal of a gyro calibration: what is wrong (``findings``), the likely causes and the override."""
    causes = LIKELY_CAUSES[0].upper() + LIKELY_CAUSES[1:]
    return f"the gyro calibration cannot be right: {'; '.join(findings)}. {causes}"


def axis_findings(Tg: NDArray) -> list[str]:
    """Test 3: the gyro axes further than :data:`AXIS_MATCH_DEG` from the accelerometer's axes of their names."""
    axes = np.linalg.inv(np.asarray(Tg, float))
    axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    out = []
    for i, row in enumerate(axes):
        angle = float(np.degrees(np.arccos(np.clip(row[i], -1.0, 1.0))))
        if angle > AXIS_MATCH_DEG:
            j = int(np.argmax(np.abs(row)))
            sign = "+" if row[j] > 0 else "-"
            near = float(np.degrees(np.arccos(np.clip(abs(row[j]), -1.0, 1.0))))
            out.append(f"gyro {AXES[i]} senses {angle:.1f}° from the accelerometer's {AXES[i]} axis, "
                       f"{near:.1f}° from its {sign}{AXES[j]} axis")
    return out


def scale_findings(Tg: NDArray, units: str, rad_per_unit: float | None) -> list[str]:
    """Test 4: fitted scales more than :data:`MAX_SCALE_ERROR` off the nominal of the units (none for counts)."""
    if rad_per_unit is None:
        return []
    scale = np.linalg.norm(np.asarray(Tg, float), axis=0) / rad_per_unit  # per raw axis, × nominal
    low, high = 1 / (1 + MAX_SCALE_ERROR), 1 + MAX_SCALE_ERROR
    off = [f"{AXES[j]} {s:.3g}×" for j, s in enumerate(scale) if not low <= s <= high]
    if not off:
        return []
    return [f"the fitted gyro scale is {', '.join(off)} the nominal of {units} (a sensitivity is within "
            f"{MAX_SCALE_ERROR:.0%} of it)"]


@dataclass(frozen=True)
class GyroFitCheck:
    """The four tests of a fitted gyro calibration (module docstring).

    Attributes
    ----------
    residual : ResidualTest
    signal : float
        ``S`` of test 2.
    signal_level : float
        The level ``S`` must exceed.
    findings : tuple of str
        Why the calibration cannot be right (empty: it may be).
    accepted : bool
        Kept despite findings (``accept_gyro_fit``).
    hint : str
        What to try when the residual is flagged (e.g. a model term not fitted), or empty.
    """

    residual: ResidualTest
    signal: float
    signal_level: float
    findings: tuple[str, ...] = ()
    accepted: bool = False
    hint: str = ""

    @property
    def refused(self) -> bool:
        return bool(self.findings)

    @property
    def signal_to_noise(self) -> float:
        """Rms over moves and axes of the integrated rotation over the noise's random walk (≈ 1 for noise)."""
        return float(np.sqrt(self.signal / (3 * self.residual.angles_deg.size)))

    def refusal(self) -> str:
        """The one-line refusal: what is wrong, the likely causes and the override."""
        return refusal_line(self.findings)

    def warning(self) -> str | None:
        """The warning of a calibration kept despite findings, or of a flagged residual; ``None`` otherwise."""
        if self.refused:
            return (f"gyro calibration kept (accept_gyro_fit) although it cannot be right: {'; '.join(self.findings)}; "
                    f"this {OVERRIDE_ASSUMES}")
        if self.residual.flagged:
            hint = f"; {self.hint}" if self.hint else ""
            point = "" if self.residual.far_beyond else f"; {DIAGNOSE_POINTER}"
            return f"gyro: {self.residual.describe()}{hint}{point}"
        return None

    def note(self) -> str:
        """The report's line on the tests."""
        line = (f"fit check: {self.residual.describe()}; moves' rotation {self.signal_to_noise:.3g}× the noise's "
                "random walk")
        if self.refused:
            line += f"; KEPT DESPITE: {'; '.join(self.findings)} (accept_gyro_fit)"
        return line

    def to_dict(self) -> dict[str, Any]:
        return {"residual": self.residual.to_dict(), "signal_to_noise": self.signal_to_noise,
                "findings": list(self.findings), "refused": self.refused, "accepted": self.accepted,
                "warning": self.warning()}


def check_gyro_fit(
    residual: ResidualTest,
    moves: MoveSet,
    w: NDArray,
    Tg: NDArray,
    units: str,
    rad_per_unit: float | None,
    accepted: bool = False,
    determined: bool = True,
    hint: str = "",
) -> GyroFitCheck:
    """Run the four tests on a fitted gyro calibration (module docstring).

    Parameters
    ----------
    residual : ResidualTest
        Test 1, with the fit's residual angles and budget.
    moves : MoveSet
    w : ndarray, shape (N, 3)
        Bias-free raw rates of the steps.
    Tg : ndarray, shape (3, 3)
        The fitted ``T_g``.
    units : str
        The gyro units.
    rad_per_unit : float or None
        Their nominal scale (``None`` for counts).
    accepted : bool
        The caller keeps the calibration whatever the findings.
    determined : bool
        ``T_g`` is determined by the moves; without (degenerate moves allowed) its axes and
        scales are partly arbitrary and tests 3-4 are skipped.
    hint : str
        What to try when the residual is flagged.
    """
    S, level = signal_to_noise(moves, w)
    findings: list[str] = []
    unseen = unseen_moves_finding(moves, S, level)
    if unseen is not None:
        findings.append(unseen)
    if residual.refused:
        findings.append(residual.describe())
    if determined:
        findings += axis_findings(Tg)
        findings += scale_findings(Tg, units, rad_per_unit)
    return GyroFitCheck(residual, S, level, tuple(findings), accepted, hint)
