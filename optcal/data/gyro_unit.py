"""The gyro's unit: radians per second per unit, from the unit the file or the user states, the moves' scale
(:mod:`optcal.data.move_scale`), or the convention beside the accelerometer's unit, and the decision in words.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.core.units import RAD_PER_UNIT
from optcal.data import rest_model as rm
from optcal.data.move_scale import (MAX_MOVE_S, MAX_UNEXPLAINED_TURN, MIN_MOVE_TURN_RAD, MIN_SCALE_MOVES,
                                    ScaleEvidence)
from optcal.data.quantiles import np_median, np_quantile
from optcal.data.recording import Recording
from optcal.data.rest_model import UNIT_RATE_QUANTILE


#: A measured scale names a unit when it lies within this factor of the unit's (rad/s, deg/s): the fixed-axis
#: approximation of a hand's move and the bias err by tens of percent, the two units differ 57-fold.
UNIT_MATCH_FACTOR: float = 2.0


def decide_gyro_scale(rec: Recording, measured: ScaleEvidence | None, fallback: float | None) -> tuple[float | None, str]:
    """The gyro's radians per second per unit, and the decision in words (printed by ``optcal segment``).

    A unit the file or the user states (``--gyro-units``) is taken, and the moves' scale said beside it when it
    disagrees by more than :data:`UNIT_MATCH_FACTOR`; a unit the names do not say is the one whose scale the moves'
    (:func:`scale_from_moves`) lies within :data:`UNIT_MATCH_FACTOR` of, else the moves' scale itself (counts, or
    a unit of its own); without moves, ``fallback`` (the convention of the accelerometer's unit, or None for counts).
    """
    flag = "--gyro-units to override"
    if rec.gyro_units in RAD_PER_UNIT:
        stated = RAD_PER_UNIT[rec.gyro_units]
        note = ""
        if measured is not None and abs(np.log(measured.rad_per_unit / stated)) > np.log(UNIT_MATCH_FACTOR):
            note = (f"; the moves say {measured.rad_per_unit:.4g} rad/s per unit ({measured.moves} moves): check the "
                    "columns' unit")
        return stated, f"{rec.gyro_units} as stated{note}"
    if measured is None:
        none = (f"no moves measure its scale (fewer than {MIN_SCALE_MOVES} turning gravity by "
                f"{np.degrees(MIN_MOVE_TURN_RAD):g}° within {MAX_MOVE_S:g} s, or their turn left more than "
                f"{MAX_UNEXPLAINED_TURN:.0%} unexplained)")
        if fallback is None:
            return None, f"{rec.gyro_units or 'unit unstated'}: {none}; {flag}"
        unit = "rad/s" if fallback == RAD_PER_UNIT["rad/s"] else "deg/s"
        return fallback, f"{unit} by the convention beside {rec.units}: {none}; {flag}"
    evidence = (f"the rate integral across {measured.moves} moves against the accelerometer's turn: "
                f"{measured.rad_per_unit:.4g} rad/s per unit, {measured.rms_deg:.2g}° rms")
    if rec.gyro_units is None:
        for unit in ("rad/s", "deg/s"):
            if abs(np.log(measured.rad_per_unit / RAD_PER_UNIT[unit])) <= np.log(UNIT_MATCH_FACTOR):
                return RAD_PER_UNIT[unit], f"{unit} from {evidence} ({flag})"
    per_dps = RAD_PER_UNIT["deg/s"] / measured.rad_per_unit
    unit = rec.gyro_units or ("counts" if rec.units == "counts" else "a unit of its own")
    return measured.rad_per_unit, f"{unit}, {per_dps:.4g} per °/s from {evidence} ({flag})"


def gyro_rad_per_unit(rec: Recording, gyro: NDArray[np.float64] | None, bias: NDArray[np.float64] | None,
                       blocks: rm.Blocks) -> float | None:
    """Radians per second per gyro unit, for a gyro whose unit the file does not state.

    The moves say it: gravity's direction in the sensor turns no faster than the sensor, so between
    consecutive blocks the accelerometer's turn rate |Δĝ|/Δt is at most the gyro's rate; at the fast moves
    (the :data:`UNIT_RATE_QUANTILE` quantile of both) the gyro reads 1-3 times the accelerometer's turn rate
    in rad/s and 57 times more in °/s.  A ratio above √57.3 (half-way on the log scale) says °/s.  A recording
    that never turns (its accelerometer's fast quantile within its noise) keeps the convention of the
    accelerometer's units: rad/s beside m/s² (ROS's ``sensor_msgs/Imu``), °/s beside g (datasheets).
    ``None`` for counts (their scale is the sensor's).
    """
    if gyro is None:
        return None
    if rec.gyro_units in RAD_PER_UNIT:
        return RAD_PER_UNIT[rec.gyro_units]
    if rec.gyro_units is not None or bias is None or blocks.gmean is None or rec.units == "counts":
        return None  # counts, or beside an accelerometer in counts: the scale is the sensor's
    u = blocks.mean / np.linalg.norm(blocks.mean, axis=1, keepdims=True)
    dt = np.diff(blocks.t_mid)
    ok = blocks.joined[1:] & (dt > 0)
    if ok.sum() >= 2:
        turn = np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0))[ok] / dt[ok]
        # the accelerometer's turn rate that its noise alone gives: two block means' noise over the block step
        noise = np.sqrt(2.0 * np_median(blocks.var.sum(axis=1) / blocks.n)) / np_median(np.linalg.norm(blocks.mean, axis=1))
        acc_fast = np_quantile(turn, UNIT_RATE_QUANTILE)
        if acc_fast > 3.0 * noise / float(np_median(dt)):
            gyro_fast = np_quantile(np.linalg.norm(blocks.gmean - bias, axis=1), UNIT_RATE_QUANTILE)
            ratio = gyro_fast / acc_fast
            return RAD_PER_UNIT["deg/s"] if ratio > np.sqrt(1.0 / RAD_PER_UNIT["deg/s"]) else RAD_PER_UNIT["rad/s"]
    return RAD_PER_UNIT["rad/s"] if rec.units == "m/s^2" else RAD_PER_UNIT["deg/s"]
