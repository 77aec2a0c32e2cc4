"""Decisions: what a file is, decided from the evidence, each with its reason and the flag that overrides it.

The data layer runs in this order, each step in one place and each module visited once:

1. **read** (:mod:`optcal.data.readers`, :mod:`optcal.data.text`, :mod:`optcal.data.columns`):
   the file's columns under canonical names, and what the file itself states (unit words,
   a rate line, the format's conventions, names that leave the roles of columns open);
2. **evidence** (:func:`optcal.data.evidence.gather_evidence`): one pass of statistics over
   those columns (rows, finite and absurd samples, the median norm and the step between rows,
   the time column's steps, bursts and repeated stamps, the nominal conversion's statistics,
   and how candidate triples read at rest);
3. **decisions** (:func:`decide`): columns, kind (pose table or raw recording), units, time
   base and rate, each with its reason and the flag that overrides it; evidence that does
   not settle a question, or that conflicts, is resolved toward the documented reading or
   refused with the reason and the flags that settle it;
4. **conversion** (:func:`optcal.data.recording.recording_from_source`,
   :func:`optcal.data.tables.pose_table_from_source`): the decisions applied, every
   excluded sample counted;
5. **segmentation** (:mod:`optcal.data.static`).

:class:`DataDecisions` is what every command prints and records in its JSON; an error met
after some decisions were made is a :class:`DataInputError` that carries them, and the
command line prints them before the error.

The kind is weighed from three pieces of evidence: the time column read in its stated unit
(a unit word, ``--time-unit``, a rate stated in the header) or else in seconds as documented,
the step between consecutive rows against what a recording at that rate can make
(:func:`max_recording_step_g`), and the number of rows.  A time unit is never re-read from
the spacing of the stamps alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.evidence import (
    ABSURD,
    ABSURD_G,
    BURST_RATIO,
    COARSE_REPEATED_FRACTION,
    NON_FINITE,
    ROLE_BLOCK_SAMPLES,
    ZERO_ROWS,
    Evidence,
    RoleEvidence,
    TimeEvidence,
    gather_evidence,
    time_evidence,
)
from optcal.data.backwards import refuse_backwards, sections_explain_backwards
from optcal.data.readers import Source
from optcal.data import sample_clock as clock
from optcal.data.sample_clock import ClockLimits, held_recording, sample_clock
from optcal.data.rest_units import units_and_nominal_at_rest
from optcal.data.units import G_NORM_RANGE, MAX_REST_NOISE_G, MS2_NORM_RANGE, NominalConversion
from optcal.errors import InputError

__all__ = [
    "ABSURD", "ABSURD_G", "BURST_RATIO", "COARSE_REPEATED_FRACTION", "KINDS", "NON_FINITE", "POSE_TABLE",
    "RAW_RECORDING", "TIMINGS", "TIME_UNITS", "ZERO_ROWS", "DataDecisions", "DataInputError", "Decision",
    "Evidence", "TimeEvidence", "decide", "gather_evidence", "max_recording_step_g", "time_evidence",
    "with_decisions",
]

POSE_TABLE = "pose table"
RAW_RECORDING = "raw recording"
#: ``kind`` choices: decide automatically, or force a pose table or a raw recording.
KINDS: tuple[str, ...] = ("auto", "poses", "raw")
#: ``time_unit`` choices.
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: ``timing`` choices: decide, keep the stamps, or spread the samples evenly over the stamped span.
TIMINGS: tuple[str, ...] = ("auto", "stamps", "uniform")

#: Consecutive rows of a raw recording differ by less than this fraction of 1 g (median): the samples
#: of a resting sensor differ by its noise, a few mg; distinct poses by the chord of a turn of more
#: than a degree.
RAW_STEP_RATIO: float = 0.02
#: Consecutive rows of a pose table differ by more than this fraction of 1 g (median): poses a turn
#: of 6° or more apart.
POSE_STEP_RATIO: float = 0.10
#: A regular time column at this rate or more over this many rows is a recording's (a pose is held
#: for seconds: poses do not come five per second, and a table of poses has tens to hundreds of rows).
RAW_MIN_RATE_HZ: float = 5.0
RAW_MIN_ROWS: int = 200
#: More rows than this without a time column: a recording (pose tables have tens to hundreds).
MANY_ROWS: int = 2000
#: Plausible sampling rates of a recording, Hz: slower than 1 Hz no rest holds the samples of a
#: static detection window; faster than 100 kHz is no MEMS inertial sensor's output rate.
PLAUSIBLE_RATE_HZ: tuple[float, float] = (1.0, 100_000.0)
#: A ``rate`` that differs from a regular time column's rate by more than this fraction is warned
#: about (and a rate stated in the header settles the time column's unit when one unit gives it within it).
RATE_MISMATCH_FRACTION: float = 0.05
#: The fastest turn of a sensor in a recording: 2000 °/s, the largest full scale of common MEMS
#: gyroscopes (a hand turns a sensor at 1-20 rad/s at its peak, below 1150 °/s).
MAX_TURN_RATE_DEG_S: float = 2000.0
#: Rows of a pose table are poses held still and turned between: at least this far apart in time
#: (the static detection's shortest dwell, ``--min-dwell 0.5``).
MIN_POSE_SPACING_S: float = 0.5
#: Dates a recording's Unix stamps can hold, seconds since 1970-01-01: from 1990-01-01 (the first
#: digital loggers of MEMS accelerometers) to 2100-01-01.  A first stamp inside this span read in
#: one unit of :data:`TIME_UNITS` is evidence of that unit: the spans of the four units do not
#: overlap (the span's end is 6.5 times its start, the units 1000 times apart), so at most one unit
#: reads a given stamp as a date; what it protects against is a counter since power-on read as a
#: date, which the rate check in :func:`_epoch_reading` catches as well.
EPOCH_SPAN_S: tuple[float, float] = (631_152_000.0, 4_102_444_800.0)
#: Seconds in a mean Gregorian year, to state how far from any date a stamp is in the wrong unit.
YEAR_S: float = 31_556_952.0


def max_recording_step_g(rate_hz: float) -> float:
    """The largest median change between consecutive samples of a recording at ``rate_hz``, in g.

    Model: the sensor is a rigid body turning at :data:`MAX_TURN_RATE_DEG_S` at most, so between
    two samples gravity turns by at most ω/rate and the specific force changes by the chord
    ``2 sin(ω / (2 rate))`` g (2 g at most, a reversal); the noise of two samples of a resting
    accelerometer adds ``√6 ×`` :data:`~optcal.data.units.MAX_REST_NOISE_G` (√2 for a
    difference, √3 over three axes).  The linear accelerations of the moves last a small part
    of a recording and do not move the median.  At 100 Hz: 0.35 + 0.12 = 0.47 g.
    """
    angle = min(np.pi, np.deg2rad(MAX_TURN_RATE_DEG_S) / rate_hz) if rate_hz > 0 else np.pi
    return float(2.0 * np.sin(angle / 2.0) + np.sqrt(6.0) * MAX_REST_NOISE_G)


_CLOCK = ClockLimits(TIME_UNITS, PLAUSIBLE_RATE_HZ, POSE_STEP_RATIO, MIN_POSE_SPACING_S, max_recording_step_g)


@dataclass(frozen=True)
class Decision:
    """One decision about the data, why it was made, and the flag that overrides it.

    Attributes
    ----------
    value : str, float or None
    reason : str
    flag : str
        The command-line option (and keyword of :func:`optcal.data.load`) that sets it.
    """

    value: Any
    reason: str
    flag: str

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "reason": self.reason, "override": self.flag}


@dataclass
class DataDecisions:
    """Every decision made about a data file, each with its reason (printed and saved in JSON).

    Attributes
    ----------
    kind : Decision
        ``"pose table"`` or ``"raw recording"`` (``--format``).
    columns : Decision
        The column mapping (``--columns``).
    units : Decision
        ``"g"``, ``"m/s^2"`` or ``"counts"`` (``--units``).
    time_base : Decision
        ``"stamps"``, ``"uniform"`` (re-timed evenly over the stamped span), ``"rate"``
        (row number / rate) or ``"none"`` (``--timing``, ``--time-unit``).
    rate : Decision
        Sampling rate in Hz, or ``None`` for a pose table (``--rate``).
    layout : str
        How the file was laid out (delimiter, header) and read.
    exclusions : dict of str to int
        Rows excluded before segmentation, by reason (segmentation adds its own).
    warnings : list of str
        Choices given by the user that the evidence contradicts (the user's choice is kept).
    nominal : NominalConversion or None
        The nominal conversion of the units decided, from the evidence (the "before calibration"
        baseline of the usable rows; not printed).
    evidence : Evidence or None
        The evidence of the file as the decisions read it (its columns' roles), for the
        conversion (not printed).
    """

    kind: Decision
    columns: Decision
    units: Decision
    time_base: Decision
    rate: Decision
    layout: str = ""
    exclusions: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    nominal: NominalConversion | None = field(default=None, repr=False, compare=False)
    evidence: Evidence | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form."""
        return {
            "kind": self.kind.to_dict(),
            "columns": self.columns.to_dict(),
            "units": self.units.to_dict(),
            "time_base": self.time_base.to_dict(),
            "rate_hz": self.rate.to_dict(),
            "layout": self.layout,
            "exclusions": dict(self.exclusions),
            "warnings": list(self.warnings),
        }

    def lines(self) -> list[str]:
        """One line per decision, for the text report of every command."""
        return decision_lines(self.kind, self.columns, self.units, self.time_base, self.rate, self.layout,
                              self.exclusions, self.warnings)


def decision_lines(
    kind: Decision | None,
    columns: Decision | None,
    units: Decision | None,
    time_base: Decision | None,
    rate: Decision | None,
    layout: str,
    exclusions: dict[str, int],
    warnings: list[str],
) -> list[str]:
    """One line per decision made (``None``: not made), as :meth:`DataDecisions.lines` prints them."""
    out = []
    if kind is not None:
        kind_flag = f"; {kind.flag}" if kind.flag else ""
        out.append(f"kind: {kind.value} ({kind.reason}{kind_flag})")
    if columns is not None:
        out.append(f"columns: {columns.value} ({columns.reason}; {columns.flag})")
    if units is not None:
        out.append(f"units: {units.value} ({units.reason}; {units.flag})")
    if time_base is not None:
        if kind is None or kind.value == RAW_RECORDING:
            hz = "" if rate is None or rate.value is None else f", {rate.value:.6g} Hz"
            out.append(f"time: {time_base.value}{hz} ({time_base.reason}; {time_base.flag})")
        elif time_base.value != "none":
            out.append(f"time: {time_base.reason}")
    if layout:
        out.append(f"read: {layout}")
    if exclusions:
        out.append("excluded while reading: " + "; ".join(f"{k}: {v}" for k, v in exclusions.items()))
    out.extend(f"warning: {w}" for w in warnings)
    return out


class DataInputError(InputError):
    """Bad input met after some decisions about the data were made: the error carries them.

    The command line prints them before the error line, so that the user sees what the file was
    read as when it was refused.

    Attributes
    ----------
    decisions : list of str
        The decisions made before the error, one line each (as :meth:`DataDecisions.lines`).
    """

    def __init__(self, message: str, decisions: list[str]) -> None:
        super().__init__(message)
        self.decisions = list(decisions)


def with_decisions(exc: InputError, decisions: DataDecisions | list[str]) -> InputError:
    """``exc`` carrying ``decisions`` (a :class:`DataInputError` with its message), to raise in its place.

    An error that already carries decisions, or is of a more specific kind
    (:class:`~optcal.errors.IdentifiabilityError`, ...), is returned as it is.
    """
    if type(exc) is not InputError:
        return exc
    lines = decisions.lines() if isinstance(decisions, DataDecisions) else list(decisions)
    error = DataInputError(str(exc), lines)
    error.__cause__ = exc
    return error


def decide(
    src: Source,
    ev: Evidence,
    *,
    kind: str = "auto",
    units: str | None = None,
    rate: float | None = None,
    time_unit: str | None = None,
    timing: str = "auto",
    required_by: str | None = None,
) -> DataDecisions:
    """Decide columns, kind, units, time base and rate from the evidence (flags win).

    Parameters
    ----------
    src : Source
        Read with the roles of its columns decided (``src.roles``: the decided triple is read as
        the accelerometer, in place).
    ev : Evidence
    kind : {"auto", "poses", "raw"}
    units : str, optional
    rate : float, optional
        Hz; the sampling rate of a recording without a time column (or instead of it).
    time_unit : {"s", "ms", "us", "ns"}, optional
        Unit of an unnamed time column.
    timing : {"auto", "stamps", "uniform"}
        Keep the stamps, or spread the samples evenly over the stamped span (bursty or
        coarse stamps are spread evenly under ``auto``).
    required_by : str, optional
        What requires ``kind`` (e.g. ``"the allan command"``) when it is not the user's
        choice; the kind decision then gives that as its reason.

    Raises
    ------
    InputError
        An unknown option.
    DataInputError
        A flag that contradicts the data (units against the norm), or evidence that does not
        settle a decision (named with the flag that does), with the decisions made before it.
    """
    if kind not in KINDS:
        raise InputError(f"unknown kind {kind!r}; use one of {', '.join(KINDS)}")
    if timing not in TIMINGS:
        raise InputError(f"unknown timing {timing!r}; use one of {', '.join(TIMINGS)}")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise InputError(f"unknown time unit {time_unit!r}; use one of {', '.join(TIME_UNITS)}")
    if rate is not None and not rate > 0:
        raise InputError(f"rate must be positive, got {rate}")
    if required_by is not None and kind not in ("poses", "raw"):
        raise InputError(f"required_by needs kind 'poses' or 'raw', got {kind!r}")
    made: dict[str, Decision] = {}
    warnings: list[str] = []
    try:
        if not ev.usable.any():
            raise InputError(
                f"{src.path}: no usable sample (of {ev.n_rows} rows: "
                + "; ".join(f"{k}: {v}" for k, v in ev.exclusions().items()) + ")"
            )
        made["columns"], ev = _decide_columns(src, ev)
        units_error: InputError | None = None
        nominal: NominalConversion | None = None
        try:
            found, nominal = units_and_nominal_at_rest(src, ev, units)  # the quiet stretches where the median is not 1 g
            one_g = nominal.sensitivity
        except InputError as exc:  # refused once the kind is known (a pose table's bad cell is named first)
            units_error, one_g = exc, ev.median_norm
        if required_by is not None:
            what = POSE_TABLE if kind == "poses" else RAW_RECORDING
            made["kind"] = Decision(what, f"{required_by} requires a {what}", "")
        else:
            made["kind"] = _decide_kind(src, ev, kind, one_g, time_unit)
            if kind != "auto":
                warnings.extend(_kind_contradiction(src, ev, made["kind"], one_g, time_unit))
            if units_error is None:
                warnings.extend(_step_contradiction(src, ev, made["kind"], one_g, time_unit))
        if made["kind"].value == POSE_TABLE:
            for canon, (count, row, value) in src.non_numeric.items():
                raise InputError(
                    f"{src.path}: column {src.column_map.get(canon, canon)!r} has a non-numeric value "
                    f"{value!r} on data row {row} ({count} such cell(s)); every cell of a pose table must be a number"
                )
        if units_error is not None:
            if src.roles is not None:  # the columns were taken by a layout the data did not confirm
                raise InputError(f"{units_error}; or, if these columns are not the accelerometer's, map them with "
                                 "--columns (see the columns decision)")
            raise units_error
        made["units"] = Decision(found.units, found.reason, "--units")
        if made["kind"].value == POSE_TABLE:
            if rate is not None:
                raise InputError(f"rate applies to raw recordings; {src.path} was read as a pose table ({made['kind'].reason})")
            made["time_base"], made["rate"] = _pose_table_time(src, time_unit)
        else:
            made["time_base"], made["rate"] = _recording_time(src, ev, rate, time_unit, timing)
            warnings.extend(_rate_contradiction(src, ev, rate, time_unit))
    except InputError as exc:
        raise with_decisions(exc, decision_lines(
            made.get("kind"), made.get("columns"), made.get("units"), made.get("time_base"), made.get("rate"),
            src.layout, ev.exclusions(), warnings)) from exc
    return DataDecisions(
        made["kind"], made["columns"], made["units"], made["time_base"], made["rate"], src.layout, ev.exclusions(),
        warnings, nominal=nominal, evidence=ev,
    )


# ----------------------------------------------------------------------------- columns
def _decide_columns(src: Source, ev: Evidence) -> tuple[Decision, Evidence]:
    """The columns as named, or, when the names leave the roles open, as the rest readings say
    (``src`` is then read so, in place); and the evidence of that reading."""
    roles, rest = src.roles, ev.roles
    if roles is None or rest is None:
        return Decision(src.describe_columns(), src.columns_reason, "--columns"), ev
    time = src.column_map.get("t")
    if rest.triples:
        like = [t.acceleration_like for t in rest.triples]
        said = [t.describe() for t in rest.triples]
    else:
        like = [False] * len(roles.triples)
        said = [f"only {rest.quiet_blocks} of {rest.blocks} blocks of {ROLE_BLOCK_SAMPLES} rows are quiet"] * len(like)
    if roles.conditional:
        if not like[0]:
            raise InputError(
                f"{src.path}: {roles.positions(0)} are read as the accelerometer only when the data say acceleration, "
                f"and they do not ({said[0]}; an accelerometer turned between rests reads on one sphere); map the "
                "accelerometer with --columns ax=NAME,ay=NAME,az=NAME"
            )
        reason = (f"{roles.positions(0)} read as the accelerometer: the data say acceleration ({said[0]}, as an "
                  f"accelerometer turned between rests reads)")
        return Decision(src.describe_columns(), reason, "--columns"), ev
    picks = [k for k, ok in enumerate(like) if ok]
    if len(picks) == 1 and len(roles.triples) == 2:
        k = picks[0]
        if k != roles.acc:
            src.assign_accelerometer(k)
        reason = (
            f"no header; {roles.positions(k)} read as the accelerometer by the data ({said[k]}: an accelerometer "
            f"turned between rests), {roles.positions(1 - k)} as the gyroscope ({said[1 - k]}: a gyroscope reads its "
            f"bias at rest in every orientation){_time_words(src, time)}; --columns {roles.columns_option(1 - k, time)} "
            "reads them the other way"
        )
        return Decision(src.describe_columns(), reason, "--columns"), rest.readings[k]
    k_norm = _accelerometer_by_norm(rest) if not picks and rest.triples and len(roles.triples) == 2 else None
    if k_norm is not None:
        k, norms = k_norm, [r.median_norm for r in rest.readings]
        if k != roles.acc:
            src.assign_accelerometer(k)
        reason = (
            f"no header; the sensor was not turned (neither triple's rests move on a sphere), so by the norms: "
            f"{roles.positions(k)} read as the accelerometer (median |a| {norms[k]:.4g}: gravity's 1 g in g or m/s^2), "
            f"{roles.positions(1 - k)} as the gyroscope (median norm {norms[1 - k]:.3g}, below {G_NORM_RANGE[0]:g}: "
            f"less than 1 g in any unit, as a gyroscope's bias reads at rest){_time_words(src, time)}; "
            f"--columns {roles.columns_option(1 - k, time)} reads them the other way"
        )
        return Decision(src.describe_columns(), reason, "--columns"), rest.readings[k]
    why = ("both triples read as an accelerometer turned between rests" if len(picks) == 2 else
           "neither triple's rest readings move on a sphere: the sensor was not turned through orientations"
           if rest.triples else said[0])
    reason = (f"{src.columns_reason}; the data do not tell which triple is the accelerometer ({why}), so the common "
              f"layout; --columns {roles.columns_option(1 - roles.acc, time)} reads them the other way")
    return Decision(src.describe_columns(), reason, "--columns"), ev


def _accelerometer_by_norm(rest: RoleEvidence) -> int | None:
    """The triple that reads gravity's 1 g while the other reads less than 1 g in any unit, or ``None``.

    For a sensor that was not turned (the rests' sphere cannot tell the triples apart). A resting
    accelerometer reads 1 g: a median norm in the g or m/s^2 range (:data:`~optcal.data.units.G_NORM_RANGE`,
    :data:`~optcal.data.units.MS2_NORM_RANGE`; counts, also above them, are not told apart from a
    gyroscope's counts). A triple whose median norm is below :data:`~optcal.data.units.G_NORM_RANGE`'s
    lower end (0.5) is less than 1 g in every unit an accelerometer is written in, so it cannot be the
    accelerometer at rest; a gyroscope at rest reads its bias there (in rad/s up to 0.35 even for an
    MPU-6050's ±20 °/s zero-rate tolerance). Only when one triple reads 1 g and the other below 0.5 is
    the answer taken; otherwise the common layout stands, as before.
    """
    norms = [r.median_norm for r in rest.readings]
    if len(norms) != 2 or not all(np.isfinite(norms)):
        return None
    gravity = [G_NORM_RANGE[0] <= n <= G_NORM_RANGE[1] or MS2_NORM_RANGE[0] <= n <= MS2_NORM_RANGE[1] for n in norms]
    below = [n < G_NORM_RANGE[0] for n in norms]
    picks = [k for k in range(2) if gravity[k] and below[1 - k]]
    return picks[0] if len(picks) == 1 else None


def _time_words(src: Source, time: str | None) -> str:
    if time is None:
        return ""
    return f", time in {time.replace('#', 'column ')} (it increases)"


# ----------------------------------------------------------------------------- kind
@dataclass(frozen=True)
class _TimeReading:
    """The time column read in one unit: the stated one, or seconds as documented."""

    factor: float  # to seconds, applied to the column as it stands
    unit: str
    stated: bool  # by the column's name, --time-unit or a rate in the header (not the documented default)
    why: str
    spacing_s: float  # (N−1)/duration in seconds

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.spacing_s if self.spacing_s > 0 else float("inf")


def _time_reading(src: Source, te: TimeEvidence, time_unit: str | None) -> _TimeReading:
    """The unit of the time column: its name's, ``--time-unit``'s, the header rate's, or seconds as documented.

    Never the spacing's alone: a stated rate picks the unit whose stamps give it.
    """
    name = f"column {src.column_map.get('t', 't')!r}"
    if src.time_unit is not None:  # the reader converted it to seconds
        # the reader's reason less its trailing "(its name says so)": the name itself may hold " (" (``Time (s)``)
        said = src.time_reason.rsplit(" (", 1)[0] if src.time_reason.endswith(")") else src.time_reason
        why = f"{name} {said.removeprefix(name + ' ')}"
        return _TimeReading(1.0, src.time_unit, True, why, te.mean_step)
    if time_unit is not None:
        factor = TIME_UNITS[time_unit]
        return _TimeReading(factor, time_unit, True, f"{name} in {time_unit} (given with --time-unit)", te.mean_step * factor)
    if src.rate_hint is not None and te.mean_step > 0:
        for unit, factor in TIME_UNITS.items():
            rate_u = 1.0 / (te.mean_step * factor)
            if abs(rate_u / src.rate_hint - 1.0) <= RATE_MISMATCH_FRACTION:
                why = f"{name} in {unit}: the header states {src.rate_hint:g} Hz ({src.rate_reason}), which it gives in {unit}"
                return _TimeReading(factor, unit, unit != "s", why, te.mean_step * factor)
    epoch = _epoch_reading(name, te)
    if epoch is not None:
        return epoch
    return _TimeReading(1.0, "s", False, f"{name} in seconds, as documented", te.mean_step)


def _epoch_reading(name: str, te: TimeEvidence) -> _TimeReading | None:
    """The unit in which the first stamp is a date since 1970 and the samples come at a recording's rate.

    Model: a logger that stamps with the host's clock writes Unix time in s, ms, µs or ns; the
    first stamp read in its unit is a date within :data:`EPOCH_SPAN_S`, and the steps read in
    that unit give a rate within :data:`PLAUSIBLE_RATE_HZ`.  Both must hold (a counter since
    power-on that happens to read as a date in one unit gives no recording's rate in it).
    """
    if not (np.isfinite(te.start) and te.mean_step > 0):
        return None
    for unit, factor in TIME_UNITS.items():
        start_s = te.start * factor
        if not EPOCH_SPAN_S[0] <= start_s <= EPOCH_SPAN_S[1]:
            continue
        rate = 1.0 / (te.mean_step * factor)
        if not PLAUSIBLE_RATE_HZ[0] <= rate <= PLAUSIBLE_RATE_HZ[1]:
            return None
        date = datetime.fromtimestamp(start_s, tz=timezone.utc).strftime("%Y-%m-%d")
        why = f"{name} in {unit} since 1970: its first stamp {te.start:.10g} is {date} in {unit}"
        if unit != "s":
            why += f" (in seconds, the year {1970 + te.start / YEAR_S:,.0f})"
        return _TimeReading(factor, unit, True, why + "; --time-unit overrides", te.mean_step * factor)
    return None


def _other_unit(te: TimeEvidence) -> str:
    """``--time-unit ms (100 Hz)``: the first smaller unit giving a plausible rate, as a hint (never applied)."""
    for unit in ("ms", "us", "ns"):
        rate_u = 1.0 / (te.mean_step * TIME_UNITS[unit]) if te.mean_step > 0 else float("inf")
        if PLAUSIBLE_RATE_HZ[0] <= rate_u <= PLAUSIBLE_RATE_HZ[1]:
            return f"--time-unit {unit} ({rate_u:.4g} Hz)"
    return "--time-unit UNIT"


def _decide_kind(src: Source, ev: Evidence, requested: str, one_g: float, time_unit: str | None) -> Decision:
    flag = "--format"
    if requested == "poses":
        if src.always_raw:
            raise InputError(f"{src.path}: a {src.file_type} holds a raw recording; it cannot be read as a pose table")
        return Decision(POSE_TABLE, "given with --format poses", flag)
    if requested == "raw":
        return Decision(RAW_RECORDING, "given with --format raw", flag)
    if src.always_raw:
        return Decision(RAW_RECORDING, f"a {src.file_type} is a time series", flag)
    if src.has("sigma") or src.has("n_samples"):
        return Decision(POSE_TABLE, "it has per-pose columns (sigma / n_samples)", flag)
    if src.rate_hint is not None:
        return Decision(RAW_RECORDING, f"its header gives a sampling rate ({src.rate_reason})", flag)
    n = int(ev.usable.sum())
    ratio = ev.median_step / one_g if one_g > 0 else float("nan")
    step = f"consecutive rows differ by {100 * ratio:.3g} % of 1 g (median)"
    te = ev.time
    if te is not None and te.n >= 2 and te.duration > 0 and te.backwards == 0:
        reading = _time_reading(src, te, time_unit)
        rate = reading.rate_hz
        if te.series_like and te.n >= RAW_MIN_ROWS and rate >= RAW_MIN_RATE_HZ:
            bound = max_recording_step_g(rate)
            within = "within" if ratio <= bound else "beyond"
            return Decision(
                RAW_RECORDING,
                f"a regular time column ({te.n} rows at {rate:.4g} Hz on average, {reading.why}), {step}, "
                f"{within} the {100 * bound:.3g} % a recording at that rate can change",
                flag,
            )
        if reading.spacing_s >= MIN_POSE_SPACING_S and ratio > POSE_STEP_RATIO:
            if (clock := sample_clock(src, ev, te, reading, ratio, one_g, _CLOCK)) is not None:
                raise InputError(f"{src.path}: cannot tell a pose table from a raw recording: read in seconds "
                                 f"({reading.why}) its rows would be poses {reading.spacing_s:.3g} s apart ({step}), {clock}")
            return Decision(
                POSE_TABLE,
                f"{step}, as distinct poses do, {reading.spacing_s:.3g} s apart on average ({reading.why})"
                + _not_a_recording(te, reading, ratio),
                flag,
            )
        if ratio < RAW_STEP_RATIO and not reading.stated and not (PLAUSIBLE_RATE_HZ[0] <= rate <= PLAUSIBLE_RATE_HZ[1]):
            raise InputError(
                f"{src.path}: {step}, as samples of a time series do, but the time column ({reading.why}) puts them "
                f"{reading.spacing_s:.4g} s apart ({rate:.4g} Hz), outside any recording's rates "
                f"({PLAUSIBLE_RATE_HZ[0]:g} Hz to {PLAUSIBLE_RATE_HZ[1]:g} Hz); its unit is not re-read from the "
                f"spacing alone: pass {_other_unit(te)} if that is its unit, or --format poses if the rows are poses"
            )
    if n < 3:
        return Decision(POSE_TABLE, "too few rows for a recording", flag)
    if ratio < RAW_STEP_RATIO:
        return Decision(RAW_RECORDING, f"{step}, as samples of a time series do", flag)
    if ratio > POSE_STEP_RATIO and n <= MANY_ROWS:
        stated = _time_reading(src, te, time_unit) if te is not None and te.duration > 0 and not te.backwards else None
        if (held := held_recording(src, ev, te, stated, ratio, one_g, _CLOCK)) is not None:
            return Decision(RAW_RECORDING, f"{step}, but {held}", flag)
        return Decision(POSE_TABLE, f"{step}, as different poses do ({n} rows)", flag)
    if n > MANY_ROWS:
        return Decision(RAW_RECORDING, f"{n} rows with no per-pose columns (a pose table has tens to hundreds), {step}", flag)
    raise InputError(
        f"{src.path}: cannot tell a pose table from a raw recording: {step} (between the "
        f"≤ {100 * RAW_STEP_RATIO:g} % of a time series and the ≥ {100 * POSE_STEP_RATIO:g} % of distinct poses) "
        f"over {n} rows" + ("" if te is None else ", and the time column does not settle it")
        + "; pass --format raw or --format poses"
    )


def _not_a_recording(te: TimeEvidence, reading: _TimeReading, ratio: float) -> str:
    """Why the rows are not a recording's: too slow in the unit read, too steep in a unit that would not be."""
    out = ""
    if reading.rate_hz < PLAUSIBLE_RATE_HZ[0]:
        out = f"; a recording at {reading.rate_hz:.3g} Hz would be slower than any"
    if reading.stated:
        return out
    for unit in ("ms", "us", "ns"):
        rate_u = reading.rate_hz / TIME_UNITS[unit]
        if PLAUSIBLE_RATE_HZ[0] <= rate_u <= PLAUSIBLE_RATE_HZ[1]:
            bound = max_recording_step_g(rate_u)
            if ratio > bound:
                out += (f"; were t in {unit}, a recording at {rate_u:.4g} Hz, its rows could differ by "
                        f"{100 * bound:.3g} % at most (a turn at {MAX_TURN_RATE_DEG_S:g} °/s and a resting "
                        "accelerometer's noise)")
            break
    return out


def _step_contradiction(src: Source, ev: Evidence, kind: Decision, one_g: float, time_unit: str | None) -> list[str]:
    """A warning when a recording read from a regular time column changes between rows more than any recording can."""
    te = ev.time
    if kind.value != RAW_RECORDING or te is None or te.n < 2 or not te.duration > 0 or te.backwards:
        return []
    reading = _time_reading(src, te, time_unit)
    ratio = ev.median_step / one_g if one_g > 0 else float("nan")
    bound = max_recording_step_g(reading.rate_hz)
    if not ratio > bound:
        return []
    return [
        f"consecutive rows differ by {100 * ratio:.3g} % of the nominal 1 g (median), more than the {100 * bound:.3g} % "
        f"any recording at {reading.rate_hz:.4g} Hz can change (a turn at {MAX_TURN_RATE_DEG_S:g} °/s and a resting "
        "accelerometer's noise): if the columns are not the accelerometer's, map them with --columns; if the rows are "
        "poses, pass --format poses (and --time-unit)"
    ]


def _kind_contradiction(src: Source, ev: Evidence, given: Decision, one_g: float, time_unit: str | None) -> list[str]:
    """A warning when the evidence alone would read the file as the other kind (the user's choice is kept)."""
    try:
        auto = _decide_kind(src, ev, "auto", one_g, time_unit)
    except InputError:
        return []
    if auto.value == given.value:
        return []
    return [
        f"read as a {given.value} as given, but the evidence says {auto.value}: {auto.reason}"
        + (f" ({int(ev.usable.sum())} rows would each be one pose)" if given.value == POSE_TABLE else "")
    ]


# ----------------------------------------------------------------------------- time
def _rate_contradiction(src: Source, ev: Evidence, rate: float | None, time_unit: str | None) -> list[str]:
    """A warning when a given rate contradicts a regular time column (the given rate is kept)."""
    te = ev.time
    if rate is None or te is None or not src.has("t") or te.backwards or not te.duration > 0 or te.n < RAW_MIN_ROWS:
        return []
    reading = _time_reading(src, te, time_unit)
    rate_t = reading.rate_hz  # (N−1)/duration: robust to bursty stamps
    if abs(rate / rate_t - 1.0) <= RATE_MISMATCH_FRACTION:
        return []
    return [
        f"the given rate {rate:g} Hz differs by {100 * abs(rate / rate_t - 1.0):.0f} % from the time column "
        f"({reading.why}; {te.n} rows over {te.duration * reading.factor:.6g} s: {rate_t:.4g} Hz); "
        "the given rate is used (drop rate= to use the time column)"
    ]


def _pose_table_time(src: Source, time_unit: str | None) -> tuple[Decision, Decision]:
    no_rate = Decision(None, "a pose table has no sampling rate", "--rate")
    if not src.has("t"):
        return Decision("none", "no time column", "--time-unit"), no_rate
    if time_unit is not None:
        factor = TIME_UNITS[time_unit]
        if src.time_unit is not None and src.time_unit != time_unit:
            raise InputError(f"{src.path}: time_unit {time_unit} contradicts the column name ({src.time_reason})")
        if src.time_unit is None and factor != 1.0:
            src.data["t"] = src.column("t") * factor
        return Decision("stamps", f"t in {time_unit} (given with --time-unit)", "--time-unit"), no_rate
    if src.time_unit is not None:
        return Decision("stamps", src.time_reason, "--time-unit"), no_rate
    return Decision("stamps", f"{src.time_reason} in seconds, as documented for pose tables (never rescaled)", "--time-unit"), no_rate


def _recording_time(
    src: Source, ev: Evidence, rate: float | None, time_unit: str | None, timing: str
) -> tuple[Decision, Decision]:
    """Time base and rate of a recording; rescales or re-times ``src``'s ``t`` column in place."""
    if rate is not None or not src.has("t"):
        rate_used = rate if rate is not None else src.rate_hint
        text_time = src.time_reason if src.time_reason and not src.has("t") else ""  # a time column of text, set aside
        if rate_used is None:
            raise InputError(
                f"{src.path}: no time column{f' ({text_time})' if text_time else ''} and no sampling rate; pass "
                "--rate HZ (or add a time column t_s, or map one with --columns t=NAME or t=POSITION)"
            )
        why = ("--rate" if rate is not None else src.rate_reason) + (f"; {text_time}" if text_time else "")
        what = f"column {src.column_map['index']!r}" if src.has("index") else "row number"
        if src.has("t"):
            why += ", instead of the time column"
        if src.has("index"):
            counter = f"column {src.column_map['index']!r}"
            sections = sections_explain_backwards(src, ev, src.column("index"))
            if sections is None:
                refuse_backwards(src, ev, src.column("index"), counter)
            else:  # the time is the row number: the counter is set aside (the recording would read it as time)
                what = f"row number (not {counter}: {sections})"
                src.data.pop("index")
        return Decision("rate", f"{what} / {rate_used:g} Hz ({why})", "--rate"), Decision(float(rate_used), why, "--rate")
    te = ev.time
    t = src.column("t")
    if te is None:
        raise InputError(f"{src.path}: fewer than two usable samples with a time")
    if te.backwards:  # the evidence counted the steps back among the usable rows
        refuse_backwards(src, ev, t, "time")
    if time_unit is not None and src.time_unit is not None and src.time_unit != time_unit:
        raise InputError(f"{src.path}: time_unit {time_unit} contradicts the column name ({src.time_reason})")
    reading = _time_reading(src, te, time_unit)
    if not reading.stated and te.duration > 0 and not PLAUSIBLE_RATE_HZ[0] <= reading.rate_hz <= PLAUSIBLE_RATE_HZ[1]:
        raise InputError(
            f"{src.path}: the time column ({reading.why}) gives {te.n} samples at {reading.rate_hz:.4g} Hz, outside "
            f"any recording's rates ({PLAUSIBLE_RATE_HZ[0]:g} Hz to {PLAUSIBLE_RATE_HZ[1]:g} Hz); its unit is not "
            f"re-read from the spacing alone: pass {_other_unit(te)} if that is its unit (or --time-unit s to keep seconds)"
        )
    factor = reading.factor
    if factor != 1.0:
        t = t * factor
        src.data["t"] = t
    mean_step = te.mean_step * factor
    median_step = te.median_step * factor
    name = reading.why
    rows = np.flatnonzero(ev.usable)
    gaps, held, mean_step = clock.pauses(t, rows, mean_step) if te.bursty and mean_step > 0 else (rows[:0], 0.0, mean_step)
    irregular = (te.bursty and median_step * BURST_RATIO < mean_step) or te.coarse  # bursts judged between pauses
    if timing == "uniform" or (timing == "auto" and irregular and mean_step > 0):
        if not mean_step > 0:
            raise InputError(f"{src.path}: the time column does not advance; pass --rate HZ")
        src.data["t"] = clock.spread_evenly(t, rows, gaps, mean_step)
        if timing == "uniform":
            why = "given with --timing uniform"
        elif te.bursty:
            why = (
                f"the stamps arrive in bursts (median step {1e3 * median_step:.3g} ms, mean step "
                f"{1e3 * mean_step:.3g} ms): host receive times; pass --timing stamps to keep them"
            )
        else:
            why = (
                f"the stamps are coarse ({100 * te.repeated_fraction:.0f} % of the samples repeat the previous "
                f"stamp; resolution {1e3 * te.min_positive_step * factor:.3g} ms); pass --timing stamps to keep them"
            )
        reason = f"{name}; samples spread evenly over the stamped span{clock.pause_note(gaps, held)}: {why}"
        return Decision("uniform", reason, "--timing"), Decision(
            1.0 / mean_step, clock.spread_rate_reason(te.n, te.duration * factor, gaps, mean_step), "--rate")
    rate_hz = 1.0 / median_step if median_step > 0 else float("nan")
    return Decision("stamps", name + clock.pause_note(gaps, held), "--timing"), Decision(rate_hz, "1/median time step", "--rate")

