"""The gyroscope diagnosis's check of the accelerometer's frame: do the moves disagree with the frame the six-face
rests gave the accelerometer?

Rests on the six faces, each within a degree or so of an axis, see a non-orthogonality ``ρ`` of the accelerometer
only through its product with their tilt (``|a|`` changes by about ``ρ · tilt``): with a pose noise of a milligravity
it is left to that noise (its standard error some degrees).  A move between two poses sees it at first order: the
gravity direction at each end turns by up to ``ρ``, and the gyro's prediction (Tedaldi 2014, eq. 13-14) misses by as
much.  No gyro candidate of the selection explains that misfit.

So, when the moves' misfit leaves the simulated band and the selection names nothing or leaves moves outside it,
the accelerometer's frame is refitted jointly with the moves (:func:`optcal.families.gyro.estimator.calibrate_gyro`
with ``accelerometer="joint"``, the joint fit of ``optcal calibrate --imu --joint``), and judged by

(a) the held-out moves: the moves in ``k`` interleaved folds; for each fold the paper's model with the accelerometer
    fixed and the joint model are both fitted to the other folds' moves (every rest kept: the rests' norms are the
    accelerometer's data), each held-out move's gravity-prediction angle under the two is paired, and their mean
    gain (:func:`~optcal.applications.diagnosis.gyro_heldout.paired_gain`, its standard error from the moves' own
    scatter) must exceed the critical t of the other gyro candidates' held-out moves;
(b) what it costs the rests: the joint frame's weighted residual sum of squares of the rests' norms against the
    six-face fit's (their minimum), by ``F = (RSS₁ − RSS₀)/q / (RSS₀/ν)`` with ``q`` the accelerometer's nine
    parameters and ``ν`` the six-face fit's degrees of freedom (``s²`` from the rests' own residual: their pose
    noise, not the white noise of an ideal sensor); the cost is within what their pose noise allows when ``F`` is
    below its upper quantile at the diagnosis's level.

The frame is named as the moves' cause only when both hold.  The check refits 2k + 1 IMU models (about a second of
CPU each on a 30-minute recording); ``--no-gyro-frame-check`` skips it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.gyro_heldout import paired_gain
from optcal.core import quantiles
from optcal.core.stats import rms
from optcal.data.units import GyroUnitsDecision
from optcal.errors import IdentifiabilityError, InputError
from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro
from optcal.families.gyro.moves import MoveSet
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows

#: The accelerometer's parameters the joint fit re-estimates (six of ``T_a``'s lower triangle, three offsets): the
#: numerator's degrees of freedom of the rests' F.
ACCELEROMETER_PARAMETERS: int = 9
#: The remedy printed with a relevant frame.
REMEDY: str = "optcal calibrate --imu --joint"


def moves_subset(moves: MoveSet, keep: NDArray[np.bool_]) -> MoveSet:
    """The moves ``keep`` of ``moves`` with every rest (their steps, first-step flags and last steps re-indexed)."""
    ends = np.concatenate([[0], moves.last_step + 1])
    steps = np.concatenate([np.arange(ends[i], ends[i + 1]) for i in np.flatnonzero(keep)])
    lengths = (ends[1:] - ends[:-1])[keep]
    first = np.zeros(steps.size, dtype=bool)
    first[np.concatenate([[0], np.cumsum(lengths)[:-1]])] = True

    def cut(a: NDArray[Any] | None) -> Any:
        return a[steps] if a is not None and a.size == moves.dt.size else a

    return replace(moves, move_from=moves.move_from[keep], move_to=moves.move_to[keep],
                   gyro_pairs=moves.gyro_pairs[steps], acc_mid=moves.acc_mid[steps], dt=moves.dt[steps],
                   first_step=first, last_step=np.cumsum(lengths) - 1,
                   bridge_bound=moves.bridge_bound[keep] if moves.bridge_bound.size == keep.size else moves.bridge_bound,
                   t_mid=cut(moves.t_mid), temp_mid=cut(moves.temp_mid))


def prediction_angles(moves: MoveSet, cal: Any) -> NDArray[np.float64]:
    """Each move's gravity-prediction angle (degrees) under an IMU calibration, its own accelerometer giving the
    gravity directions (as :func:`optcal.families.gyro.check.gravity_prediction_check`)."""
    u = unit_rows(cal.correct(moves.acc_means))
    predictor = GravityPredictor(moves.first_step, moves.last_step)
    return angles_deg(predictor(cal.correct_gyro(moves.gyro_mid(), moves.acc_mid), moves.dt, u[moves.move_from]),
                      u[moves.move_to])


def _frame_deg(acc: Any) -> dict[str, float]:
    p = acc.model.physical()
    return {"rho": math.degrees(p.rho), "phi": math.degrees(p.phi), "lambda": math.degrees(p.lam)}


def _rests_mg(acc: Any) -> float:
    return rms(acc.residuals) * 1e3  # |a| − 1 in g: milligravity


@dataclass(frozen=True)
class FrameCheck:
    """The accelerometer frame check's result (:func:`frame_check`); ``to_dict`` is the JSON's
    ``gyroscope.accelerometer_frame``."""

    run: bool
    reason: str
    relevant: bool = False
    details: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"run": self.run, "relevant": self.relevant, "reason": self.reason, **(self.details or {})}

    def line(self) -> str:
        """The report's one line."""
        if not self.run or self.details is None:
            return f"  accelerometer frame against the moves: not checked ({self.reason})"
        d = self.details
        change = ", ".join(f"{k} {d['frame_fixed_deg'][k]:+.2f}° → {d['frame_joint_deg'][k]:+.2f}°"
                           for k in ("rho", "phi", "lambda"))
        head = ("the moves disagree with the accelerometer's frame" if self.relevant
                else "the accelerometer's frame refitted to the moves: not named")
        return (f"  {head}: non-orthogonality {change}; moves {d['moves_rms_deg']['fixed']:.3f}° → "
                f"{d['moves_rms_deg']['joint']:.3f}° rms (held-out gain {d['heldout_gain_deg']:+.3f} ± "
                f"{d['heldout_se_deg']:.3f}° per move, t {d['heldout_t']:.2f} against {d['heldout_critical_t']:.2f}); "
                f"rests {d['rests_rms_mg']['fixed']:.3f} → {d['rests_rms_mg']['joint']:.3f} mg (F {d['rests_f']:.2f} "
                f"against {d['rests_critical_f']:.2f})" + (f"; remedy: {REMEDY}" if self.relevant else ""))


def frame_check(moves: MoveSet, accelerometer: Any, outside: bool, alpha: float, folds: list[NDArray[np.bool_]],
                critical_t: float, solver: str | None = None) -> FrameCheck:
    """Refit the accelerometer's frame jointly with the moves and judge it (module docstring).

    Parameters
    ----------
    moves : MoveSet
        The recording's moves.
    accelerometer : CalibrationResult
        The six-face (rests') accelerometer calibration.
    outside : bool
        Moves are outside the band under the diagnosis's final model (the check runs only then).
    alpha : float
        Level of the rests' F.
    folds : list of ndarray of bool
        The held-out moves of each fold: the gyro candidates' folds
        (:func:`~optcal.applications.diagnosis.gyro_heldout.interleaved_folds`).
    critical_t : float
        The held-out moves' paired t the gain must exceed (the gyro candidates').
    solver : str, optional
        The NLP solver of the fits.

    Returns
    -------
    FrameCheck
    """
    if not outside:
        return FrameCheck(False, "every move within the band under the diagnosis's model")
    units = GyroUnitsDecision("counts", "the frame check: the scale as fitted")  # the fits' start, not their result
    fixed = GyroSettings(accept_gyro_fit=True, solver=solver)
    joint = replace(fixed, accelerometer="joint")
    try:
        full_fixed = calibrate_gyro(moves, accelerometer, units, fixed)
        full_joint = calibrate_gyro(moves, accelerometer, units, joint)
        angle_fixed = np.zeros(moves.n_moves)
        angle_joint = np.zeros(moves.n_moves)
        for test in folds:
            train = moves_subset(moves, ~test)
            held = moves_subset(moves, test)
            angle_fixed[test] = prediction_angles(held, calibrate_gyro(train, accelerometer, units, fixed))
            angle_joint[test] = prediction_angles(held, calibrate_gyro(train, accelerometer, units, joint))
    except (IdentifiabilityError, InputError) as exc:  # a fold's moves that turn about too few axes, or not at all
        return FrameCheck(False, f"a fold's moves do not determine the fit ({exc})")
    # paired on the angles, as the gyro candidates (gyro_diagnosis: a move's angle is Rayleigh, its square not)
    gain, se, t = paired_gain(angle_fixed - angle_joint)
    acc0, acc1 = accelerometer, full_joint.accelerometer
    nu = int(acc0.dof)
    rss0, rss1 = float(acc0.chisqr), float(acc1.chisqr)
    if nu > 0 and rss0 > 0:
        f = (rss1 - rss0) / ACCELEROMETER_PARAMETERS / (rss0 / nu)
        f_critical = quantiles.f_isf(alpha, ACCELEROMETER_PARAMETERS, nu)
    else:  # no scatter left to judge the cost by: the rests cannot allow it
        f, f_critical = math.inf, 0.0
    relevant = bool(t > critical_t and f < f_critical)
    details = {
        "frame_fixed_deg": _frame_deg(acc0), "frame_joint_deg": _frame_deg(acc1),
        "moves_rms_deg": {"fixed": rms(full_fixed.angles_after_deg), "joint": rms(full_joint.angles_after_deg)},
        "heldout_rms_deg": {"fixed": rms(angle_fixed), "joint": rms(angle_joint)},
        "heldout_gain_deg": gain, "heldout_se_deg": se, "heldout_t": t, "heldout_critical_t": critical_t,
        "rests_rms_mg": {"fixed": _rests_mg(acc0), "joint": _rests_mg(acc1)},
        "rests_rss": {"fixed": rss0, "joint": rss1}, "rests_dof": nu, "rests_f": f, "rests_critical_f": f_critical,
        "remedy": REMEDY if relevant else None,
    }
    reason = ("the held-out moves gain beyond their standard errors and the rests' cost is within their pose noise"
              if relevant else
              ("the held-out moves do not gain beyond their standard errors" if t <= critical_t else "")
              + ("; " if t <= critical_t and f >= f_critical else "")
              + ("the rests' cost exceeds what their pose noise allows" if f >= f_critical else ""))
    return FrameCheck(True, reason, relevant, details)
