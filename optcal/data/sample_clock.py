"""A sample clock read as a pose table's time: the evidence that a table's rows are a rest sampled, not poses.

:func:`optcal.data.decisions.decide` reads a file whose time column, its unit unstated, puts the rows at least
half a second apart, and whose rows differ as distinct poses do, as a pose table (its time in seconds, as
documented).  An Arduino's ``millis()`` (a counter since power-on, about 19 Hz) is read that way as poses "52 s
apart".  The model here tells the two apart: a pose table holds one row per pose, its consecutive rows poses a
turn apart (more than :data:`~optcal.data.decisions.POSE_STEP_RATIO` of 1 g, the rule that reads a table as
poses); a recording samples each rest again and again, its consecutive samples within a pose step of each other
(the sensor's noise, a slow sway).  Rows that stay so for the static detection's shortest dwell
(:data:`~optcal.data.decisions.MIN_POSE_SPACING_S`) at a rate the time column gives are a rest sampled.

And the pauses of a recording (:func:`pauses`): a step between stamps longer than a host ever holds samples is
a pause (a logger stopped, sessions joined), not the wait between a host's bursts; bursty stamps are spread
evenly within the sections between pauses (:func:`spread_evenly`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np

from optcal.data.columns import ACC
from optcal.data.evidence import Evidence, TimeEvidence
from optcal.data.readers import Source


class ClockLimits(NamedTuple):
    """The kind decision's limits these tests read by (:mod:`optcal.data.decisions` gives its own)."""

    time_units: dict[str, float]  # to seconds
    plausible_rate_hz: tuple[float, float]
    pose_step_ratio: float  # consecutive rows of a pose table differ by more, in g
    min_dwell_s: float  # the shortest rest
    max_step_g: Callable[[float], float]  # the largest median change between a recording's rows at a rate


class Reading(Protocol):
    """A time column read in one unit (:class:`optcal.data.decisions._TimeReading`)."""

    @property
    def stated(self) -> bool: ...  # by the column's name, --time-unit or a header's rate

    @property
    def why(self) -> str: ...

    @property
    def spacing_s(self) -> float: ...  # between rows, seconds

    @property
    def rate_hz(self) -> float: ...


def held_rows(src: Source, ev: Evidence, one_g: float, rate_hz: float, lim: ClockLimits) -> tuple[int, int] | None:
    """The longest run of rows that hold one pose for a rest's length at ``rate_hz``: data rows ``(first, last)``
    (1-based), else None.

    A run of rows each within a pose step of the one before, lasting the shortest dwell at ``rate_hz`` (at least
    3 rows): no table of distinct poses writes one pose that many times in a row.
    """
    need = max(3, int(np.ceil(lim.min_dwell_s * rate_hz)))
    rows = np.flatnonzero(ev.usable)
    if rows.size < need or not one_g > 0:
        return None
    acc = np.column_stack([src.column(c)[rows] for c in ACC])
    held = np.linalg.norm(np.diff(acc, axis=0), axis=1) <= lim.pose_step_ratio * one_g  # step k: rows k and k + 1
    edges = np.flatnonzero(np.diff(np.r_[0, held.astype(np.int8), 0]))
    if not edges.size:
        return None
    starts, stops = edges[0::2], edges[1::2]  # runs of held steps [start, stop): rows start … stop
    k = int(np.argmax(stops - starts))
    if stops[k] - starts[k] + 1 < need:
        return None
    return int(rows[starts[k]]) + 1, int(rows[stops[k]]) + 1


def _held_text(held: tuple[int, int], rate_hz: float, lim: ClockLimits) -> str:
    first, last = held
    return (f"data rows {first}–{last} hold one pose ({last - first + 1} rows within {100 * lim.pose_step_ratio:g} % of "
            f"1 g of the one before, {(last - first + 1) / rate_hz:.2g} s at")


def sample_clock(src: Source, ev: Evidence, te: TimeEvidence, reading: Reading, ratio: float, one_g: float,
                 lim: ClockLimits) -> str | None:
    """Why a time column read in seconds, which makes the rows poses, counts samples in a smaller unit; else None.

    Evidence of a sample clock: the stamps are a time series' (:attr:`TimeEvidence.series_like`), a smaller unit
    reads them at a plausible sampling rate at which the rows change no more than a recording can
    (``lim.max_step_g``; ``ratio``: the rows' median change in g), and at that rate
    some rows hold one pose for a rest's length (:func:`held_rows`).  Never with a unit stated.
    """
    if reading.stated or not te.series_like:
        return None
    for unit in ("ms", "us", "ns"):
        rate_u = reading.rate_hz / lim.time_units[unit]
        if lim.plausible_rate_hz[0] <= rate_u <= lim.plausible_rate_hz[1]:
            break
    else:
        return None
    bound = lim.max_step_g(rate_u)
    held = held_rows(src, ev, one_g, rate_u, lim) if ratio <= bound else None
    if held is None:
        return None
    return (f"but the time column counts like a sample clock in {unit}: a recording at {rate_u:.4g} Hz (whose rows "
            f"can change by up to {100 * bound:.3g} % of 1 g), and {_held_text(held, rate_u, lim)} that rate), a rest "
            f"sampled, where a pose table has one row per pose (more than {100 * lim.pose_step_ratio:g} % of 1 g apart); "
            f"pass --time-unit {unit} to read it as a recording, or --format poses if the rows are poses")


def held_recording(src: Source, ev: Evidence, te: TimeEvidence | None, reading: Reading | None, ratio: float,
                   one_g: float, lim: ClockLimits) -> str | None:
    """Why rows that differ as poses do are a recording after all, else None: the time column's unit stated, its
    stamps a time series' closer than the shortest dwell at a plausible rate at which the rows change no more than
    a recording can, and some rows hold one pose for a rest's length there (:func:`held_rows`)."""
    if te is None or reading is None:
        return None
    rate = reading.rate_hz
    if not (reading.stated and te.series_like and reading.spacing_s < lim.min_dwell_s
            and lim.plausible_rate_hz[0] <= rate <= lim.plausible_rate_hz[1] and ratio <= lim.max_step_g(rate)):
        return None
    held = held_rows(src, ev, one_g, rate, lim)
    if held is None:
        return None
    return (f"{_held_text(held, rate, lim)} {rate:.4g} Hz, {reading.why}): a rest sampled, where a pose table has one row "
            "per pose")


#: The longest a host holds a sensor's samples before it receives (and stamps) them, seconds: Bluetooth LE's
#: longest connection interval (4 s; USB and serial links deliver within tens of ms).  A longer step between
#: stamps is a pause of the recording (a logger stopped, sessions joined), not the wait between bursts.
MAX_HOST_HOLD_S: float = 4.0


def pauses(t: np.ndarray, rows: np.ndarray, mean_step: float) -> tuple[np.ndarray, float, float]:
    """The steps of ``t[rows]`` (seconds) longer than :data:`MAX_HOST_HOLD_S`: their indices into the steps, the
    time they hold in all, and the mean step between them (``mean_step``, over the whole span, without a pause)."""
    steps = np.diff(t[rows])
    at = np.flatnonzero(steps > MAX_HOST_HOLD_S)
    held = float(steps[at].sum())
    return at, held, (float(steps.sum()) - held) / max(1, steps.size - at.size) if at.size else mean_step


def spread_rate_reason(n: int, duration: float, at: np.ndarray, step: float) -> str:
    """The rate's reason for samples spread evenly: ``(N−1)/duration = ...``, the pauses left out."""
    if not at.size:
        return f"(N−1)/duration = {n - 1}/{duration:.6g} s"
    return f"(N−1−pauses)/(duration−pauses) = {n - 1 - at.size}/{(n - 1 - at.size) * step:.6g} s"


def pause_note(at: np.ndarray, held: float) -> str:
    """``; 2 pause(s) of the recording (710.5 s in all: ...) kept as gaps``, or ``""`` without a pause."""
    if not at.size:
        return ""
    return (f"; {at.size} pause(s) of the recording ({held:.4g} s in all: steps over {MAX_HOST_HOLD_S:g} s, longer "
            "than a host holds samples) kept as gaps")


def spread_evenly(t: np.ndarray, rows: np.ndarray, at: np.ndarray, step: float) -> np.ndarray:
    """Times for ``rows`` spread ``step`` apart from each section's first stamp (sections between the pauses
    ``at``; one section without a pause); NaN elsewhere."""
    out = np.full(t.size, np.nan)
    starts = np.r_[0, at + 1]
    k = np.arange(rows.size)
    section = np.searchsorted(starts, k, side="right") - 1
    out[rows] = t[rows[starts]][section] + (k - starts[section]) * step
    return out
