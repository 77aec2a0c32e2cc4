"""ROS 1 and ROS 2 bags: opened with the ``rosbags`` library (imported only when a bag is read,
``pip install 'optcal[ros]'``), one topic chosen, its ``sensor_msgs/Imu`` messages read into a
:class:`~optcal.data.source.Source`.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from optcal.errors import InputError
from optcal.data.source import Source


ROS_IMU_TYPE = "sensor_msgs/msg/Imu"
ROS_TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"


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
