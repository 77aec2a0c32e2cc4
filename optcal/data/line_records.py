"""Samples written one record over several lines, each sensor's values on a line of its own after its name.

An iOS app's dump of CoreMotion (fffire-oss/imu_processing's ``dataset/circle.txt``) writes each sample as::

    2023-04-17 15:24:05.1450
    Acceleration: 0.1071014404296875, -0.4418487548828125, -0.829620361328125
    Rotation Rate: -0.6461145877838135, -0.3688158392906189, 0.0037950044497847557
    Magnetic Field: 456.3912353515625, -227.53884887695312, -400.04608154296875

No column holds a sensor: read as delimited text, every field is a label glued to a number and every row is
dropped as non-finite.  Here a record begins at its date-time line (its clock: seconds since the first), and
each labelled line gives its sensor's three axes (:data:`SENSOR_WORDS`): the accelerometer's and the gyro's are
read, the magnetometer's said not read; a record without the accelerometer's line is kept as a non-finite row,
counted by the reading's exclusions.  The units are the data's to decide (CoreMotion's are g and rad/s; the
labels state none).
"""

from __future__ import annotations

import re
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
#: A sensor's line: its name, a colon, three numbers separated by commas, semicolons or spaces.
LABELLED = re.compile(rf"^\s*([A-Za-z][A-Za-z _]*?)\s*:\s*({_NUM})\s*[,;\s]\s*({_NUM})\s*[,;\s]\s*({_NUM})\s*$")
#: A record's date-time line (ISO 8601's date, a space or ``T``, the time of day with any fraction of a second).
STAMP = re.compile(r"^\s*(\d{4})-(\d{2})-(\d{2})[ T](\d{1,2}):(\d{2}):(\d{2}(?:\.\d*)?)\s*$")
#: The sensor each label names (lower case, spaces as ``_``): the canonical axes it fills, or ``None`` (not read).
SENSOR_WORDS: dict[str, tuple[str, str, str] | None] = {
    **dict.fromkeys(("acceleration", "accelerometer", "acc", "accel", "gravity_and_acceleration"), ("ax", "ay", "az")),
    **dict.fromkeys(("rotation_rate", "rotationrate", "gyroscope", "gyro", "angular_velocity", "angular_rate"),
                    ("gx", "gy", "gz")),
    **dict.fromkeys(("magnetic_field", "magnetometer", "mag", "magnetic"), None),
}
#: Lines the sniffer reads: enough for a dozen records of four lines.
SNIFF_LINES = 48


def _label(text: str) -> str:
    return re.sub(r"\s+", "_", text.strip().lower())


def is_line_records(path: str | Path) -> bool:
    """Whether the file's first lines are records of this layout: every non-empty line a date-time or a labelled
    sensor line, and the accelerometer's label among them."""
    labels: set[str] = set()
    with open(path, encoding="utf-8", errors="replace") as f:
        for k, line in enumerate(f):
            if k >= SNIFF_LINES:
                break
            if not line.strip() or STAMP.match(line):
                continue
            m = LABELLED.match(line)
            if m is None or _label(m.group(1)) not in SENSOR_WORDS:
                return False
            labels.add(_label(m.group(1)))
    return any(SENSOR_WORDS[w] == ("ax", "ay", "az") for w in labels)


def _seconds(m: re.Match[str]) -> float:
    """A date-time line's time in seconds from the proleptic Gregorian day 1 (differences are what is used)."""
    day = date(int(m.group(1)), int(m.group(2)), int(m.group(3))).toordinal()
    return day * 86400.0 + int(m.group(4)) * 3600.0 + int(m.group(5)) * 60.0 + float(m.group(6))


def read_line_records(path: str | Path) -> dict[str, Any]:
    """Read the records: the keyword arguments of :class:`optcal.data.readers.Source`.

    Raises nothing of its own: a line of another shape after the first ones is counted among the lines not read
    and said in the layout.
    """
    records: list[dict[str, float]] = []
    current: dict[str, float] | None = None
    unread, mag_lines = 0, 0
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if not line.strip():
                continue
            if (stamp := STAMP.match(line)) is not None:
                current = {"t": _seconds(stamp)}
                records.append(current)
                continue
            m = LABELLED.match(line)
            if m is None or _label(m.group(1)) not in SENSOR_WORDS:
                unread += 1
                continue
            axes = SENSOR_WORDS[_label(m.group(1))]
            if axes is None:
                mag_lines += 1
                continue
            if current is None or axes[0] in current:  # values before any stamp, or a sensor twice: a record of its own
                current = {}
                records.append(current)
            current.update(zip(axes, (float(m.group(j)) for j in (2, 3, 4))))
    names = ("t", "ax", "ay", "az", "gx", "gy", "gz")
    present = [c for c in names if any(c in r for r in records)]
    data = {c: np.array([r.get(c, np.nan) for r in records], dtype=float) for c in present}
    if "t" in data:
        data["t"] = data["t"] - np.nanmin(data["t"])
    column_map = {c: {"t": "date-time line", "ax": "Acceleration x", "ay": "Acceleration y", "az": "Acceleration z",
                      "gx": "Rotation Rate x", "gy": "Rotation Rate y", "gz": "Rotation Rate z"}[c] for c in present}
    layout = (f"one record over several lines ({len(records)} records: a date-time line, then each sensor's "
              f"'Label: x, y, z' line)")
    if mag_lines:
        layout += f"; {mag_lines} magnetometer line(s) not read"
    if unread:
        layout += f"; {unread} line(s) of another shape not read"
    fields: dict[str, Any] = {
        "path": str(path), "file_type": "csv", "data": data, "column_map": column_map,
        "columns_reason": "the labels of the lines (Acceleration: the accelerometer; Rotation Rate: the gyro)",
        "layout": layout, "size_bytes": Path(path).stat().st_size, "always_raw": True,
    }
    if "t" in data:
        fields["time_unit"], fields["time_reason"] = "s", "the date-time lines, in seconds since the first"
    return fields
