"""Readers (the *read* step): delimited text, Parquet, ROS 1/ROS 2 bags and PX4 ULog into one form.

Every reader returns a :class:`Source`: the data under optcal's canonical column names
(:data:`CANONICAL`), with what the file itself says about units, sampling rate and
saturation.  Deciding whether the data are a pose table or a raw recording, and turning
them into a :class:`~optcal.core.poses.PoseTable`, happens in :mod:`optcal.data`.

Text files are laid out by :mod:`optcal.data.text` (any delimiter, decimal commas, a header
row or a comment line naming the columns, or no header: a headerless file's columns are
taken by the common layout of their number, :func:`optcal.data.columns.headerless_mapping`).
Column names are matched by :mod:`optcal.data.columns` (case-insensitively, after removing
a unit word: ``acc_x_counts`` → ``acc_x`` in counts, ``t_s`` → ``t`` in seconds, ``gyr_x`` →
``gx``); ``--columns ax=ACC1,ay=ACC2,...`` maps any other names.  Columns whose names do not
settle their roles are recorded as :class:`~optcal.data.columns.ColumnRoles` for the evidence.  The file type is recognised from
its first bytes (ULog, ROS 1 bag, Parquet, SQLite/MCAP ROS 2 bag) or, for a directory, from
its ROS 2 ``metadata.yaml``; everything else is read as delimited text.  ROS bags need
``pip install 'optcal[ros]'`` (the ``rosbags`` library), ULog files ``pip install 'optcal[px4]'``
(``pyulog``); both are imported only when such a file is read.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.data.columns import (
    ACC,
    ALIASES,
    CANONICAL,
    GYRO,
    GYRO_UNIT_WORDS,
    MAG,
    MAG_ALIASES,
    NO_COLUMN,
    RATE_KEYS,
    RATE_SETTING,
    TIME_UNITS,
    ColumnRoles,
    attribute_mapping,
    headerless_mapping,
    partial_gyro,
    joined_stamp_note,
    normalise_name,
    parse_columns_option,
    resolve_columns,
    sensor_logger_mapping,
    split_stamp,
    strip_unit,
)
from optcal.data.container_kind import container_type
from optcal.data.gyro_merge import gyro_onto_times
from optcal.data.ulog import TRUNCATED_MESSAGE, read_ulog_imu, ulog_is_cut
from optcal.data.quantiles import median
from optcal.core.units import UNIT_ALIASES, normalise_units

__all__ = [  # the column names, for the modules and tests that read them here
    "ACC", "ALIASES", "CANONICAL", "GYRO", "GYRO_UNIT_WORDS", "NO_COLUMN", "RATE_KEYS", "TIME_UNITS",
    "ColumnRoles", "Source", "detect_file_type", "merge_gyro_file", "parse_columns_option",
    "open_rosbag", "read_parquet", "read_rosbag", "read_source", "read_text", "read_ulog", "resolve_columns",
    "source_from_columns", "source_from_frame", "ulog_is_cut",
]

ROS_IMU_TYPE = "sensor_msgs/msg/Imu"
ROS_TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"


class GyroOnlyColumns(InputError):
    """A file whose columns name a gyroscope and no accelerometer; ``source`` holds what was read (time and gyro).

    Refused by every reader of an accelerometer's recording; :func:`optcal.data.gyro_log.read_gyro_recording`
    takes the source and reads the gyro alone (``optcal allan FILE --sensor gyro``).
    """

    def __init__(self, message: str, source: "Source") -> None:
        super().__init__(message)
        self.source = source


@dataclass
class Source:
    """Data read from a file, under canonical column names (the *read* step).

    Attributes
    ----------
    path : str
    file_type : str
        ``"csv"``, ``"parquet"``, ``"ros1 bag"``, ``"ros2 bag"``, ``"ulog"`` or ``"dataflash"``.
    data : dict of str to ndarray
        Canonical columns (a subset of :data:`CANONICAL` plus ``index``) as floats; cells
        that were not numbers are NaN and counted in :attr:`non_numeric`.
    extra : dict of str to ndarray
        Further numeric columns of the file, under their own names.
    column_map : dict of str to str
        Canonical name → the file's column name (or ``#N`` for the N-th field of a file
        without a header).
    columns_reason : str
        How the columns were matched (header names, positions, ``--columns``).
    ignored_columns : list of str
        Columns neither mapped nor numeric (e.g. a text label column).
    units_hint, units_reason : str or None, str
        Accelerometer units stated by the file (a unit word in the column names, or the
        format's convention), and where that came from.
    gyro_units : str or None
    rate_hint, rate_reason : float or None, str
        Sampling rate stated by the file (e.g. an ``Fs,100`` metadata line).
    time_unit, time_reason : str or None, str
        Unit of the time column as the file states it (a unit word, or the format), and
        how it was read; ``None`` when nothing states it (decided in :mod:`optcal.data.decisions`).
    header : dict of str to str
        Metadata lines found above the header row.
    layout : str
        How a text file is laid out (delimiter, decimal mark, header), for reports.
    non_numeric : dict of str to tuple
        Canonical column → (number of non-numeric cells, first data row, first value).
    saturated, gyro_saturated : ndarray of bool or None
        Per-row saturation flags of the accelerometer and the gyro stated by the file (ULog clip counters).
    always_raw : bool
        The format holds time series only (bags, ULog).
    size_bytes : int
        Size of the file (evidence for the kind of data).
    notes : list of str
    exclusions : dict of str to int
        What the reader could not use, counted (e.g. a message cut off by truncation).
    roles : ColumnRoles or None
        Columns whose names do not settle their roles (a file without a header, ``tx, ty,
        tz``), read in the common layout; the decisions read them as the evidence says.
    gyro_unhealthy : ndarray of bool or None
        Rows whose gyro sample the file marks unusable while their accelerometer sample is sound (a DataFlash
        ``GH`` = 0): the row is kept, its gyro sample left out of the gyro's use (counted by the reader).
    """

    path: str
    file_type: str
    data: dict[str, NDArray[np.float64]]
    extra: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    column_map: dict[str, str] = field(default_factory=dict)
    columns_reason: str = "header names"
    ignored_columns: list[str] = field(default_factory=list)
    units_hint: str | None = None
    units_reason: str = ""
    gyro_units: str | None = None
    rate_hint: float | None = None
    rate_reason: str = ""
    time_unit: str | None = None
    time_reason: str = ""
    header: dict[str, str] = field(default_factory=dict)
    layout: str = ""
    non_numeric: dict[str, tuple[int, int, str]] = field(default_factory=dict)
    saturated: NDArray[np.bool_] | None = None
    gyro_saturated: NDArray[np.bool_] | None = None
    always_raw: bool = False
    size_bytes: int = 0
    notes: list[str] = field(default_factory=list)
    exclusions: dict[str, int] = field(default_factory=dict)
    roles: ColumnRoles | None = None
    gyro_unhealthy: NDArray[np.bool_] | None = None

    @property
    def n_rows(self) -> int:
        return int(next(iter(self.data.values())).size) if self.data else 0

    def has(self, *names: str) -> bool:
        """Whether every canonical column in ``names`` is present."""
        return all(n in self.data for n in names)

    def column(self, name: str) -> NDArray[np.float64]:
        return self.data[name]

    def describe_columns(self) -> str:
        """``ax←acc_x_counts, ...`` for reports."""
        return ", ".join(f"{k}←{v}" for k, v in self.column_map.items() if k != v) or "as named"

    def block(self, names: tuple[str, ...]) -> NDArray[np.float64]:
        """The columns ``names`` as one (n, k) array in column-major (Fortran) order.

        Each column is contiguous, so the column-by-column statistics of the static detection and
        the per-interval means read contiguous memory.  When the columns are already adjacent
        columns, in this order, of one column-major block (a large text file is parsed into one,
        :class:`optcal.data.text.ColumnBlock`), the result is a view of that block: no copy.
        """
        view = self._adjacent([self.column(name) for name in names])
        if view is not None:
            return view
        block = np.empty((self.n_rows, len(names)), order="F")
        for j, name in enumerate(names):
            block[:, j] = self.column(name)
        return block

    @staticmethod
    def _adjacent(cols: list[NDArray[np.float64]]) -> NDArray[np.float64] | None:
        """``base[:n, k:k + len(cols)]`` when ``cols`` are those columns of one column-major base, else ``None``."""
        base = cols[0].base
        if not isinstance(base, np.ndarray) or base.ndim != 2 or not base.flags.f_contiguous or base.dtype != np.float64:
            return None
        n = cols[0].size
        start = base.__array_interface__["data"][0]
        stride = base.strides[1]
        first = cols[0].__array_interface__["data"][0] - start
        if n > base.shape[0] or first % stride:
            return None
        k = first // stride
        for j, col in enumerate(cols):
            if (col.base is not base or col.ndim != 1 or col.size != n or col.strides != (8,)
                    or col.__array_interface__["data"][0] - start != (k + j) * stride):
                return None
        if k + len(cols) > base.shape[1]:
            return None
        return base[:n, k:k + len(cols)]

    def with_accelerometer(self, k: int) -> Source:
        """This source read with candidate triple ``k`` of :attr:`roles` as the accelerometer (and the
        other as the gyroscope): a copy that shares the arrays."""
        if self.roles is None or k == self.roles.acc:
            return self
        by_name = {self.column_map[c]: self.data[c] for c in (*ACC, *GYRO) if c in self.data}
        data, column_map = dict(self.data), dict(self.column_map)
        for i, names in enumerate(self.roles.triples):
            for canon, name in zip(ACC if i == k else GYRO, names):
                data[canon], column_map[canon] = by_name[name], name
        order = [c for c in self.column_map]  # the columns listed as before
        roles = ColumnRoles(self.roles.triples, k, self.roles.layout, self.roles.conditional)
        return replace(self, data=data, column_map={c: column_map[c] for c in order}, roles=roles)

    def assign_accelerometer(self, k: int) -> None:
        """Read candidate triple ``k`` of :attr:`roles` as the accelerometer from now on (in place)."""
        other = self.with_accelerometer(k)
        self.data, self.column_map, self.roles = other.data, other.column_map, other.roles


# ----------------------------------------------------------------------------- file types

#: The first bytes of an ArduPilot DataFlash log: its message header (0xA3 0x95) and the id of the FMT message
#: (0x80) that every log opens with, describing itself (ArduPilot's libraries/AP_Logger/LogStructure.h).
DATAFLASH_HEAD = b"\xa3\x95\x80"


def detect_file_type(path: str | Path) -> str:
    """Recognise the file type from its first bytes (or a directory's ROS 2 metadata)."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or directory")
    if p.is_dir():
        if (p / "metadata.yaml").exists():
            return "ros2 bag"
        raise InputError(f"{p}: is a directory but not a ROS 2 bag (no metadata.yaml); give a data file")
    with p.open("rb") as fh:
        head = fh.read(16)
    if head.startswith(b"ULog"):
        return "ulog"
    if head.startswith(b"#ROSBAG V2.0"):
        return "ros1 bag"
    if head[:3] == DATAFLASH_HEAD:
        return "dataflash"
    if head.startswith(b"PAR1") or p.suffix.lower() in (".parquet", ".pq"):
        return "parquet"
    if head.startswith(b"SQLite format 3") or head.startswith(b"\x89MCAP"):
        return "ros2 bag"
    if p.suffix.lower() in (".bag", ".ulg", ".db3", ".mcap"):
        raise InputError(f"{p}: the file is truncated or corrupt (its header is not a valid {p.suffix} header)")
    return "csv"


def read_source(
    path: str | Path,
    columns: str | dict[str, str] | None = None,
    topic: str | None = None,
    gyro_file: str | Path | None = None,
    *,
    keep_unhealthy: bool = False,
    keep_clipped: bool = False,
) -> Source:
    """Read any supported file into a :class:`Source`.

    Parameters
    ----------
    path : str or Path
        CSV/text, Parquet, ROS 1 bag file, ROS 2 bag directory (or its ``.db3``/``.mcap``),
        PX4 ULog file, or ArduPilot DataFlash log.
    columns : str or dict, optional
        ``"ax=acc1,ay=acc2,az=acc3,t=time"``: the file's names (or 1-based positions,
        ``"t=1,ax=2"``) for canonical columns (tabular files only).
    topic : str, optional
        ROS topic of ``sensor_msgs/Imu`` messages, the ULog topic (``sensor_accel`` or
        ``sensor_accel:1`` for the second instance), or the DataFlash messages (``IMU[:N]``, ``ACC[:N]``).
    gyro_file : str or Path, optional
        A second text file ``t gx gy gz`` (imu_tk writes accelerometer and gyroscope in two
        files): merged onto the accelerometer's times.
    keep_unhealthy : bool
        Keep the samples a log flags unhealthy (DataFlash ``AH``/``GH`` = 0; ``--keep-unhealthy``).
    keep_clipped : bool
        Do not take a log's own clip flags as saturation (DataFlash ``VIBE.Clip`` rises, PX4 ``clip_counter``;
        ``--keep-clipped``); the rails found in the values are still sought.
    """
    src = _read_any(path, columns, topic, gyro_file, keep_unhealthy, keep_clipped)
    if (keep_unhealthy or keep_clipped) and src.file_type not in ("ulog", "dataflash"):
        flag = "--keep-unhealthy" if keep_unhealthy else "--keep-clipped"
        src.notes.append(f"{flag}: a {src.file_type} file holds no health or clip flags of its own; nothing to keep")
    if keep_clipped and src.file_type == "ulog" and src.saturated is not None:  # DataFlash's said by its reader
        if src.saturated.any():
            src.notes.append(f"the topic's clip counters flag {int(np.count_nonzero(src.saturated))} samples: kept "
                             f"(--keep-clipped)")
        src.saturated = None
    return set_aside_empty_temperature(src)


def set_aside_empty_temperature(src: Source) -> Source:
    """``src`` without its temperature column when that column holds no number at all, said in a note.

    A temperature is read beside the samples, not as one of them: a sensor with no thermometer (a PX4 driver
    that publishes NaN, a logger's empty column) must not make every accelerometer sample unusable.  A
    temperature missing in some rows only keeps those rows out, counted, as before (the temperature-dependent
    fits need it on every row they use)."""
    if not src.has("temp") or np.isfinite(src.data["temp"]).any():
        return src
    name = src.column_map.pop("temp", "temp")
    del src.data["temp"]
    src.ignored_columns.append(name)
    how = "--columns temp=NAME reads another column" if src.file_type in ("csv", "parquet") else f"a {src.file_type} holds no other"
    src.notes.append(f"temperature {name} holds no number in any of its {src.n_rows} rows (the sensor logged none): "
                     f"set aside, the samples read without a temperature ({how})")
    return src


def _read_any(
    path: str | Path,
    columns: str | dict[str, str] | None,
    topic: str | None,
    gyro_file: str | Path | None,
    keep_unhealthy: bool = False,
    keep_clipped: bool = False,
) -> Source:
    kind = detect_file_type(path)
    if kind == "csv" and (container := container_type(path)) is not None:  # MATLAB, netCDF-4, HDF5
        from optcal.data.containers import read_container

        return Source(**read_container(path, container, topic=topic, columns=columns, gyro_file=gyro_file))
    if kind in ("csv", "parquet"):
        if topic is not None:
            raise InputError(f"topic applies to ROS bags, ULog and DataFlash files, not to a {kind} file")
        mapping = parse_columns_option(columns)
        if kind == "csv" and not mapping and (records := _line_records(path)) is not None:
            src = records  # one record over several lines, a label before each sensor's values
        elif kind == "csv":
            src = read_text(path, mapping)
        else:
            src = source_from_frame(read_parquet(path), str(path), kind, mapping)
        if gyro_file is not None:
            merge_gyro_file(src, gyro_file)
        return src
    if columns:
        raise InputError(f"columns applies to CSV and Parquet files, not to a {kind}")
    if gyro_file is not None:
        raise InputError(f"gyro_file applies to text files, not to a {kind} (it holds its own gyro)")
    if kind == "ulog":
        return read_ulog(path, topic)
    if kind == "dataflash":
        return read_dataflash(path, topic, keep_unhealthy=keep_unhealthy, keep_clipped=keep_clipped)
    return read_rosbag(path, topic, kind)


def _line_records(path: str | Path) -> Source | None:
    from optcal.data.line_records import is_line_records, read_line_records

    return Source(**read_line_records(path)) if is_line_records(path) else None


# ----------------------------------------------------------------------------- tabular
def read_text(path: str | Path, mapping: dict[str, str] | None = None) -> Source:
    """Read a delimited text file (any delimiter, with or without a header) into a :class:`Source`."""
    from optcal.data.text import read_numbers

    p = Path(path)
    mapping = dict(mapping or {})
    # --columns by position (t=1,ax=2,...) reads the fields where a row of names does not match them
    layout, parsed = read_numbers(p, by_position=any(v.isdigit() for v in mapping.values()))
    if not layout.has_header and layout.comment_names is not None and _names_columns(layout.comment_names, mapping):
        layout = layout.with_comment_header()
    names = layout.names
    reason = "header names"
    if layout.header_in_comment and layout.header_line is not None:
        reason = f"names in the comment on line {layout.header_line + 1}"
    roles = None
    logger_gyro = False
    joined_stamp = False  # fields 1-2 read as one time stamp (columns.split_stamp): field 2 is read, as its fraction
    if layout.has_header and not mapping and (logger := sensor_logger_mapping(names, str(p))) is not None:
        mapping, reason = logger  # Sensor Logger's bare x, y, z: the file's name says the quantity
    elif layout.has_header and not mapping and (logger := sensor_logger_mapping(names, str(p), "gyro")) is not None:
        # its Gyroscope.csv read alone (optcal allan FILE): the gyro's axes, in rad/s (a gyro-only log)
        mapping = {dict(zip(ACC, GYRO)).get(k, k): v for k, v in logger[0].items()}
        reason, logger_gyro = logger[1], True
    elif layout.has_header and not mapping and parsed.columns and (attribute := attribute_mapping(
            names, {names[j]: v for j, v in parsed.non_numeric.items()}, len(parsed.columns[0]), str(p))) is not None:
        mapping, reason = attribute  # VMU931's bare x, y, z: a column of words says the quantity
    mapping_given = bool(mapping)
    if not layout.has_header:
        if mapping:
            reason = "no header; columns by position from --columns"
            if layout.ignored_header is not None:
                reason = (f"line {layout.ignored_header + 1}'s names do not match the fields (read as a note); "
                          "columns by position from --columns")
            # t=1 on a stamp split in whole seconds and a sub-second count (columns.split_stamp: the seconds alone
            # repeat, no time) reads the stamp, as without --columns; --rate HZ times the rows instead
            if mapping.get("t") == "1" and "2" not in mapping.values() and (joined := split_stamp(parsed.columns)):
                parsed.columns[0] = joined[0]
                reason += joined_stamp_note(joined[1]) + ": column 1 holds their sum in seconds"
                joined_stamp = True
        else:
            headerless = headerless_mapping(str(p), parsed.columns, layout.describe(),
                                            {j: v[2] for j, v in parsed.non_numeric.items()})
            mapping, reason, roles = headerless.mapping, headerless.reason, headerless.roles
            joined_stamp = headerless.joined_stamp is not None
    gyro_only: GyroOnlyColumns | None = None
    try:
        src = source_from_columns(
            names, parsed.columns, str(p), "csv", mapping, layout.metadata,
            {names[j]: v for j, v in parsed.non_numeric.items()},
        )
    except GyroOnlyColumns as exc:  # described as any source (positions, layout), then refused
        src, gyro_only = exc.source, exc
        if logger_gyro and src.gyro_units is None:
            src.gyro_units = "rad/s"  # Sensor Logger's UNITS.md
    unread = [n for n in names if n not in src.column_map.values()] if not layout.has_header else []
    if unread and joined_stamp:
        unread.remove("2")  # the time's fraction (columns.split_stamp), read into column 1
    if not layout.has_header:
        src.column_map = {k: f"#{v}" for k, v in src.column_map.items()}
        src.columns_reason = reason
        src.roles = roles
    elif any(v.isdigit() and v not in names for v in mapping.values()):
        src.columns_reason = f"{reason} and positions from --columns"
    elif src.roles is None:
        src.columns_reason = reason
    src.layout = layout.describe() + parsed.comments_note + (f"; {src.layout}" if src.layout else "")  # a partial gyro's note
    if "t" not in src.column_map and src.time_reason:  # a time column of text, set aside (source_from_columns)
        src.layout += f"; {src.time_reason}"
    if unread and not mapping_given:
        # a 9-axis logger's magnetometer (columns.HEADERLESS_TRIPLES): said, not silently dropped
        src.layout += f"; columns {', '.join(unread)} not read (--columns maps them)"
    src.size_bytes = p.stat().st_size
    if gyro_only is not None:
        raise gyro_only
    return src


def _names_columns(names: list[str], mapping: dict[str, str]) -> bool:
    """Whether a comment line's words name the columns: ``--columns`` names them, or optcal knows one of them."""
    if any(v in names for v in mapping.values()):
        return True
    try:
        return bool(resolve_columns(names, {}).column_map)
    except InputError:
        return False


def read_parquet(path: str | Path) -> Any:
    """Read a Parquet file (pyarrow) into a frame."""
    import pandas as pd

    try:
        frame = pd.read_parquet(path)
    except ImportError as exc:
        raise InputError("reading Parquet files needs pyarrow: pip install 'optcal[parquet]'") from exc
    except Exception as exc:  # pyarrow raises several types for damaged files
        raise InputError(f"{path}: not a readable Parquet file, truncated or corrupt ({exc.__class__.__name__}: {str(exc).splitlines()[0]})") from exc
    frame.columns = [str(c).strip() for c in frame.columns]
    if len(frame) == 0:
        raise InputError(f"{path}: no data rows")
    return frame


def source_from_frame(
    frame: Any,
    path: str,
    file_type: str,
    mapping: dict[str, str] | None = None,
    header: dict[str, str] | None = None,
) -> Source:
    """Map a pandas frame (Parquet, or made in memory) to canonical columns."""
    import pandas as pd

    names = [str(c) for c in frame.columns]
    columns: list[NDArray[np.float64]] = []
    non_numeric: dict[str, tuple[int, int, str]] = {}
    for name, col in zip(names, frame.columns):
        raw = frame[col]
        values = raw.astype(float) if pd.api.types.is_numeric_dtype(raw) else pd.to_numeric(raw, errors="coerce")
        bad = np.flatnonzero(values.isna().to_numpy() & raw.notna().to_numpy())
        if bad.size:
            non_numeric[name] = (int(bad.size), int(bad[0]) + 1, str(raw.iloc[bad[0]]))
        columns.append(values.to_numpy(dtype=float))
    return source_from_columns(names, columns, path, file_type, mapping, header, non_numeric)


def source_from_columns(
    names: list[str],
    columns: list[NDArray[np.float64]],
    path: str,
    file_type: str,
    mapping: dict[str, str] | None = None,
    header: dict[str, str] | None = None,
    non_numeric_by_name: dict[str, tuple[int, int, str]] | None = None,
) -> Source:
    """Map named float columns to canonical columns (units and time unit as the names state them)."""
    column_map, unit_words, roles = resolve_columns(names, mapping or {})
    missing = [c for c in ACC if c not in column_map]
    gyro_only = bool(missing) and all(c in column_map for c in GYRO)
    if missing and not gyro_only:
        # a magnetometer's file given to an accelerometer's command: its reader is one flag away
        stems = {strip_unit(normalise_name(n))[0] for n in names}
        mag = "; its columns name a magnetometer: optcal calibrate FILE --sensor mag" if all(
            stems & set(MAG_ALIASES[c]) for c in MAG) else ""
        raise InputError(
            f"{path}: no accelerometer column(s) for {', '.join(missing)} (the file has: "
            f"{', '.join(names) or 'no columns'}); name them ax, ay, az (or acc_x, ...) or map them "
            f"with columns (--columns ax=NAME,ay=NAME,az=NAME, or by 1-based position ax=2,ay=3,az=4){mag}"
        )
    if (partial := partial_gyro(column_map, names, mapping or {})) is not None:
        column_map = {c: v for c, v in column_map.items() if c not in GYRO}  # said in the layout (read_text)
    by_name = dict(zip(names, columns))
    bad_by_name = non_numeric_by_name or {}
    data = {canon: by_name[col] for canon, col in column_map.items()}
    non_numeric = {canon: bad_by_name[col] for canon, col in column_map.items() if col in bad_by_name}
    if "index" in data:
        idx = data["index"][np.isfinite(data["index"])]
        steps = np.diff(idx)
        is_index = steps.size > 0 and median(steps) == 1.0
        if not is_index and "n_samples" not in data:
            data["n_samples"] = data.pop("index")
            column_map["n_samples"] = column_map.pop("index")
    used = set(column_map.values())
    extra = {c: v for c, v in by_name.items() if c not in used and c not in bad_by_name and not np.isnan(v).all()}
    ignored = [c for c in names if c not in used and c not in extra]
    src = Source(
        path=path, file_type=file_type, data=data, extra=extra, column_map=column_map,
        ignored_columns=ignored, header=dict(header or {}), non_numeric=non_numeric, roles=roles,
        layout="" if partial is None else partial,
    )
    if roles is not None:
        src.columns_reason = (f"{', '.join(roles.triples[0])} as the accelerometer when the data say acceleration "
                              "(an acceleration in some loggers, a translation in others)")
    acc_units = {unit_words.get(c) for c in ACC}
    word = next(iter(acc_units)) if len(acc_units) == 1 else None
    if word is not None and word in UNIT_ALIASES["accelerometer"]:
        src.units_hint = normalise_units(word)
        src.units_reason = f"unit word {word!r} in the column names"
    if src.has(*GYRO):
        words = {unit_words.get(c) for c in GYRO}
        gyro_word = next(iter(words)) if len(words) == 1 else None
        if gyro_word is not None and gyro_word in GYRO_UNIT_WORDS:
            src.gyro_units = GYRO_UNIT_WORDS[gyro_word]
    if "t" in data and "t" in non_numeric and not np.isfinite(data["t"]).any():
        # a time column holding no number in any row (a date written as text, 'Wed Dec 22 21:09:46 2021') is no
        # time base: set aside and said (the rate is then needed: --rate), instead of every row dropped as non-finite
        count, row, value = non_numeric.pop("t")
        name = column_map.pop("t")
        data.pop("t")
        src.ignored_columns.append(name)
        src.time_reason = (f"column {name!r} holds no number in any row (text such as {value!r} on data row "
                           f"{row}): not read as the time")
    if "t" in data:
        word = unit_words.get("t")
        name = column_map["t"]
        if word in TIME_UNITS:
            factor = TIME_UNITS[word]
            if factor != 1.0:
                data["t"] = data["t"] * factor
            src.time_unit = "s" if word == "sec" else word
            src.time_reason = f"column {name!r} in {word} (its name says so)"
        else:
            src.time_reason = f"column {name!r}"
    for key, value in src.header.items():
        if normalise_name(key) in RATE_KEYS:
            try:
                rate = float(value.replace(",", "."))
            except ValueError:
                continue
            if rate > 0:
                src.rate_hint = rate
                src.rate_reason = f"'{key},{value}' in the file header"
        elif src.rate_hint is None:
            setting = next((m for m in RATE_SETTING.finditer(value) if normalise_name(m.group(1)) in RATE_KEYS), None)
            if setting is not None and float(setting.group(2)) > 0:
                src.rate_hint = float(setting.group(2))
                src.rate_reason = f"'{setting.group(1)} = {setting.group(2)} Hz' in the file header's {key!r} line"
    if gyro_only:  # a gyroscope's log (an Allan recording of the gyro alone): its reader is one flag away
        raise GyroOnlyColumns(
            f"{path}: no accelerometer column(s) for {', '.join(missing)} (the file has: {', '.join(names)}); its "
            f"columns name a gyroscope only: optcal allan FILE --sensor gyro analyses its noise (or map the "
            "accelerometer's with --columns ax=NAME,ay=NAME,az=NAME)", src)
    return src


def merge_gyro_file(src: Source, gyro_file: str | Path) -> None:
    """Add ``gx, gy, gz`` from a second text file ``t gx gy gz``, placed on ``src``'s times.

    imu_tk writes the accelerometer and the gyroscope of one recording in two files with
    their own time columns; samples of the gyro file are matched to the accelerometer's by
    time (:func:`optcal.data.gyro_merge.gyro_onto_times`: linear interpolation, or row for row when the
    two files share a time column that repeats stamps; accelerometer samples outside the gyro file's
    time span get NaN and are counted as non-finite).
    """
    if not src.has("t"):
        raise InputError(f"{src.path}: merging a gyro file needs a time column in both files")
    if src.has(*GYRO):
        raise InputError(f"{src.path}: already has gyro columns; give gyro_file only for accelerometer-only files")
    mapping, unit = _gyro_only_mapping(gyro_file)
    g = read_text(gyro_file, mapping)
    tg = g.column("t")
    ok = np.isfinite(tg)
    if ok.sum() < 2 or np.any(np.diff(tg[ok]) < 0):
        raise InputError(f"{gyro_file}: the gyro file's time column must increase")
    if (src.time_unit or "s") != (g.time_unit or "s"):
        raise InputError(f"{gyro_file}: its time unit ({g.time_unit}) differs from {src.path}'s ({src.time_unit})")
    t = src.column("t")
    cols = ("ax", "ay", "az") if not g.has(*GYRO) else GYRO
    placed, how = gyro_onto_times(t, tg, [g.column(c) for c in cols])
    src.data.update(zip(GYRO, placed))
    src.column_map.update({name: f"{Path(gyro_file).name}:{g.column_map[c]}" for name, c in zip(GYRO, cols)})
    src.notes.append(f"gyro from {gyro_file}, {how}")
    if src.gyro_units is None and g.column_map.get("ax") is not None:  # a gyro read in the accelerometer's place
        word = strip_unit(normalise_name(g.column_map["ax"]))[1]
        src.gyro_units = GYRO_UNIT_WORDS.get(word) if word is not None else unit


def _gyro_only_mapping(gyro_file: str | Path) -> tuple[dict[str, str] | None, str | None]:
    """A gyro file whose names say gyroscope and nothing accelerometer (phyphox's ``Gyroscope.csv``: ``X (rad/s)``;
    Sensor Logger's ``Gyroscope.csv``, bare ``x, y, z`` in rad/s by its documentation): its gyro columns mapped into
    the accelerometer's place, where :func:`merge_gyro_file` reads a headerless ``t x y z`` file's, and the unit a
    name-less layout documents; ``(None, None)`` for any other file (read as it is)."""
    from optcal.data.text import sniff_layout

    layout = sniff_layout(gyro_file)
    if not layout.has_header:
        return None, None
    logger = sensor_logger_mapping(layout.names, str(gyro_file), sensor="gyro")
    if logger is not None:
        return logger[0], "rad/s"
    found = resolve_columns(layout.names, {}).column_map
    if any(c in found for c in ACC) or not all(c in found for c in GYRO):
        return None, None
    mapping = {a: found[c] for a, c in zip(ACC, GYRO)}
    if "t" in found:
        mapping["t"] = found["t"]
    return mapping, None


# ----------------------------------------------------------------------------- ROS bags
def _import_rosbags() -> Any:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:
        raise InputError("reading ROS bags needs the rosbags library: pip install 'optcal[ros]'") from exc
    return AnyReader, Stores, get_typestore


def bag_topic(reader: Any, path: str | Path, msgtype: str, topic: str | None) -> list[Any]:
    """The connections of the one topic of ``msgtype`` (e.g. ``sensor_msgs/msg/Imu``) in an open bag: ``topic`` when
    given, else the bag's only such topic; an :class:`InputError` naming the topics found and ``--topic`` otherwise."""
    name = msgtype.split("/")[-1]
    of_type = [c for c in reader.connections if c.msgtype == msgtype]
    topics = sorted({c.topic for c in of_type})
    if not topics:
        found = ", ".join(sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})) or "none"
        raise InputError(f"{path}: no sensor_msgs/{name} topic in the bag (topics: {found})")
    if topic is None:
        if len(topics) > 1:
            raise InputError(f"{path}: several sensor_msgs/{name} topics ({', '.join(topics)}); choose one with --topic")
        topic = topics[0]
    elif topic not in topics:
        raise InputError(f"{path}: no sensor_msgs/{name} topic {topic!r} ({name} topics: {', '.join(topics)})")
    return [c for c in of_type if c.topic == topic]


def open_rosbag(path: str | Path, kind: str) -> Any:
    """A ROS 1 or ROS 2 bag opened with rosbags' ``AnyReader`` (the caller closes it).

    Parameters
    ----------
    path : str or Path
        The bag (a ROS 2 bag's ``.db3``/``.mcap`` file stands for its directory).
    kind : str
        :func:`detect_file_type`'s kind (``"ros1 bag"`` or ``"ros2 bag"``).

    Returns
    -------
    rosbags.highlevel.AnyReader
        Opened; its messages deserialised with ROS 2 Humble's types where the bag carries none.

    Raises
    ------
    InputError
        rosbags is not installed (with the extra that installs it), or the bag cannot be opened.
    """
    AnyReader, Stores, get_typestore = _import_rosbags()
    p = Path(path)
    if kind == "ros2 bag" and p.is_file():
        p = p.parent
    try:
        reader = AnyReader([p], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags raises its own error classes per format
        raise InputError(f"{path}: not a readable ROS bag, truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc
    return reader


def read_rosbag(path: str | Path, topic: str | None, kind: str) -> Source:
    """Read ``sensor_msgs/Imu`` messages of one topic from a ROS 1 or ROS 2 bag.

    Time is the message header stamp (the bag's receive time when the stamp is zero);
    acceleration in m/s² and angular rate in rad/s (ROS REP 103/145).  A single
    ``sensor_msgs/Temperature`` topic, when present, is interpolated onto the IMU times.
    """
    reader = open_rosbag(path, kind)
    try:
        conns = bag_topic(reader, path, ROS_IMU_TYPE, topic)
        topic = conns[0].topic
        rows = []
        try:
            for conn, logtime, raw in reader.messages(connections=conns):
                m = reader.deserialize(raw, conn.msgtype)
                stamp = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                la, av = m.linear_acceleration, m.angular_velocity
                rows.append((stamp if stamp > 0 else logtime * 1e-9, la.x, la.y, la.z, av.x, av.y, av.z))
            temps = [c for c in reader.connections if c.msgtype == ROS_TEMPERATURE_TYPE]
            temp_series = None
            if len({c.topic for c in temps}) == 1:
                tt = []
                for conn, logtime, raw in reader.messages(connections=temps):
                    m = reader.deserialize(raw, conn.msgtype)
                    stamp = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                    tt.append((stamp if stamp > 0 else logtime * 1e-9, m.temperature))
                temp_series = np.array(tt, dtype=float) if tt else None
        except InputError:
            raise
        except Exception as exc:
            raise InputError(f"{path}: the bag is truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc
    finally:
        reader.close()
    if not rows:
        raise InputError(f"{path}: topic {topic!r} has no messages")
    data = np.array(rows, dtype=float)
    frame = {name: np.ascontiguousarray(data[:, j]) for j, name in enumerate(("t", "ax", "ay", "az", "gx", "gy", "gz"))}
    notes = []
    if temp_series is not None and len(temp_series) >= 1:
        order = np.argsort(temp_series[:, 0])
        frame["temp"] = np.interp(frame["t"], temp_series[order, 0], temp_series[order, 1])
        notes.append("temperature interpolated from the one sensor_msgs/Temperature topic")
    return Source(
        path=str(path),
        file_type=kind,
        data=frame,
        column_map={"t": "header.stamp", "ax": "linear_acceleration.x", "ay": "linear_acceleration.y",
                    "az": "linear_acceleration.z", "gx": "angular_velocity.x", "gy": "angular_velocity.y",
                    "gz": "angular_velocity.z"},
        units_hint="m/s^2",
        units_reason="sensor_msgs/Imu is in m/s^2 (ROS REP 103)",
        gyro_units="rad/s",
        time_unit="s",
        time_reason=f"header stamps of topic {topic}",
        always_raw=True,
        notes=notes,
        header={"topic": topic},
    )


# ----------------------------------------------------------------------------- ArduPilot DataFlash, PX4 ULog
def read_dataflash(path: str | Path, topic: str | None, *, keep_unhealthy: bool = False,
                   keep_clipped: bool = False) -> Source:
    """Read an ArduPilot DataFlash log's IMU (:func:`optcal.data.dataflash.read_dataflash_imu`: ``IMU`` or
    ``ACC``/``GYR``; m/s², rad/s, with VIBE's clip count as the saturation flags) as a :class:`Source`."""
    from optcal.data.dataflash import read_dataflash_imu

    imu = read_dataflash_imu(path, topic, keep_unhealthy=keep_unhealthy, keep_clipped=keep_clipped)
    return Source(
        path=str(path), file_type="dataflash", data=imu.frame, column_map=imu.column_map, units_hint="m/s^2",
        units_reason=imu.units_reason, gyro_units="rad/s" if imu.has_gyro else None, time_unit="s",
        time_reason=imu.time_reason, saturated=imu.saturated, gyro_saturated=imu.gyro_saturated, always_raw=True,
        notes=list(imu.notes), header={"topic": imu.topic}, exclusions=dict(imu.exclusions),
        gyro_unhealthy=imu.gyro_unhealthy,
    )


def read_ulog(path: str | Path, topic: str | None) -> Source:
    """Read a PX4 ULog file's IMU (:func:`optcal.data.ulog.read_ulog_imu`: ``sensor_accel`` with its
    ``sensor_gyro``, or ``sensor_combined``; m/s², rad/s, with the clip flags) as a :class:`Source`."""
    imu = read_ulog_imu(path, topic)
    return Source(
        path=str(path), file_type="ulog", data=imu.frame, column_map=imu.column_map, units_hint="m/s^2",
        units_reason=imu.units_reason, gyro_units="rad/s" if imu.has_gyro else None, time_unit="s",
        time_reason=imu.time_reason, saturated=imu.saturated, gyro_saturated=imu.gyro_saturated, always_raw=True,
        notes=list(imu.notes), header={"topic": imu.topic}, exclusions=dict(imu.exclusions),
    )
