"""The typed reading API: :class:`ReadOptions` (every DATA flag in one place) and :class:`Reading`.

:func:`read` is the one path from a file to what optcal fits: **read** the file
(:mod:`optcal.data.readers`), gather the **evidence** (:mod:`optcal.data.evidence`), make
the **decisions** (:mod:`optcal.data.decisions`, each with its reason and the flag that
overrides it), **convert** (a pose table, or a :class:`~optcal.data.recording.Recording`)
and, for a recording, **segment** it into static poses (:mod:`optcal.data.static`).  Every
command, ``apply``, the pose tables and the fleet read DATA through it; the command line
builds its :class:`ReadOptions` from the flags in :mod:`optcal.cli.data_options`.

Example
-------
>>> import optcal                                                    # doctest: +SKIP
>>> r = optcal.load("still_log.csv", rate=100)                       # doctest: +SKIP
>>> r.kind, r.poses.n, r.exclusions                                  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from optcal.core.poses import PoseTable
from optcal.core.stats import rms
from optcal.data.decisions import KINDS, POSE_TABLE, TIMINGS, TIME_UNITS, DataDecisions, Decision, decide, with_decisions
from optcal.data.evidence import Evidence, gather_evidence
from optcal.data.readers import Source, read_source
from optcal.data.recording import Recording, recording_from_source
from optcal.data.rest_model import MAX_GYRO_BIAS_RAD_S
from optcal.data.static import Segmentation, StaticSettings, detect_static
from optcal.data.units import check_sensitivity
from optcal.errors import InputError

__all__ = ["MAX_RATE_HZ", "READ_FIELDS", "STATIC_FIELDS", "Reading", "ReadOptions", "read", "read_options"]

#: Highest sampling rate accepted (Hz).  MEMS inertial sensors output at most tens of kHz; this bound, 10³ above
#: that, only protects the time base ``row / rate`` from overflowing or collapsing to steps below a float's
#: resolution (``--rate 1e308``), never a real recording's rate.
MAX_RATE_HZ = 1e7

#: The static-detection settings a :class:`ReadOptions` override may name (the fields of
#: :class:`~optcal.data.static.StaticSettings`).
STATIC_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(StaticSettings))

#: The gyro units a :class:`ReadOptions` may state (``None``: decided from the data).
GYRO_UNITS: tuple[str, ...] = ("rad/s", "deg/s", "counts")


@dataclass(frozen=True)
class ReadOptions:
    """How to read DATA: every reading flag of the command line, typed and validated.

    Each field left at its default lets the evidence decide (and say why); a value given
    overrides that decision, and the decision then says it was given.

    Attributes
    ----------
    columns : str or dict or None
        ``"ax=NAME,ay=NAME,az=NAME,t=NAME,..."`` or 1-based positions (``"t=1,ax=2,ay=3,az=4"``)
        (``--columns``).
    units : {"g", "m/s^2", "counts"} or None
        Units of the accelerometer data (``--units``).
    topic : str or None
        ROS topic, ULog topic (``sensor_accel[:N]``, ``sensor_combined``) or MAT/netCDF/HDF5 variable (``--topic``).
    rate : float or None
        Sampling rate, Hz, of a recording without a time column (``--rate``); finite, positive,
        at most :data:`MAX_RATE_HZ`.
    kind : {"auto", "poses", "raw"}
        Read DATA as a pose table or a raw recording (``--format``).
    time_unit : {"s", "ms", "us", "ns"} or None
        Unit of a time column whose name does not say it (``--time-unit``).
    timing : {"auto", "stamps", "uniform"}
        Keep the stamps or spread the samples evenly over the stamped span (``--timing``).
    gyro_file : str or Path or None
        A second text file ``t gx gy gz`` merged on time (``--gyro-file``).
    gyro_units : {"rad/s", "deg/s", "counts"} or None
        Units of the gyro columns (``--gyro-units``); ``None`` decides them from the data.
    keep_gyro_rail : bool
        Keep the gyro's samples at a saturation rail (``--keep-gyro-rail``; by default they enter no rest and the
        moves holding them are left out of the gyro's fit: :mod:`optcal.data.rails`).
    keep_unhealthy : bool
        Keep the samples a log flags unhealthy (ArduPilot's ``AH``/``GH`` = 0; ``--keep-unhealthy``; by default
        counted and left out, an ``AH`` = 0 row whole, a ``GH`` = 0 row's gyro sample: :mod:`optcal.data.dataflash`).
    keep_clipped : bool
        Keep the samples a log's own clip flags mark (ArduPilot's ``VIBE.Clip`` rises, PX4's ``clip_counter``;
        ``--keep-clipped``; by default they are saturated samples, counted); rails in the values are still sought.
    keep_held : bool
        Keep every row where the accelerometer's value is held over several rows of a faster log (``--keep-held``;
        by default the first row of each update is kept and the repeats counted: :mod:`optcal.data.held_samples`).
    gyro_range_dps : float or None
        The gyro's full scale, ±°/s (``--gyro-range``): where the gyro's unit is not known, a rail of it is sought
        beyond a rest's largest reading as that share of the full scale (:func:`optcal.data.rails.gyro_rail`).
    static : StaticSettings
        The rest detector's settings (``--static-window``, ``--static-threshold``,
        ``--gyro-threshold``, ``--drift-threshold``, ``--min-dwell``, ``--trim``,
        ``--no-gyro-gate``, ``--min-independent``).

    Raises
    ------
    InputError
        A value out of its range or not finite, naming the field.
    """

    columns: str | dict[str, str] | None = None
    units: str | None = None
    topic: str | None = None
    rate: float | None = None
    kind: str = "auto"
    time_unit: str | None = None
    timing: str = "auto"
    gyro_file: str | Path | None = None
    gyro_units: str | None = None
    keep_gyro_rail: bool = False
    keep_unhealthy: bool = False
    keep_clipped: bool = False
    keep_held: bool = False
    gyro_range_dps: float | None = None
    static: StaticSettings = field(default_factory=StaticSettings)

    def __post_init__(self) -> None:
        if self.rate is not None:
            rate = _number("rate", self.rate)
            if not 0 < rate <= MAX_RATE_HZ:
                raise InputError(f"rate must be a positive sampling rate of at most {MAX_RATE_HZ:g} Hz, got {self.rate!r} (--rate)")
            object.__setattr__(self, "rate", rate)
        if self.gyro_range_dps is not None:
            full_scale = _number("gyro_range_dps", self.gyro_range_dps)
            largest_bias_dps = math.degrees(MAX_GYRO_BIAS_RAD_S)  # a full scale a rest can reach is no gyro's
            if not full_scale > largest_bias_dps:
                raise InputError(f"gyro_range_dps must be a full scale beyond a MEMS gyro's largest bias, "
                                 f"{largest_bias_dps:g} °/s, got {self.gyro_range_dps!r} (--gyro-range)")
            object.__setattr__(self, "gyro_range_dps", full_scale)
        if self.kind not in KINDS:
            raise InputError(f"unknown kind {self.kind!r}; use one of {', '.join(KINDS)} (--format)")
        if self.timing not in TIMINGS:
            raise InputError(f"unknown timing {self.timing!r}; use one of {', '.join(TIMINGS)} (--timing)")
        if self.time_unit is not None and self.time_unit not in TIME_UNITS:
            raise InputError(f"unknown time unit {self.time_unit!r}; use one of {', '.join(TIME_UNITS)} (--time-unit)")
        if self.gyro_units is not None and self.gyro_units not in GYRO_UNITS:
            raise InputError(f"unknown gyro units {self.gyro_units!r}; use one of {', '.join(GYRO_UNITS)} (--gyro-units)")
        if self.gyro_file is not None:
            object.__setattr__(self, "gyro_file", str(self.gyro_file))
        if not isinstance(self.static, StaticSettings):
            raise InputError(f"static must be a StaticSettings, got {type(self.static).__name__}")
        for name in ("window_s", "threshold", "gyro_threshold", "drift_threshold", "min_dwell_s", "trim_s",
                     "min_independent", "max_gap_s"):
            value = getattr(self.static, name)
            if value is not None:
                _number(name, value)

    @classmethod
    def build(cls, options: "ReadOptions | None" = None, **overrides: Any) -> "ReadOptions":
        """``options`` (or the defaults) with ``overrides`` applied: any field, or a static setting by name.

        Parameters
        ----------
        options : ReadOptions, optional
        **overrides
            A field of :class:`ReadOptions` (``rate=100``), or a setting of
            :class:`~optcal.data.static.StaticSettings` (``min_dwell_s=1.0``); ``None`` leaves it
            as it is.

        Raises
        ------
        InputError
            An unknown keyword (naming the valid ones), or a value out of its range.
        """
        base = options if options is not None else cls()
        if not isinstance(base, ReadOptions):
            raise InputError(f"options must be a ReadOptions, got {type(base).__name__}")
        unknown = sorted(set(overrides) - set(READ_FIELDS) - set(STATIC_FIELDS))
        if unknown:
            raise InputError(
                f"unknown reading option(s) {', '.join(unknown)}; valid: {', '.join(READ_FIELDS + STATIC_FIELDS)}"
            )
        fields = {k: v for k, v in overrides.items() if k in READ_FIELDS and v is not None}
        static = {k: v for k, v in overrides.items() if k in STATIC_FIELDS and v is not None}
        if static:
            if "static" in fields:
                raise InputError("give the static-detection settings either as static= or as keywords, not both")
            for name, value in static.items():
                if not isinstance(value, bool):
                    _number(name, value)
            fields["static"] = dataclasses.replace(base.static, **static)
        return dataclasses.replace(base, **fields) if fields else base

    def describe(self) -> dict[str, Any]:
        """The options given (not at their defaults), JSON-safe."""
        default = ReadOptions()
        out: dict[str, Any] = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                               if f.name != "static" and getattr(self, f.name) != getattr(default, f.name)}
        out.update({k: v for k, v in dataclasses.asdict(self.static).items() if v != getattr(default.static, k)})
        return out


#: The fields of :class:`ReadOptions` (``static`` included).
READ_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(ReadOptions))


#: The command-line flag of each numeric reading option (named in its messages).
FLAGS: dict[str, str] = {
    "rate": "--rate", "window_s": "--static-window", "threshold": "--static-threshold",
    "gyro_threshold": "--gyro-threshold", "drift_threshold": "--drift-threshold", "min_dwell_s": "--min-dwell",
    "trim_s": "--trim", "min_independent": "--min-independent", "gyro_range_dps": "--gyro-range",
}


def _number(name: str, value: Any) -> float:
    """``value`` as a finite float, or an :class:`InputError` naming ``name`` and its flag."""
    flag = f" ({FLAGS[name]})" if name in FLAGS else ""
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a number, got {value!r}{flag}") from None
    if not math.isfinite(number):
        raise InputError(f"{name} must be finite, got {value!r}{flag}")
    return number


@dataclass(frozen=True)
class Reading:
    """What :func:`read` made of DATA: the poses, and how they were made.

    Attributes
    ----------
    path : str
        DATA as given.
    options : ReadOptions
        The options it was read with.
    decisions : DataDecisions
        Every decision (kind, columns, units, time base, rate) with its reason and the flag
        that overrides it (``decisions.lines()`` prints them), and the warnings of overrides
        the evidence contradicts.
    poses : PoseTable
        The static poses (a pose table's rows, or the rests of a recording); every excluded
        row, sample or pose is counted in ``poses.exclusions``.
    recording : Recording or None
        The samples of a raw recording (``None`` for a pose table).
    segmentation : Segmentation or None
        The static detection of a raw recording.
    """

    path: str
    options: ReadOptions
    decisions: DataDecisions
    poses: PoseTable
    recording: Recording | None = field(default=None, repr=False)
    segmentation: Segmentation | None = field(default=None, repr=False)

    @property
    def kind(self) -> Decision:
        """The kind decision: ``value`` ``"pose table"`` or ``"raw recording"``, and its ``reason``."""
        return self.decisions.kind

    @property
    def evidence(self) -> Evidence | None:
        """The evidence the decisions were made from."""
        return self.decisions.evidence

    @property
    def exclusions(self) -> dict[str, int]:
        """Every excluded row, sample or pose, counted by reason."""
        return dict(self.poses.exclusions)

    def lines(self) -> list[str]:
        """Every decision with its reason, as the command line prints them."""
        return self.decisions.lines()


def read_options(**overrides: Any) -> ReadOptions:
    """:class:`ReadOptions` from keywords (see :meth:`ReadOptions.build`)."""
    return ReadOptions.build(None, **overrides)


def read_decided(path: str | Path, options: ReadOptions, *, required_by: str | None = None,
                 kind: str | None = None) -> tuple[Source, DataDecisions]:
    """Read DATA and make the decisions: the first two steps of :func:`read`, for a caller that converts itself.

    Parameters
    ----------
    path : str or Path
    options : ReadOptions
    required_by : str, optional
        What needs the kind asked for (the kind decision's reason, e.g. ``"the allan command"``).
    kind : {"auto", "poses", "raw"}, optional
        Overrides ``options.kind`` (a command that takes only one kind).
    """
    src = read_source(path, columns=options.columns, topic=options.topic, gyro_file=options.gyro_file,
                      keep_unhealthy=options.keep_unhealthy, keep_clipped=options.keep_clipped)  # read
    if options.gyro_units is not None:  # the user's unit wins over the file's words and the data (the rest
        src.gyro_units = options.gyro_units  # model's tolerances, the segment report and the gyro fit read it)
    decisions = decide(  # evidence, then decisions
        src, gather_evidence(src), kind=kind or options.kind, units=options.units, rate=options.rate,
        time_unit=options.time_unit, timing=options.timing, required_by=required_by,
    )
    return src, decisions


def read_recording(path: str | Path, options: ReadOptions | None = None, *, required_by: str = "reading a recording",
                   **overrides: Any) -> Recording:
    """Read a raw recording's samples (no segmentation), as :func:`read` would.

    Parameters
    ----------
    path : str or Path
    options : ReadOptions, optional
    required_by : str
        What needs the raw recording (the kind decision's reason).
    **overrides
        As for :meth:`ReadOptions.build`.
    """
    options = ReadOptions.build(options, **overrides)
    src, decisions = read_decided(path, options, required_by=required_by, kind="raw")
    return recording_from_source(src, decisions, keep_gyro_rail=options.keep_gyro_rail,
                                gyro_range_dps=options.gyro_range_dps, keep_held=options.keep_held)  # conversion


def read(path: str | Path, options: ReadOptions | None = None, **overrides: Any) -> Reading:
    """Read DATA, a pose table or a raw recording, the one way every command does.

    Parameters
    ----------
    path : str or Path
        CSV/text, Parquet, MAT/netCDF/HDF5, ROS 1 bag, ROS 2 bag (directory), or PX4 ULog.
    options : ReadOptions, optional
        The reading options (default: every decision from the evidence).
    **overrides
        Any field of :class:`ReadOptions` (``rate=100``, ``units="counts"``, ``kind="raw"``)
        or static-detection setting (``min_dwell_s=1``) over ``options``.

    Returns
    -------
    Reading
        The poses, the decisions with their reasons, the recording and its segmentation;
        every excluded row, sample or pose counted.

    Raises
    ------
    InputError
        An unknown keyword (naming the valid ones), a value out of range, an unreadable file,
        or DATA refused (a :class:`~optcal.data.decisions.DataInputError` carrying the
        decisions made before).
    """
    options = ReadOptions.build(options, **overrides)
    src, decisions = read_decided(path, options)
    stated = options.units is not None or src.units_hint is not None  # the unit given, not decided from magnitudes
    try:
        if decisions.kind.value == POSE_TABLE:
            from optcal.data.tables import pose_table_from_source

            poses = pose_table_from_source(src, decisions)  # conversion
            check_sensitivity(poses.acc, poses.units, stated=stated)  # the units and columns decisions, checked on the poses
            return Reading(str(path), options, decisions, poses)
        rec = recording_from_source(src, decisions, keep_gyro_rail=options.keep_gyro_rail,
                                gyro_range_dps=options.gyro_range_dps, keep_held=options.keep_held)  # conversion
        del src  # the recording holds its own arrays: free the file's columns before segmenting
        check_static_settings(options.static, rec)
        seg = detect_static(rec, options.static)  # segmentation
        decisions.warnings.extend(seg.override_warnings())  # an override says what it assumes, on the error path too
        table = seg.pose_table()
        # the units and columns decisions, checked on the poses and their noise
        check_sensitivity(table.acc, table.units, noise=[rms(iv.std) for iv in seg.intervals], stated=stated)
    except InputError as exc:
        raise with_decisions(exc, decisions) from exc
    table.meta.update(recording_meta(rec, decisions))
    table.decisions = decisions
    return Reading(str(path), options, decisions, table, rec, seg)


def check_static_settings(static: StaticSettings, rec: Recording) -> None:
    """Refuse rest-detection durations that no rest of ``rec`` can satisfy (longer than the whole recording).

    A rest can be no longer than the recording: a longer ``--min-dwell``, ``--static-window`` or twice
    ``--trim`` finds nothing by definition (and used to run for minutes before saying so).

    Raises
    ------
    InputError
        Naming the flag, its value and the recording's length.
    """
    duration = float(rec.duration_s)
    for value, flag in ((static.min_dwell_s, "--min-dwell"), (static.window_s, "--static-window"),
                        (2 * static.trim_s, "--trim (twice, from both ends)")):
        if value > duration:
            raise InputError(f"{flag} {value:g} s is longer than the recording ({duration:.4g} s): no rest can be "
                             f"found; give a shorter {flag.split()[0]}")


def recording_meta(rec: Recording, decisions: DataDecisions) -> dict[str, Any]:
    """Provenance of a recording for ``PoseTable.meta``."""
    return {
        "path": rec.path,
        "file_type": rec.file_type,
        "kind_reason": decisions.kind.reason,
        "units_reason": rec.units_reason,
        "time": rec.time_reason,
        "rate_hz": rec.rate_hz,
        "duration_s": rec.duration_s,
        "n_usable": rec.n_usable,
        "decisions": decisions.to_dict(),
        **rec.meta,
    }
