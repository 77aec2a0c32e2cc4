"""Evidence and decisions: what a file is, made from one pass of statistics over it.

The data layer runs in this order, each step in one place:

1. **read** (:mod:`optcal.data.readers`): the file's columns under canonical names, and
   what the file itself states (unit words, a rate line, the format's conventions);
2. **evidence** (:func:`gather_evidence`): one pass of statistics over those columns
   (rows, finite and absurd samples, the median norm and the step between rows, the time
   column's steps, bursts and repeated stamps, file size);
3. **decisions** (:func:`decide`): kind (pose table or raw recording), columns, units,
   time base and rate, each with its reason and the flag that overrides it; evidence
   that does not settle a question is refused with the reason and that flag;
4. **conversion** (:func:`optcal.data.recording.recording_from_source`,
   :func:`optcal.data.tables.pose_table_from_source`): the decisions applied, every
   excluded sample counted;
5. **segmentation** (:mod:`optcal.data.static`).

:class:`DataDecisions` is what every command prints and records in its JSON.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.quantiles import median
from optcal.data.readers import ACC, GYRO, Source, columns_block
from optcal.data.units import decide_units, nominal_conversion
from optcal.errors import InputError

POSE_TABLE = "pose table"
RAW_RECORDING = "raw recording"
#: ``kind`` choices: decide automatically, or force a pose table or a raw recording.
KINDS: tuple[str, ...] = ("auto", "poses", "raw")
#: ``time_unit`` choices.
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: ``timing`` choices: decide, keep the stamps, or spread the samples evenly over the stamped span.
TIMINGS: tuple[str, ...] = ("auto", "stamps", "uniform")

#: Consecutive rows of a raw recording differ by less than this fraction of 1 g (median).
RAW_STEP_RATIO: float = 0.02
#: Consecutive rows of a pose table differ by more than this fraction of 1 g (median).
POSE_STEP_RATIO: float = 0.10
#: A regular time column at this rate or more over this many rows is a recording.
RAW_MIN_RATE_HZ: float = 5.0
RAW_MIN_ROWS: int = 200
#: More rows than this without a time column: a recording (pose tables have tens to hundreds).
MANY_ROWS: int = 2000
#: An axis beyond this many g (by the median norm as 1 g) is beyond any accelerometer's full scale.
ABSURD_G: float = 64.0
#: Stamps are bursty when 1/median(Δt) exceeds (N−1)/duration by this factor.
BURST_RATIO: float = 2.0
#: Stamps are coarse when more than this fraction of the steps repeat the previous stamp.
COARSE_REPEATED_FRACTION: float = 0.05
#: Plausible sampling rates of a recording, Hz (for a stated assumption on the time unit).
PLAUSIBLE_RATE_HZ: tuple[float, float] = (1.0, 100_000.0)
#: A ``rate`` that differs from a regular time column's rate by more than this fraction is warned about.
RATE_MISMATCH_FRACTION: float = 0.05

# exclusion counters (also the keys of ``PoseTable.exclusions``)
NON_FINITE = "non-finite samples (empty, non-numeric or truncated cells)"
ZERO_ROWS = "all-zero rows (an unfilled buffer)"
ABSURD = f"samples beyond any full scale (an axis above {ABSURD_G:g} g)"


@dataclass(frozen=True)
class TimeEvidence:
    """Statistics of a time column over the usable rows (in the column's own unit).

    Attributes
    ----------
    n : int
    duration : float
    median_step, min_positive_step : float
    repeated : int
        Steps of exactly zero (a repeated stamp).
    backwards : int
        Negative steps.
    first_backwards : int or None
        Index (into the usable rows) of the first sample after a negative step.
    regular_fraction : float
        Fraction of the steps within ±50 % of the median step (0 when the median step is not positive).
    """

    n: int
    duration: float
    median_step: float
    min_positive_step: float
    repeated: int
    backwards: int
    first_backwards: int | None
    regular_fraction: float = 0.0

    @property
    def mean_step(self) -> float:
        return self.duration / (self.n - 1) if self.n > 1 else float("nan")

    @property
    def repeated_fraction(self) -> float:
        return self.repeated / max(1, self.n - 1)

    @property
    def bursty(self) -> bool:
        """Host stamps in bursts: the typical step is far shorter than the mean step."""
        return self.n > 10 and self.median_step > 0 and self.median_step * BURST_RATIO < self.mean_step

    @property
    def coarse(self) -> bool:
        """Stamps coarser than the sampling: many samples share a stamp."""
        return self.n > 10 and self.repeated_fraction > COARSE_REPEATED_FRACTION


@dataclass(frozen=True)
class Evidence:
    """One pass of statistics over a :class:`~optcal.data.readers.Source`.

    Attributes
    ----------
    n_rows : int
    size_bytes : int
    usable : ndarray of bool
        Rows with finite accelerometer (and time, gyro, temperature) values, not all-zero,
        not absurd.
    non_finite, zero_rows, absurd : int
        Rows excluded for each reason.
    median_norm : float
        Median ‖a‖ over the usable rows, raw units.
    median_step : float
        Median ‖a_k+1 − a_k‖ over consecutive usable rows, raw units.
    time : TimeEvidence or None
    """

    n_rows: int
    size_bytes: int
    usable: NDArray[np.bool_]
    non_finite: int
    zero_rows: int
    absurd: int
    median_norm: float
    median_step: float
    time: TimeEvidence | None

    def exclusions(self) -> dict[str, int]:
        return {k: v for k, v in ((NON_FINITE, self.non_finite), (ZERO_ROWS, self.zero_rows), (ABSURD, self.absurd)) if v}


def gather_evidence(src: Source) -> Evidence:
    """The statistics every decision is made from, in one pass over the columns.

    Column by column, with no copy of the samples when every row is usable (the common
    case); the median norm over the usable rows is the one over the finite, non-zero rows
    when no row is absurd (one median, not two).
    """
    n = src.n_rows
    acc = [src.column(c) for c in ACC]  # column by column: no copy of the file's data
    finite = np.ones(n, dtype=bool)
    for name in (*ACC, "t", *GYRO, "temp"):
        if src.has(name):
            finite &= np.isfinite(src.column(name))
    zero = finite.copy()
    for name in (*ACC, *(GYRO if src.has(*GYRO) else ())):
        zero &= src.column(name) == 0.0
    ok = finite & ~zero
    every_ok = bool(ok.all())
    with np.errstate(over="ignore", invalid="ignore"):
        # the median norm ignores a few absurd cells; then an axis beyond ABSURD_G of it is absurd
        norm = acc[0] * acc[0]
        for a in acc[1:]:
            norm += a * a
        np.sqrt(norm, out=norm)
        med = median(norm if every_ok else norm[ok]) if ok.any() else float("nan")
        absurd = np.zeros(n, dtype=bool)
        if np.isfinite(med) and med > 0:
            for a in acc:
                absurd |= ok & (np.abs(a) > ABSURD_G * med)
    n_absurd = int(np.count_nonzero(absurd))
    usable = ok & ~absurd if n_absurd else ok
    every = every_ok and not n_absurd
    if usable.any():
        median_norm = med if not n_absurd else median(norm[usable])
        del norm
        with np.errstate(over="ignore", invalid="ignore"):  # values near the float limit
            step = np.zeros(max(0, int(np.count_nonzero(usable)) - 1))
            for a in acc:
                d = np.diff(a if every else a[usable])
                np.multiply(d, d, out=d)
                step += d
            np.sqrt(step, out=step)
        median_step = median(step, overwrite_input=True) if step.size else 0.0
        del step
    else:
        median_norm = median_step = float("nan")
    if src.has("t") and np.count_nonzero(usable) > 1:
        t = src.column("t")
        time = time_evidence(t if every else t[usable])
    else:
        time = None
    return Evidence(
        n_rows=n,
        size_bytes=src.size_bytes,
        usable=usable,
        non_finite=n - int(np.count_nonzero(finite)),
        zero_rows=int(np.count_nonzero(zero)),
        absurd=n_absurd,
        median_norm=median_norm,
        median_step=median_step,
        time=time,
    )


def time_evidence(t: NDArray[np.float64]) -> TimeEvidence:
    """Steps, repeats and reversals of a time column (one difference of the column, one median)."""
    d = np.diff(t)
    back = np.flatnonzero(d < 0)
    positive = d > 0
    med = median(d) if d.size else 0.0
    regular = float(np.mean(np.abs(d - med) <= 0.5 * med)) if med > 0 else 0.0
    return TimeEvidence(
        n=int(t.size),
        duration=float(t[-1] - t[0]),
        median_step=med,
        min_positive_step=float(d.min(where=positive, initial=np.inf)) if positive.any() else 0.0,
        repeated=int(np.count_nonzero(d == 0)),
        backwards=int(back.size),
        first_backwards=int(back[0] + 1) if back.size else None,
        regular_fraction=regular,
    )


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
    """

    kind: Decision
    columns: Decision
    units: Decision
    time_base: Decision
    rate: Decision
    layout: str = ""
    exclusions: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

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
        kind_flag = f"; {self.kind.flag}" if self.kind.flag else ""
        out = [
            f"kind: {self.kind.value} ({self.kind.reason}{kind_flag})",
            f"columns: {self.columns.value} ({self.columns.reason}; {self.columns.flag})",
            f"units: {self.units.value} ({self.units.reason}; {self.units.flag})",
        ]
        if self.kind.value == RAW_RECORDING:
            rate = "" if self.rate.value is None else f", {self.rate.value:.6g} Hz"
            out.append(f"time: {self.time_base.value}{rate} ({self.time_base.reason}; {self.time_base.flag})")
        elif self.time_base.value != "none":
            out.append(f"time: {self.time_base.reason}")
        if self.layout:
            out.append(f"read: {self.layout}")
        if self.exclusions:
            out.append("excluded while reading: " + "; ".join(f"{k}: {v}" for k, v in self.exclusions.items()))
        out.extend(f"warning: {w}" for w in self.warnings)
        return out


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
    """Decide kind, columns, units, time base and rate from the evidence (flags win).

    Parameters
    ----------
    src : Source
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
        A flag that contradicts the data (units against the norm), or evidence that does not
        settle a decision (named with the flag that does).
    """
    if kind not in KINDS:
        raise InputError(f"unknown kind {kind!r}; use one of {', '.join(KINDS)}")
    if timing not in TIMINGS:
        raise InputError(f"unknown timing {timing!r}; use one of {', '.join(TIMINGS)}")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise InputError(f"unknown time unit {time_unit!r}; use one of {', '.join(TIME_UNITS)}")
    if rate is not None and not rate > 0:
        raise InputError(f"rate must be positive, got {rate}")
    if not ev.usable.any():
        raise InputError(
            f"{src.path}: no usable sample (of {ev.n_rows} rows: "
            + "; ".join(f"{k}: {v}" for k, v in ev.exclusions().items()) + ")"
        )
    try:
        found = decide_units(None, units, src.units_hint, src.units_reason, norm=ev.median_norm)
        # the samples are gathered (a copy) only for counts, whose nominal 1 g comes from them
        one_g = nominal_conversion(found.units, _acc(src, ev.usable) if found.units == "counts" else None,
                                   median_norm=ev.median_norm).sensitivity
    except InputError:  # refused below, once the kind is known
        one_g = ev.median_norm
    warnings: list[str] = []
    if required_by is not None:
        if kind not in ("poses", "raw"):
            raise InputError(f"required_by needs kind 'poses' or 'raw', got {kind!r}")
        what = POSE_TABLE if kind == "poses" else RAW_RECORDING
        kind_decision = Decision(what, f"{required_by} requires a {what}", "")
    else:
        kind_decision = _decide_kind(src, ev, kind, one_g)
        if kind != "auto":
            warnings.extend(_kind_contradiction(src, ev, kind_decision, one_g))
    if kind_decision.value == POSE_TABLE:
        for canon, (count, row, value) in src.non_numeric.items():
            raise InputError(
                f"{src.path}: column {src.column_map.get(canon, canon)!r} has a non-numeric value "
                f"{value!r} on data row {row} ({count} such cell(s)); every cell of a pose table must be a number"
            )
    units_d = decide_units(None, units, src.units_hint, src.units_reason, norm=ev.median_norm)
    units_decision = Decision(units_d.units, units_d.reason, "--units")
    columns = Decision(src.describe_columns(), src.columns_reason, "--columns")
    if kind_decision.value == POSE_TABLE:
        if rate is not None:
            raise InputError(f"rate applies to raw recordings; {src.path} was read as a pose table ({kind_decision.reason})")
        time_base, rate_d = _pose_table_time(src, time_unit)
    else:
        time_base, rate_d = _recording_time(src, ev, rate, time_unit, timing)
        warnings.extend(_rate_contradiction(src, ev, rate, time_unit))
    return DataDecisions(
        kind_decision, columns, units_decision, time_base, rate_d, src.layout, ev.exclusions(), warnings
    )


def _kind_contradiction(src: Source, ev: Evidence, given: Decision, one_g: float) -> list[str]:
    """A warning when the evidence alone would read the file as the other kind (the user's choice is kept)."""
    try:
        auto = _decide_kind(src, ev, "auto", one_g)
    except InputError:
        return []
    if auto.value == given.value:
        return []
    return [
        f"read as a {given.value} as given, but the evidence says {auto.value}: {auto.reason}"
        + (f" ({int(ev.usable.sum())} rows would each be one pose)" if given.value == POSE_TABLE else "")
    ]


def _rate_contradiction(src: Source, ev: Evidence, rate: float | None, time_unit: str | None) -> list[str]:
    """A warning when a given rate contradicts a regular time column (the given rate is kept)."""
    te = ev.time
    if rate is None or te is None or not src.has("t") or te.backwards or not te.duration > 0 or te.n < RAW_MIN_ROWS:
        return []
    if time_unit is not None and src.time_unit is None:
        factor = TIME_UNITS[time_unit]
    else:
        factor = 1.0  # a unit named by the column is already in seconds
    rate_t = 1.0 / (te.mean_step * factor)  # (N−1)/duration: robust to bursty stamps
    if src.time_unit is None and time_unit is None and rate_t < PLAUSIBLE_RATE_HZ[0]:
        rate_t *= 1e3  # an unnamed column of ms stamps (as in the kind decision)
    if abs(rate / rate_t - 1.0) <= RATE_MISMATCH_FRACTION:
        return []
    return [
        f"the given rate {rate:g} Hz differs by {100 * abs(rate / rate_t - 1.0):.0f} % from the time column "
        f"{src.column_map.get('t', 't')!r} ({te.n} rows over {te.duration * factor:.6g} s: {rate_t:.4g} Hz); "
        "the given rate is used (drop rate= to use the time column)"
    ]


def _acc(src: Source, rows: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The accelerometer samples of ``rows`` (n, 3); a view of the file's columns when every row is taken."""
    if rows.all():
        return columns_block(src, ACC)
    return np.column_stack([src.column(c)[rows] for c in ACC])


def _decide_kind(src: Source, ev: Evidence, requested: str, one_g: float) -> Decision:
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
    step = f"consecutive rows differ by {100 * ratio:.2g} % of 1 g (median)"
    te = ev.time
    if te is not None and te.n >= RAW_MIN_ROWS and te.duration > 0:
        # the rate a time column in seconds would give (or in the unit its name states)
        rate_s = 1.0 / te.mean_step
        if src.time_unit is None and rate_s < PLAUSIBLE_RATE_HZ[0]:
            rate_s = 1e3 / te.mean_step  # an unnamed column of ms stamps; seconds are decided later
        regular = te.backwards == 0 and (te.bursty or te.coarse or _regular(te))
        if regular and rate_s >= RAW_MIN_RATE_HZ:
            return Decision(
                RAW_RECORDING,
                f"a regular time column ({te.n} rows at {rate_s:.4g} Hz on average), {step}",
                flag,
            )
    if n < 3:
        return Decision(POSE_TABLE, "too few rows for a recording", flag)
    if ratio < RAW_STEP_RATIO:
        return Decision(RAW_RECORDING, f"{step}, as samples of a time series do", flag)
    if ratio > POSE_STEP_RATIO and n <= MANY_ROWS:
        return Decision(POSE_TABLE, f"{step}, as different poses do ({n} rows)", flag)
    if n > MANY_ROWS:
        return Decision(RAW_RECORDING, f"{n} rows with no per-pose columns (a pose table has tens to hundreds), {step}", flag)
    raise InputError(
        f"{src.path}: cannot tell a pose table from a raw recording: {step} (between the "
        f"≤ {100 * RAW_STEP_RATIO:g} % of a time series and the ≥ {100 * POSE_STEP_RATIO:g} % of distinct poses) "
        f"over {n} rows" + ("" if te is None else ", and the time column is irregular")
        + "; pass --format raw or --format poses"
    )


def _regular(te: TimeEvidence) -> bool:
    """Steps within ±50 % of their median for 90 % of the samples (a sampled time series)."""
    return te.median_step > 0 and te.regular_fraction >= 0.9


def _refuse_backwards(src: Source, ev: Evidence, t: NDArray[np.float64], what: str) -> None:
    """Refuse a time (or sample index) column that runs backwards among the usable rows."""
    rows = np.flatnonzero(ev.usable & np.isfinite(t))
    back = np.flatnonzero(np.diff(t[rows]) < 0)
    if back.size:
        i, j = rows[back[0]], rows[back[0] + 1]
        raise InputError(
            f"{src.path}: {what} runs backwards at data row {j + 1} ({t[j]:.6g} after "
            f"{t[i]:.6g} on row {i + 1}; {back.size} such step(s)); the file may be several "
            "logs joined together: split or sort it"
        )


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
        if rate_used is None:
            raise InputError(
                f"{src.path}: no time column and no sampling rate; pass --rate HZ "
                "(or add a time column t_s, or map one with --columns t=NAME or t=POSITION)"
            )
        why = "--rate" if rate is not None else src.rate_reason
        what = f"column {src.column_map['index']!r}" if src.has("index") else "row number"
        if src.has("t"):
            why += ", instead of the time column"
        if src.has("index"):
            _refuse_backwards(src, ev, src.column("index"), f"column {src.column_map['index']!r}")
        return Decision("rate", f"{what} / {rate_used:g} Hz ({why})", "--rate"), Decision(float(rate_used), why, "--rate")
    te = ev.time
    t = src.column("t")
    if te is None:
        raise InputError(f"{src.path}: fewer than two usable samples with a time")
    if te.backwards:  # the evidence counted the steps back among the usable rows
        _refuse_backwards(src, ev, t, "time")
    # the unit
    if time_unit is not None:
        if src.time_unit is not None and src.time_unit != time_unit:
            raise InputError(f"{src.path}: time_unit {time_unit} contradicts the column name ({src.time_reason})")
        factor, unit_why = TIME_UNITS[time_unit], f"in {time_unit} (given with --time-unit)"
    elif src.time_unit is not None:
        factor, unit_why = 1.0, src.time_reason.split(" (")[0].removeprefix(f"column {src.column_map['t']!r} ")
    else:
        factor, unit_why = 1.0, "in seconds"
        rate_s = 1.0 / te.mean_step if te.mean_step > 0 else float("inf")
        if rate_s < PLAUSIBLE_RATE_HZ[0] and te.n >= RAW_MIN_ROWS:
            for unit in ("ms", "us", "ns"):
                r = rate_s / TIME_UNITS[unit]
                if PLAUSIBLE_RATE_HZ[0] <= r <= PLAUSIBLE_RATE_HZ[1]:
                    factor = TIME_UNITS[unit]
                    unit_why = (
                        f"in {unit}: an assumption, since in seconds {te.n} samples would come at "
                        f"{rate_s:.3g} Hz; pass --time-unit s to keep seconds"
                    )
                    break
    if factor != 1.0:
        t = t * factor
        src.data["t"] = t
    mean_step = te.mean_step * factor
    median_step = te.median_step * factor
    name = f"column {src.column_map['t']!r} {unit_why}"
    irregular = te.bursty or te.coarse
    if timing == "uniform" or (timing == "auto" and irregular and mean_step > 0):
        if not mean_step > 0:
            raise InputError(f"{src.path}: the time column does not advance; pass --rate HZ")
        rows = np.flatnonzero(ev.usable)
        t_new = np.full(t.size, np.nan)
        t_new[rows] = t[rows[0]] + np.arange(rows.size) * mean_step
        src.data["t"] = t_new
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
        reason = f"{name}; samples spread evenly over the stamped span: {why}"
        return Decision("uniform", reason, "--timing"), Decision(
            1.0 / mean_step, f"(N−1)/duration = {te.n - 1}/{te.duration * factor:.6g} s", "--rate"
        )
    rate_hz = 1.0 / median_step if median_step > 0 else float("nan")
    return Decision("stamps", name, "--timing"), Decision(rate_hz, "1/median time step", "--rate")
