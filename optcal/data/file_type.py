"""The file type, recognised from a file's first bytes (ULog, ROS 1 bag, DataFlash, Parquet, SQLite/MCAP ROS 2
bag) or a directory's ROS 2 ``metadata.yaml``; everything else is delimited text.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

from pathlib import Path

from optcal.errors import InputError


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
