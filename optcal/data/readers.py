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

from pathlib import Path

import numpy as np

from optcal.errors import InputError
from optcal.data.columns import (
    ACC,
    ALIASES,
    CANONICAL,
    GYRO,
    GYRO_UNIT_WORDS,
    NO_COLUMN,
    RATE_KEYS,
    TIME_UNITS,
    ColumnRoles,
    parse_columns_option,
    resolve_columns,
)
from optcal.data.container_kind import container_type
from optcal.data.ulog import TRUNCATED_MESSAGE, ulog_is_cut
# the reading's concepts, one module each (and importable from here, as before): the source and its refusal, the
# file type, a temperature column with no number, the text reader, the columns of named columns and of a frame,
# the gyro file's merge, the ROS bags, the flight controllers' logs
from optcal.data.source import GyroOnlyColumns, Source
from optcal.data.file_type import DATAFLASH_HEAD, detect_file_type
from optcal.data.empty_temperature import set_aside_empty_temperature
from optcal.data.source_columns import source_from_columns
from optcal.data.text_reader import _names_columns, read_text
from optcal.data.frames import read_parquet, source_from_frame
from optcal.data.gyro_merge import _gyro_only_mapping, merge_gyro_file
from optcal.data.rosbag_reader import (ROS_IMU_TYPE, ROS_TEMPERATURE_TYPE, _import_rosbags, bag_topic, open_rosbag,
                                       read_rosbag)
from optcal.data.flight_logs import read_dataflash, read_ulog

__all__ = [  # the column names, for the modules and tests that read them here
    "ACC", "ALIASES", "CANONICAL", "GYRO", "GYRO_UNIT_WORDS", "NO_COLUMN", "RATE_KEYS", "TIME_UNITS",
    "ColumnRoles", "Source", "detect_file_type", "merge_gyro_file", "parse_columns_option",
    "open_rosbag", "read_parquet", "read_rosbag", "read_source", "read_text", "read_ulog", "resolve_columns",
    "source_from_columns", "source_from_frame", "ulog_is_cut",
]


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
