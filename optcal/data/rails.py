"""Saturation rails: samples of a sensor held at the end of its range, the accelerometer's and the gyro's.

A converter that clips holds its output at its full scale while the true signal is beyond it: the same value,
reached exactly by several samples, the same magnitude on every axis and in both directions.  An unclipped
signal passes its extreme once and never exactly on another axis.  :func:`rail_samples` finds such rails in a
block of samples; :func:`gyro_rail` applies it to a gyro with the gyro's own bound (a rail lies beyond any rate
a rest reads, :data:`~optcal.data.rest_model.MAX_GYRO_BIAS_RAD_S`, in the gyro's units as stated or as the most
units it can be in, as the rest bounds take it, :func:`gyro_bias_bound`).

A gyro held at a rail integrates less than the turn it missed: the move's angle is wrong by the part of the rate
above the rail, whatever the calibration, so a move holding one is left out of the gyro's fit and diagnosis
(:mod:`optcal.families.gyro.moves`), and a sample at one is no rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.units import RAD_PER_UNIT
from optcal.data.quantiles import np_column_medians
from optcal.data.quantisation import smallest_step
from optcal.data.rest_model import MAX_GYRO_BIAS_RAD_S, gyro_unit_bound
from optcal.data.units import UNSIGNED_16_MIDSCALE, around_midscale, in_unsigned_16_range

#: An axis's extreme value reached by this many samples marks a saturation rail.
SATURATION_MIN_COUNT: int = 2
#: Full-scale limits of integer converters: a sample at one of these is saturated.
INTEGER_RAILS: tuple[tuple[float, float], ...] = ((-32768.0, 32767.0), (0.0, 65535.0))
#: Consecutive samples a gyro's rail holds at least.  A smooth peak of curvature ``c`` (converter steps per sample²)
#: stays within one step of its top for ``√(8/c)`` samples: about 2 for a hand's move read by a 16-bit converter at
#: 100 Hz (the Xsens log's fastest peak, +31717 counts, is read twice), so a peak is read by at most 2 equal samples
#: there, while a clipped rate holds the full scale as long as the turn exceeds it.  Logs at several hundred Hz or
#: more can hold a smooth peak longer: a longer run is then judged by its flanks' curvature (:func:`_held_beyond_a_peak`).
GYRO_RAIL_MIN_RUN: int = 3
#: Counts from the zero that a converter's full scale reaches at least: a 10-bit converter's half range (an
#: Arduino's analogRead of an analog gyro, about its mid-scale), the coarsest a gyro is read with; digital MEMS
#: gyros have 12 to 20 bits.  A stated full scale (``--gyro-range``) is taken to be the largest reading only when
#: that reading reaches this far (in a still log it is a rest's, a few counts from the bias).
MIN_FULL_SCALE_CODES: int = 2**9 - 1
#: Samples, evenly spaced over the recording, whose column medians stand for the gyro's reading (mid-scale or not;
#: the rest reading a rail lies beyond): a median of 1024 samples lies within about 4 % of the readings' spread of
#: the whole file's, while a rail lies a MEMS gyro's largest bias (75 °/s) beyond it; a fixed number, so that the
#: reading takes no second statistic of the whole recording.
MEDIAN_SAMPLES: int = 1024


#: Values of a column looked at first by :func:`_whole_numbers` (evenly strided): one that is not a whole number
#: answers for the column without a temporary of its length (35 MB, 10-30 ms with its page faults, on an axis of
#: a 12-hour log in g); the answer is the same as the whole column's either way.
WHOLE_NUMBER_PROBE: int = 1000


def _whole_numbers(c: NDArray[np.float64]) -> bool:
    """Whether every value of ``c`` is a whole number (``c == round(c)``), an evenly strided sample of
    :data:`WHOLE_NUMBER_PROBE` values looked at first."""
    probe = c[:: max(1, c.size // WHOLE_NUMBER_PROBE)]
    if not bool(np.all(probe == np.round(probe))):
        return False
    return bool(np.all(c == np.round(c)))


def rail_samples(
    x: NDArray[np.float64],
    usable: NDArray[np.bool_],
    zero: ArrayLike,
    min_distance: float,
    flagged: NDArray[np.bool_] | None = None,
    about: ArrayLike = (0.0, 0.0, 0.0),
    min_run: int = 1,
    centre: ArrayLike | None = None,
    levels: list[float] | None = None,
    outward: bool = False,
) -> NDArray[np.bool_]:
    """Samples with an axis at a saturation rail.

    A rail is an extreme value (minimum or maximum of an axis over the usable samples) whose magnitude about
    ``about`` at least :data:`SATURATION_MIN_COUNT` samples reach exactly on any axis (a clipped signal keeps
    hitting the same full scale, the same on every axis and in both directions; an unclipped one does not) and
    which lies at least ``min_distance`` from the axis's ``zero`` (beyond anything the sensor reads at rest, so
    that the extreme of a coarsely quantised rest is never taken for a rail); or a full-scale value of a 16-bit
    converter (:data:`INTEGER_RAILS`) reached by integer-valued data.  ``flagged`` adds the file's own
    saturation flags (ULog clip counters).

    Parameters
    ----------
    x : ndarray, shape (n, 3)
        The samples, raw units.
    usable : ndarray of bool, shape (n,)
        Samples the extremes are taken over (the others are never flagged, except by ``flagged``).
    zero : array_like, shape (3,)
        Each axis's reading at rest (an accelerometer's nominal offset, a gyro's zero).
    min_distance : float
        Least distance of a rail from ``zero``, raw units.
    flagged : ndarray of bool, shape (n,), optional
        The file's own saturation flags.
    about : array_like, shape (3,)
        Each axis's value about which magnitudes are matched across axes and directions.
    min_run : int
        Consecutive samples at the level, on one axis at least, that a rail holds (1: any).
    centre : array_like, shape (3,), optional
        A second reading the rail also lies ``min_distance`` from (a gyro's median reading: a level the sensor
        mostly reads is a rest's, not a rail).
    levels : list, optional
        Filled with the magnitudes (about ``about``) of the rails found.
    outward : bool
        Take only a maximum above ``zero`` or a minimum below it (a converter's full scale lies beyond its zero on
        the extreme's side): for a sensor whose readings may all lie on one side of its zero (a magnetometer's,
        offset by hard iron or failed), whose minimum there is no rail.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    sat = np.zeros(x.shape[0], dtype=bool) if flagged is None else np.asarray(flagged, bool).copy()
    if not usable.any():
        return sat
    every = bool(usable.all())  # then no copy of the samples: column by column below
    zero = np.asarray(zero, dtype=float)
    about = np.asarray(about, dtype=float)

    def usable_column(axis: int) -> NDArray[np.float64]:
        return x[:, axis] if every else x[usable, axis]

    integer = all(_whole_numbers(c) for c in map(usable_column, range(3)))
    for axis in range(3):
        column = usable_column(axis)
        for extreme in (column.min(), column.max()):
            if outward and (extreme - zero[axis]) * (1.0 if extreme == column.max() else -1.0) <= 0:
                # on the zero's other side from the converter's full scale at this end, or at the zero itself: an
                # unsigned converter's 0 (INTEGER_RAILS) read by a signed field's axis is a reading, not a rail
                # (a 2-axis compass logged with its third axis 0; a hard iron that puts an axis's minimum at 0 counts)
                continue
            if integer and any(extreme in rail for rail in INTEGER_RAILS):
                sat |= usable & (x[:, axis] == extreme)
                if levels is not None and float(abs(extreme - about[axis])) not in levels:
                    levels.append(float(abs(extreme - about[axis])))
            elif abs(extreme - zero[axis]) >= min_distance and (
                    centre is None or abs(extreme - np.asarray(centre, float)[axis]) >= min_distance):
                if min_run > 1 and _longest_run(usable & (x[:, axis] == extreme)) < min_run:
                    continue  # not held on its own axis (one pass: a smooth peak is read once or twice)
                if min_run > 1 and not _held_beyond_a_peak(x[:, axis], usable & (x[:, axis] == extreme),
                                                           1.0 if extreme == column.max() else -1.0, min_run):
                    continue  # each run as long as a smooth peak of its flanks' curvature holds (a fast log's)
                on = np.zeros(x.shape[0], dtype=bool)
                hits = longest = 0
                level = abs(extreme - about[axis])
                for k in range(3):  # the same magnitude reached on any axis
                    at = usable & (np.abs(x[:, k] - about[k]) == level)
                    hits += int(np.count_nonzero(at))
                    on |= at
                    if min_run > 1 and at.any():
                        longest = max(longest, _longest_run(at))
                if hits >= SATURATION_MIN_COUNT and (min_run <= 1 or longest >= min_run):
                    sat |= on
                    if levels is not None and float(level) not in levels:
                        levels.append(float(level))
    return sat


def _held_beyond_a_peak(column: NDArray[np.float64], flags: NDArray[np.bool_], sign: float, min_run: int) -> bool:
    """Whether a run of at least ``min_run`` samples at the level (``flags``) is longer than a smooth peak holds.

    A smooth peak ``x = E - c τ²/2`` (``c``: its curvature, per sample²) stays within one step ``q`` of its top for
    ``√(8q/c)`` samples, so its top is read by at most ``⌊√(8q/c)⌋ + 1`` equal samples; a rate clipped at a rail is
    held as long as the turn exceeds it, ``2√(2h/c)`` samples for a peak ``h`` above the rail, longer than that as
    soon as ``h`` passes one step.  ``c`` is taken on each flank of the run, from samples spaced by the run's length
    (``(x[i-1] - 2x[i-1-L] + x[i-1-2L]) / L²``: a noise of σ adds ``√6 σ / L²``, an eighteenth of σ for a run of 3,
    and the spacing follows the peak's width), the mean of the flanks found; a flank not concave (``c ≤ 0``: the
    clipped turn's rate rose and fell steeply about it) or none at all leaves the run a rail.  ``q``: the column's
    smallest step (:func:`~optcal.data.quantisation.smallest_step`), taken only when a run is that long.
    ``sign``: +1 for a maximum, -1 for a minimum.
    """
    at = np.flatnonzero(flags)
    if at.size < min_run:
        return False
    breaks = np.flatnonzero(np.diff(at) != 1)
    starts = at[np.concatenate(([0], breaks + 1))]
    ends = at[np.concatenate((breaks, [at.size - 1]))] + 1
    q: float | None = None
    n = column.size
    for i, j in zip(starts.tolist(), ends.tolist()):
        length = j - i
        if length < min_run:
            continue
        flanks = []
        if i - 1 - 2 * length >= 0:
            flanks.append(column[i - 1] - 2.0 * column[i - 1 - length] + column[i - 1 - 2 * length])
        if j + 2 * length < n:
            flanks.append(column[j] - 2.0 * column[j + length] + column[j + 2 * length])
        c = -sign * float(np.mean(flanks)) / length**2 if flanks else float("nan")
        if not np.isfinite(c) or c <= 0.0:
            return True
        if q is None:
            q = smallest_step(column)
        if not np.isfinite(q) or length > np.floor(np.sqrt(8.0 * q / c)) + 1:
            return True
    return False


def _longest_run(flags: NDArray[np.bool_]) -> int:
    """The longest run of consecutive True values (from their positions: the flags of a rail are few)."""
    at = np.flatnonzero(flags)
    if at.size < 2:
        return int(at.size)
    breaks = np.flatnonzero(np.diff(at) != 1)
    bounds = np.concatenate(([0], breaks + 1, [at.size]))
    return int(np.max(np.diff(bounds)))


def gyro_bias_bound(gyro_units: str | None, gyro: NDArray[np.float64],
                    medians: ArrayLike | None = None) -> tuple[NDArray[np.float64], float, str]:
    """The gyro's zero and the largest rate a rest reads on an axis, in the gyro's units, and how they were taken.

    The bound is :data:`~optcal.data.rest_model.MAX_GYRO_BIAS_RAD_S` (a MEMS gyro's largest bias) in the units as
    stated; otherwise in the most units the gyro can be in (:data:`~optcal.data.rest_model.MIN_RAD_S_PER_UNIT`:
    counts of a ±125 °/s 16-bit gyro for whole numbers, °/s for decimals), about zero, or about the unsigned
    16-bit mid-scale for unsigned counts whose ``medians`` (the rests' means, else the samples') lie around it.

    Parameters
    ----------
    gyro_units : str or None
        The units stated (by the file or ``--gyro-units``).
    gyro : ndarray, shape (n, 3)
    medians : array_like, optional
        Per-axis readings at rest (default: the samples' column medians).

    Returns
    -------
    zero : ndarray, shape (3,)
    limit : float
    unit : str
        How the units were taken, in words.
    """
    zero = np.zeros(3)
    head = gyro[: 4096]
    head = head[np.isfinite(head)]
    counts = gyro_units == "counts" or bool(head.size and np.all(head == np.round(head)))
    per_unit, unit = gyro_unit_bound(gyro_units, counts)
    if counts and gyro_units not in RAD_PER_UNIT:
        finite = gyro[np.all(np.isfinite(gyro), axis=1)]
        if finite.size:
            centre = np_column_medians(finite) if medians is None else np.asarray(medians, dtype=float)
            if in_unsigned_16_range(float(finite.min()), float(finite.max())) and around_midscale(centre):
                zero = np.full(3, UNSIGNED_16_MIDSCALE)
                unit += ", zero at the unsigned mid-scale"
    return zero, MAX_GYRO_BIAS_RAD_S / per_unit, unit


@dataclass(frozen=True)
class GyroRail:
    """The gyro samples at a saturation rail, and what was taken as one.

    Attributes
    ----------
    samples : ndarray of bool, shape (n,)
        Samples with a gyro axis at a rail (or flagged by the file).
    levels : tuple of float
        The rails found (their magnitude about the zero), the gyro's units.
    zero : ndarray, shape (3,)
        The zero the rails are measured from.
    limit : float
        The least distance from the zero a rail lies at (a rest's largest rate), the gyro's units.
    unit : str
        How the gyro's units were taken for the bound.
    """

    samples: NDArray[np.bool_]
    levels: tuple[float, ...]
    zero: NDArray[np.float64]
    limit: float
    unit: str

    def describe(self, gyro_units: str | None, kept: bool = False) -> str:
        """The rails in words (a warning of the reading)."""
        n = int(np.count_nonzero(self.samples))
        levels = ", ".join(f"±{v:.6g}" for v in self.levels) or "flagged by the file"
        # kept by --keep-gyro-rail, or by apply (which corrects every sample and never fits the gyro)
        what = ("kept: their readings are clipped, below the true rate (a move holding them integrates less than its "
                "turn)" if kept else
                "they enter no rest and the moves holding them are left out of the gyro's fit and diagnosis "
                "(--keep-gyro-rail keeps them)")
        return (f"the gyro is at its rail (saturated): {n} samples at {levels} {gyro_units or '(gyro units)'} from "
                f"its zero, beyond {self.limit:.4g}, the largest rate a rest reads ({np.degrees(MAX_GYRO_BIAS_RAD_S):g} "
                f"°/s in {self.unit}); {what}")


def gyro_rail(gyro: NDArray[np.float64], usable: NDArray[np.bool_], gyro_units: str | None,
              flagged: NDArray[np.bool_] | None = None, acc_units: str | None = None,
              full_scale_dps: float | None = None) -> GyroRail:
    """The gyro's saturation rails (:func:`rail_samples` with the gyro's bound).

    A rail lies beyond any rate a rest reads (:func:`gyro_bias_bound`) from the gyro's zero (and, when the unit is
    taken by the convention, from its median reading too: a °/s gyro's bias can lie beyond 1.3 °/s, and a level it
    reads most of the time may be its rests'), and holds :data:`GYRO_RAIL_MIN_RUN` consecutive samples.  Decimal samples whose unit nothing states are taken in the unit
    the convention puts beside the accelerometer's (rad/s beside m/s², else °/s, the larger bound), as the
    segmentation's gyro scale does when no move measures it; ``--gyro-units`` states it.

    Parameters
    ----------
    gyro : ndarray, shape (n, 3)
    usable : ndarray of bool, shape (n,)
    gyro_units : str or None
        The gyro's units as stated.
    flagged : ndarray of bool, shape (n,), optional
        The file's own gyro clip flags.
    acc_units : str, optional
        The accelerometer's units as decided (for the convention).
    full_scale_dps : float, optional
        The gyro's full scale, ±°/s, as stated (``--gyro-range``).  Where its unit is not known (counts, or decimals
        not stated), a rail lies at the full scale, so the largest reading (from the zero) of a file holding one is
        the full scale: a rest, reading at most 75 °/s, lies within 75/``full_scale_dps`` of it, a bound tighter
        than the finest gyro's (75 °/s in counts of a ±125 °/s 16-bit gyro: 19661) once the full scale passes
        125 °/s or the converter has fewer bits.  The rail must then lie that far from the gyro's median reading
        too (in a still log the largest reading is a rest's, and the median lies beside it).

    Notes
    -----
    A log sampled at several hundred Hz can hold a smooth peak for more than :data:`GYRO_RAIL_MIN_RUN` equal
    samples when its converter's step is coarse beside the peak's curvature; a run no longer than a smooth peak of
    its flanks' curvature holds within one step is no rail (:func:`_held_beyond_a_peak`).
    """
    ok = usable & np.all(np.isfinite(gyro), axis=1)
    rows = np.flatnonzero(ok)
    head = gyro[rows[: 4096]]  # whole numbers or not (as the rest bounds look)
    spaced = gyro[rows[:: max(1, -(-rows.size // MEDIAN_SAMPLES))]]
    units = gyro_units
    if units is None and acc_units == "m/s^2" and head.size and not bool(np.all(head == np.round(head))):
        units = "rad/s"  # the convention beside m/s^2 (optcal.data.static_stretches.decide_gyro_scale's fallback)
    zero, limit, unit = gyro_bias_bound(units, gyro if rows.size == gyro.shape[0] else gyro[rows], np_column_medians(spaced) if spaced.size else None)
    if units != gyro_units:
        unit = "rad/s by the convention beside m/s^2 (--gyro-units to override)"
    stated_range = False
    if full_scale_dps is not None and units not in RAD_PER_UNIT and rows.size and bool(np.all(head == np.round(head))):
        reach = float(np.max(np.abs(gyro[rows] - zero)))
        stated_range = reach >= MIN_FULL_SCALE_CODES  # else the largest reading is no converter's full scale
        if stated_range:
            limit = min(limit, np.degrees(MAX_GYRO_BIAS_RAD_S) / full_scale_dps * reach)
        unit += (f"; tightened by the full scale stated, ±{full_scale_dps:g} °/s (--gyro-range): a rest reads at most "
                 f"{np.degrees(MAX_GYRO_BIAS_RAD_S) / full_scale_dps:.3g} of the largest reading, {reach:.6g}"
                 if stated_range else
                 f"; the full scale stated (--gyro-range) not used: the largest reading, {reach:.6g} counts, is no "
                 f"converter's full scale (under {MIN_FULL_SCALE_CODES}, a 10-bit one's)")
    levels: list[float] = []
    sat = rail_samples(gyro, ok, zero, limit, flagged, about=zero, min_run=GYRO_RAIL_MIN_RUN, levels=levels,
                       centre=np_column_medians(spaced) if stated_range else None)
    if sat.any() and units != gyro_units:  # under the convention (a °/s gyro's bias can pass 1.3 °/s): a level the
        # gyro reads most of the time may be a rest's, and a rail lies beyond it too; in a unit stated or bounded, no
        # rest reads beyond the bound, and a spin held at the rail is no rest
        centre = np_column_medians(spaced)
        levels.clear()
        sat = rail_samples(gyro, ok, zero, limit, flagged, about=zero, min_run=GYRO_RAIL_MIN_RUN, centre=centre,
                           levels=levels)
    return GyroRail(sat, tuple(sorted(levels)), zero, float(limit), unit)


def clip_flags(d: dict[str, NDArray]) -> NDArray[np.bool_] | None:
    """Rows of a PX4 ULog sensor topic with a non-zero ``clip_counter`` on an axis (None: the topic has none)."""
    clip = [d[f"clip_counter[{k}]"] for k in range(3) if f"clip_counter[{k}]" in d]
    return np.any(np.column_stack(clip) > 0, axis=1) if clip else None
