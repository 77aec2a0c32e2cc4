"""Writing recordings in the formats optcal reads: CSV, Parquet, ROS 1/ROS 2 bags, PX4 ULog.

Used to build test fixtures and example files from synthetic recordings
(:mod:`optcal.families.simulate.recording`).  Bags are written with the ``rosbags`` library
(``sensor_msgs/Imu``, plus ``sensor_msgs/Temperature`` when there is a ``temp`` column);
ULog files with a minimal writer of the ULog format (header, flag bits, format and
subscription messages, ``sensor_accel`` and ``sensor_gyro`` data), since ``pyulog`` only
rewrites files it has parsed.  The frame must hold ``t`` (s), ``ax, ay, az`` and optionally
``gx, gy, gz`` and ``temp``, in the units the format expects (m/s² and rad/s for bags
and ULog).
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from optcal.errors import InputError

if TYPE_CHECKING:  # rosbags is optional (the ros extra); its names are only needed by the type checker
    from rosbags.rosbag1 import Writer as Rosbag1Writer
    from rosbags.rosbag2 import Writer as Rosbag2Writer
    from rosbags.typesys.store import MsgType

FORMATS: tuple[str, ...] = ("csv", "parquet", "ros1", "ros2", "ulog")


def write_recording(frame: pd.DataFrame, path: str | Path, fmt: str, topic: str = "/imu/data") -> Path:
    """Write ``frame`` to ``path`` in ``fmt`` (one of :data:`FORMATS`); return the path."""
    p = Path(path)
    if fmt == "csv":
        frame.to_csv(p, index=False, float_format="%.9g")
    elif fmt == "parquet":
        frame.to_parquet(p, index=False)
    elif fmt in ("ros1", "ros2"):
        write_rosbag(frame, p, version=1 if fmt == "ros1" else 2, topic=topic)
    elif fmt == "ulog":
        write_ulog(frame, p)
    else:
        raise InputError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
    return p


def write_rosbag(frame: pd.DataFrame, path: Path, version: int, topic: str = "/imu/data") -> None:
    """Write ``sensor_msgs/Imu`` messages (and ``sensor_msgs/Temperature``) to a ROS bag."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:
        raise InputError("writing ROS bags needs the rosbags library: pip install 'optcal[ros]'") from exc
    ts = get_typestore(Stores.ROS1_NOETIC if version == 1 else Stores.ROS2_HUMBLE)
    types = ts.types
    Imu, Header, Time = types["sensor_msgs/msg/Imu"], types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    Vector3, Quaternion = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
    Temperature = types["sensor_msgs/msg/Temperature"]
    serialize = ts.serialize_ros1 if version == 1 else ts.serialize_cdr
    t = frame["t"].to_numpy(float)
    acc = frame[["ax", "ay", "az"]].to_numpy(float)
    gyro = frame[["gx", "gy", "gz"]].to_numpy(float) if {"gx", "gy", "gz"} <= set(frame.columns) else np.zeros_like(acc)
    temp = frame["temp"].to_numpy(float) if "temp" in frame.columns else None
    zeros9 = np.zeros(9, dtype=np.float64)

    def header(i: int, stamp_ns: int) -> MsgType:
        stamp = Time(sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000))
        return Header(seq=i, stamp=stamp, frame_id="imu") if version == 1 else Header(stamp=stamp, frame_id="imu")

    writer: Rosbag1Writer | Rosbag2Writer
    if version == 1:
        from rosbags.rosbag1 import Writer as Writer1

        writer = Writer1(path)
    else:
        from rosbags.rosbag2 import Writer as Writer2

        writer = Writer2(path, version=9)
    with writer:
        conn = writer.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ts)
        tconn = writer.add_connection(topic + "_temperature", "sensor_msgs/msg/Temperature", typestore=ts) if temp is not None else None
        for i in range(t.size):
            ns = int(round(t[i] * 1e9))
            msg = Imu(
                header=header(i, ns),
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=zeros9,
                angular_velocity=Vector3(x=gyro[i, 0], y=gyro[i, 1], z=gyro[i, 2]),
                angular_velocity_covariance=zeros9,
                linear_acceleration=Vector3(x=acc[i, 0], y=acc[i, 1], z=acc[i, 2]),
                linear_acceleration_covariance=zeros9,
            )
            writer.write(conn, ns, serialize(msg, "sensor_msgs/msg/Imu"))
            if tconn is not None and temp is not None:  # tconn is made exactly when there is a temp column
                tm = Temperature(header=header(i, ns), temperature=float(temp[i]), variance=0.0)
                writer.write(tconn, ns, serialize(tm, "sensor_msgs/msg/Temperature"))


# ----------------------------------------------------------------------------- ULog
_ULOG_MAGIC = b"ULog\x01\x12\x35"
_ACCEL_FORMAT = (
    "sensor_accel:uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;float y;float z;"
    "float temperature;uint32_t error_count;uint8_t[3] clip_counter;uint8_t samples;"
)
_GYRO_FORMAT = (
    "sensor_gyro:uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;float y;float z;"
    "float temperature;uint32_t error_count;uint8_t[3] clip_counter;uint8_t samples;"
)


def _ulog_message(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def write_ulog(frame: pd.DataFrame, path: Path, clipped: np.ndarray | None = None,
               gyro_clipped: np.ndarray | None = None) -> None:
    """Write ``sensor_accel`` (and ``sensor_gyro``) instance 0 to a ULog file (format version 1).

    ``clipped`` and ``gyro_clipped`` (bool per row) set ``clip_counter`` of the accelerometer's and the gyro's
    clipped samples.
    """
    t_us = np.round(frame["t"].to_numpy(float) * 1e6).astype(np.uint64)
    acc = frame[["ax", "ay", "az"]].to_numpy(np.float32)
    temp = frame["temp"].to_numpy(np.float32) if "temp" in frame.columns else np.full(len(frame), np.nan, np.float32)
    has_gyro = {"gx", "gy", "gz"} <= set(frame.columns)
    clip = np.zeros(len(frame), dtype=np.uint8) if clipped is None else np.asarray(clipped, bool).astype(np.uint8)
    gclip = np.zeros(len(frame), dtype=np.uint8) if gyro_clipped is None else np.asarray(gyro_clipped, bool).astype(np.uint8)
    out = bytearray()
    out += _ULOG_MAGIC + struct.pack("<B", 1) + struct.pack("<Q", int(t_us[0]) if t_us.size else 0)
    out += _ulog_message(b"B", bytes(8) + bytes(8) + struct.pack("<3Q", 0, 0, 0))
    out += _ulog_message(b"F", _ACCEL_FORMAT.encode())
    if has_gyro:
        out += _ulog_message(b"F", _GYRO_FORMAT.encode())
    out += _ulog_message(b"A", struct.pack("<BH", 0, 0) + b"sensor_accel")
    if has_gyro:
        out += _ulog_message(b"A", struct.pack("<BH", 0, 1) + b"sensor_gyro")
        gyro = frame[["gx", "gy", "gz"]].to_numpy(np.float32)
    record = struct.Struct("<HQQIffffI3BB")
    for i in range(len(frame)):
        c = int(clip[i])
        out += _ulog_message(
            b"D", record.pack(0, int(t_us[i]), int(t_us[i]), 1, *acc[i], temp[i], 0, c, c, c, 1)
        )
        if has_gyro:
            g = int(gclip[i])
            out += _ulog_message(b"D", record.pack(1, int(t_us[i]), int(t_us[i]), 2, *gyro[i], temp[i], 0, g, g, g, 1))
    Path(path).write_bytes(bytes(out))
