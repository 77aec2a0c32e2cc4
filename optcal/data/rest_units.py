"""The accelerometer's units from where the physics holds: the stretches where it is quiet, |a| = 1 g there.

The units decision (:func:`optcal.data.units.decide_units`) reads the whole file's median |a|.  On a
recording that moves most of the time (a spinning, accelerating flight) that median is not 1 g: a
flight in m/s² whose median |a| is 54.5 reads as raw counts, and a user's ``--units m/s^2`` is
refused as contradicting it.  Two pieces of evidence are then taken where the norm does not settle it:

* the median |a| over the *quiet* blocks (their per-sample noise at the recording's floor, as the
  roles' rest statistics take them, :func:`optcal.data.evidence._rest_readings`): at rest the specific
  force is gravity alone, |a| = 1 g in the sensor's units;
* the share of the samples that are not whole numbers: a converter's raw counts always are.

Where the file has a gyro, a quiet block must be at rest for the gyro too (:func:`gyro_at_rest`): a steady spin
keeps the accelerometer's noise at its floor, but adds its centripetal acceleration to |a|.

The evidence is gathered only where the whole file's median leaves the unit open or says counts, so a
file the median already reads in g or m/s² is decided as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import ACC, GYRO
from optcal.data.evidence import (
    MIN_QUIET_BLOCKS,
    NOISE_FLOOR_QUANTILE,
    QUIET_FACTOR,
    ROLE_BLOCK_SAMPLES,
    Evidence,
    _block_statistics,
    _resolution,
    quiet_blocks,
)
from optcal.data.quantiles import column_medians, median, quantiles
from optcal.data.rest_model import MAX_BIAS_WANDER_RAD_S, gyro_unit_bound
from optcal.data.readers import Source
from optcal.data.units import (
    PLAUSIBLE_NORM,
    NominalConversion,
    UnitsDecision,
    nominal_conversion,
    normalise_units,
    units_and_nominal,
    units_from_norm,
)
from optcal.errors import InputError

#: Share of the samples with a fractional part from which the samples are not raw counts.  A
#: converter's counts are whole numbers on every sample (none has a fraction); a reading in g or m/s²
#: (counts times a scale such as 9.80665/16384) has one on practically every sample.  Half keeps a
#: few stray cells (a rounded export, a logger's averaged row) from making counts look physical, and
#: a physical reading that is whole only where it crosses an integer from counting as counts.
NON_INTEGER_FRACTION: float = 0.5


@dataclass(frozen=True)
class GyroRest:
    """Which blocks the gyro holds at rest: their mean rate within a MEMS gyro's bias wander of its rest reading.

    Attributes
    ----------
    at_rest : ndarray of bool, shape (nb,)
        Blocks whose mean rate is within :attr:`allowance` of :attr:`bias`.
    bias : ndarray, shape (3,)
        The rest reading, gyro units: the median of the block means among the slowest tenth of the quiet blocks
        (:data:`~optcal.data.evidence.NOISE_FLOOR_QUANTILE`; a turn only adds to the rate).
    allowance : float
        :data:`~optcal.data.rest_model.MAX_BIAS_WANDER_RAD_S` in the gyro's units, plus
        :data:`~optcal.data.evidence.QUIET_FACTOR` times a block mean's noise at the gyro's floor.
    unit : str
        How the units were taken: stated by the file, or bounded (:data:`~optcal.data.rest_model.MIN_RAD_S_PER_UNIT`).
    """

    at_rest: NDArray[np.bool_]
    bias: NDArray[np.float64]
    allowance: float
    unit: str


def gyro_at_rest(src: Source, ev: Evidence, quiet: NDArray[np.bool_], nb: int) -> GyroRest | None:
    """The blocks among ``quiet`` (the accelerometer's) that the gyro holds at rest; ``None`` without a gyro.

    A gyro at rest reads its bias, which moves between the rests of a session by at most
    :data:`~optcal.data.rest_model.MAX_BIAS_WANDER_RAD_S` (1 °/s); a block whose mean rate is further from the
    rest reading than that, plus its own noise, turns (a steady spin's noise stays at the floor, its rate does
    not).  The bound is taken in the gyro's units as the file states them (rad/s, °/s), else as the largest it
    can be in units (:data:`~optcal.data.rest_model.MIN_RAD_S_PER_UNIT`: as °/s for samples with decimals, as counts of a ±125 °/s 16-bit
    gyro for whole numbers), so only a turn faster than 1 °/s in any unit the samples can be in is set aside.
    """
    if not src.has(*GYRO):
        return None
    cols = tuple(src.column(c) if bool(ev.usable.all()) else src.column(c)[ev.usable] for c in GYRO)
    if src.gyro_unhealthy is not None:  # the samples the log marks unhealthy hold no evidence: their blocks go
        sick = src.gyro_unhealthy if bool(ev.usable.all()) else src.gyro_unhealthy[ev.usable]
        cols = tuple(np.where(sick, np.nan, c) for c in cols)
    means, std = _block_statistics(cols, nb)
    finite = quiet & np.isfinite(std) & np.all(np.isfinite(means), axis=1)
    if np.count_nonzero(finite) < MIN_QUIET_BLOCKS:
        return None
    rad_per_unit, unit = gyro_unit_bound(src.gyro_units, _resolution(cols) > 0)
    rate = np.linalg.norm(means, axis=1)
    slow = finite & (rate <= quantiles(rate[finite], [NOISE_FLOOR_QUANTILE])[0])
    bias = column_medians(means[slow])
    floor = quantiles(std[finite], [NOISE_FLOOR_QUANTILE])[0]
    # a block mean's noise: the per-sample floor over √w samples on each of 3 axes
    allowance = MAX_BIAS_WANDER_RAD_S / rad_per_unit + QUIET_FACTOR * floor * np.sqrt(3.0 / ROLE_BLOCK_SAMPLES)
    return GyroRest(finite & (np.linalg.norm(means - bias, axis=1) <= allowance), bias, float(allowance), unit)


@dataclass(frozen=True)
class RestNorm:
    """The accelerometer's |a| where it is quiet, and how many of its samples are whole numbers.

    Attributes
    ----------
    norm : float
        Median |a| of the quiet blocks' means, raw units (NaN with fewer than
        :data:`~optcal.data.evidence.MIN_QUIET_BLOCKS` quiet blocks).
    quiet_blocks, blocks : int
        Blocks of :data:`~optcal.data.evidence.ROLE_BLOCK_SAMPLES` usable rows at the noise floor (and at rest for
        the gyro, where there is one), of all.
    non_integer, samples : int
        Usable axis samples with a fractional part, of all.
    turning : int
        Blocks quiet for the accelerometer that the gyro says turn (:func:`gyro_at_rest`), set aside.
    gyro : GyroRest or None
        The gyro's rest test, where the file has a gyro.
    """

    norm: float
    quiet_blocks: int
    blocks: int
    non_integer: int
    samples: int
    turning: int = 0
    gyro: GyroRest | None = None

    @property
    def non_integer_fraction(self) -> float:
        """Share of the samples that are not whole numbers."""
        return self.non_integer / self.samples if self.samples else 0.0

    @property
    def not_counts(self) -> bool:
        """Too many samples with a fraction for raw counts (:data:`NON_INTEGER_FRACTION`)."""
        return self.non_integer_fraction >= NON_INTEGER_FRACTION

    def describe(self) -> str:
        """The evidence in words, for a decision's reason."""
        spin = ""
        if self.gyro is not None:
            spin = (f"; {self.turning} more quiet for the accelerometer set aside as turning: their gyro mean over "
                    f"{self.gyro.allowance:.3g} from its rest reading, a gyro's 1 °/s bias wander (units "
                    f"{self.gyro.unit})")
        return (f"the quiet stretches' median |a| = {self.norm:.4g} ({self.quiet_blocks} of {self.blocks} blocks "
                f"of {ROLE_BLOCK_SAMPLES} samples at the noise floor{spin}; at rest |a| = 1 g), "
                f"{100 * self.non_integer_fraction:.0f} % of the samples not whole numbers (raw counts all are)")


def rest_norm(src: Source, ev: Evidence) -> RestNorm:
    """The accelerometer's median |a| over its quiet blocks and its count of non-integer samples (module docstring)."""
    cols = tuple(src.column(c) if bool(ev.usable.all()) else src.column(c)[ev.usable] for c in ACC)
    samples = 3 * int(cols[0].size)
    non_integer = sum(int(np.count_nonzero(c != np.round(c))) for c in cols)
    nb = int(cols[0].size) // ROLE_BLOCK_SAMPLES
    if nb < MIN_QUIET_BLOCKS:
        return RestNorm(float("nan"), 0, nb, non_integer, samples)
    means, std = _block_statistics(cols, nb)
    quiet = quiet_blocks([(means, std)], nb)  # the same quiet blocks as the roles' rest statistics
    if quiet is None:
        return RestNorm(float("nan"), 0, nb, non_integer, samples)
    gyro = gyro_at_rest(src, ev, quiet, nb)
    turning = 0
    if gyro is not None:  # a steady spin is quiet for the accelerometer, its |a| not 1 g
        turning = int(np.count_nonzero(quiet & ~gyro.at_rest))
        quiet = quiet & gyro.at_rest
    n_quiet = int(np.count_nonzero(quiet))
    if n_quiet < MIN_QUIET_BLOCKS:
        return RestNorm(float("nan"), n_quiet, nb, non_integer, samples, turning, gyro)
    return RestNorm(median(np.linalg.norm(means[quiet], axis=1)), n_quiet, nb, non_integer, samples, turning, gyro)


def units_and_nominal_at_rest(
    src: Source, ev: Evidence, requested: str | None
) -> tuple[UnitsDecision, NominalConversion]:
    """The units decision and its nominal conversion, the quiet stretches heard where the whole file's median is not 1 g.

    As :func:`optcal.data.units.units_and_nominal` on the evidence's statistics, except where the
    whole file's median |a| says counts or nothing and no unit is stated by the file:

    * a unit decided by the data: g or m/s² when the quiet stretches' |a| lies in its range and the
      samples are not counts (:attr:`RestNorm.not_counts`);
    * a unit given with ``--units``: kept, not refused, when the quiet stretches' |a| lies in its range.

    Raises
    ------
    InputError
        As :func:`~optcal.data.units.units_and_nominal`, the quiet stretches' evidence added to the message.
    """
    hint = src.units_hint
    try:
        found, nominal = units_and_nominal(requested, hint, src.units_reason, norm=ev.median_norm,
                                           extremes=ev.extremes, medians=ev.medians, midscale_norm=ev.midscale_norm)
    except InputError as exc:
        if hint is not None and requested is None:
            raise
        error: InputError | None = exc
    else:
        if requested is not None or hint is not None or found.units != "counts":
            return found, nominal
        error = None
        # counts by the median: heard only when the samples are not whole numbers (a head of them, as the roles do)
        if _resolution(tuple(src.column(c) for c in ACC)) > 0:
            return found, nominal
    rest = rest_norm(src, ev)
    moving = f"the whole file's median |a| {ev.median_norm:.4g}: the sensor moves"
    if requested is not None:
        units = normalise_units(requested)
        lo, hi = PLAUSIBLE_NORM[units]
        if np.isfinite(rest.norm) and lo <= rest.norm <= hi:
            return (UnitsDecision(units, f"given with --units; {rest.describe()} agrees ({moving})"),
                    nominal_conversion(units, None))
    else:
        by_rest = units_from_norm(rest.norm) if np.isfinite(rest.norm) else None
        if by_rest is not None and by_rest.units != "counts" and rest.not_counts:
            return (UnitsDecision(by_rest.units, f"{rest.describe()}: {by_rest.units} ({moving})"),
                    nominal_conversion(by_rest.units, None))
    if error is not None:
        if np.isfinite(rest.norm):
            raise InputError(f"{error} ({rest.describe()})") from error
        raise error
    return found, nominal
