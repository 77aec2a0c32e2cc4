"""A magnetometer's samples from a delimited text file: its header (or a header written as a comment, or the
common layout of a file without one), the magnetometer's columns and those beside it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import ALIASES, MAG, MAG_ALIASES, attribute_mapping, normalise_name, sensor_logger_mapping
from optcal.families.mag.columns import CURRENT_ALIASES, NORMAL_ZERO, THROTTLE_ALIASES, TWO_AXES, _mag_triple, _match
from optcal.families.mag.headerless import _headerless_mag
from optcal.families.mag.sample_set import MagSamples, _build


def _read_text(path: str, mapping: dict[str, str], mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    from optcal.data.text import read_numbers

    layout, parsed = read_numbers(Path(path))
    if not layout.has_header and layout.comment_names is not None:
        # the header written as a comment (rostopic echo -p's "%time,field.header.seq,...", "# mx my mz"): taken
        # when it names the magnetometer's columns (or --columns names one of its words)
        words = list(layout.comment_names)
        if any(v in words for v in mapping.values()) or set(_match(words, MAG_ALIASES)[0]) == set(MAG):
            layout = layout.with_comment_header()
    names = list(layout.names)
    col = dict(zip(names, parsed.columns))
    notes: list[str] = [parsed.comments.describe()] if parsed.comments is not None and parsed.comments.count else []
    if not layout.has_header and layout.comment_names is None and not any(k in MAG for k in mapping):
        mapping, reason = _headerless_mag(path, names, parsed.columns, mapping,
                                          {j: v[2] for j, v in parsed.non_numeric.items()})
        col = dict(zip(names, parsed.columns))  # a split stamp's two fields joined into the first (split_stamp)
        notes.append(reason)
    logger = sensor_logger_mapping(names, path, sensor="mag") if layout.has_header and not mapping else None
    if logger is not None:  # Sensor Logger's Magnetometer.csv: bare x, y, z in µT, by its file's name (UNITS.md)
        mapping = logger[0]
        notes.append(logger[1])
    elif layout.has_header and not mapping and parsed.columns and (attribute := attribute_mapping(
            names, {names[j]: v for j, v in parsed.non_numeric.items()}, len(parsed.columns[0]), path, "mag")):
        mapping = attribute[0]  # VMU931's bare x, y, z: a column of words in every row says the quantity
        notes.append(attribute[1])
    mag_cols, word = _mag_triple(names, mapping)
    if mag_cols["mz"] == NORMAL_ZERO:  # a 2-axis compass's log: its plane's normal, unmeasured, read as 0 (TWO_AXES)
        col[NORMAL_ZERO] = np.zeros(len(col[mag_cols["mx"]]))
        if layout.has_header:
            notes.append(f"2 columns ({mag_cols['mx']}, {mag_cols['my']}): {TWO_AXES}")
    if logger is not None:
        word = "ut"
    taken = set(mag_cols.values())
    rest = [n for n in names if n not in taken]
    extra_aliases = {"ax": ALIASES["ax"], "ay": ALIASES["ay"], "az": ALIASES["az"], "gx": ALIASES["gx"],
                     "gy": ALIASES["gy"], "gz": ALIASES["gz"], "t": ALIASES["t"],
                     "temp": ALIASES["temp"], "current": CURRENT_ALIASES, "throttle": THROTTLE_ALIASES}
    found, _ = _match(rest, extra_aliases)
    found.update({k: v for k, v in mapping.items() if k in extra_aliases and v in names})
    others: dict[str, NDArray] = {k: col[v] for k, v in found.items() if k in ("t", "temp", "current", "throttle")}
    if all(k in found for k in ("ax", "ay", "az")):
        others["acc"] = np.column_stack([col[found[k]] for k in ("ax", "ay", "az")])
    if all(k in found for k in ("gx", "gy", "gz")):
        others["gyro"] = np.column_stack([col[found[k]] for k in ("gx", "gy", "gz")])
    m = np.column_stack([col[mag_cols[k]] for k in MAG])
    columns = {**mag_cols, **{k: v for k, v in found.items()}}
    if word is None and all(normalise_name(mag_cols[k]).endswith("magnetic_field_" + k[1]) for k in MAG):
        # a ROS export's columns (rostopic echo -p's field.magnetic_field.x, a ros2 bag export's magnetic_field.x):
        # sensor_msgs/MagneticField is in tesla (REP 145)
        return _build(path, m, "T", "sensor_msgs/MagneticField's field names (tesla, REP 145)", mag_units, columns,
                      others, notes, keep_rail)
    where = "Sensor Logger's documentation (UNITS.md: µT)" if logger is not None else f"the unit word {word!r} in the column names"
    return _build(path, m, word, where, mag_units, columns, others, notes, keep_rail)
