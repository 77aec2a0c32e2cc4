"""The delimited text file's reader: its layout (:mod:`optcal.data.text`), its columns by name, by a logger's
layout or by position (:mod:`optcal.data.columns`), into a :class:`~optcal.data.source.Source`.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

from pathlib import Path

from optcal.errors import InputError
from optcal.data.columns import (ACC, GYRO, attribute_mapping, headerless_mapping, joined_stamp_note,
                                 resolve_columns, sensor_logger_mapping, split_stamp)
from optcal.data.source import GyroOnlyColumns, Source
from optcal.data.source_columns import source_from_columns


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
