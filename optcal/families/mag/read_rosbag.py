"""A magnetometer's samples from a ROS 1 or ROS 2 bag's ``sensor_msgs/MagneticField`` topic, with the accelerometer
of its ``sensor_msgs/Imu`` topic joined at the nearest stamps."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import MAG
from optcal.errors import InputError
from optcal.families.mag.sample_set import MagSamples, _build

#: The ROS message of a magnetometer (``magnetic_field`` in tesla, REP 145) and the IMU's.
ROS_MAG_TYPE: str = "sensor_msgs/msg/MagneticField"
ROS_IMU_TYPE: str = "sensor_msgs/msg/Imu"
#: An IMU sample is joined to a magnetometer sample when their stamps are at most this share of the IMU's median
#: period apart (the nearest of two samples is then that sample, not one across a gap in the IMU's stream: farther,
#: the accelerometer's direction may belong to another orientation of a turning sensor).
ROS_JOIN_SHARE: float = 0.5


def _stamps(reader: Any, conns: list, fields: Any) -> NDArray[np.float64]:
    """Rows ``(stamp, *fields(message))`` of ``conns``' messages (the header stamp; the bag's time when it is zero)."""
    rows = []
    for conn, logtime, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        rows.append((stamp if stamp > 0 else logtime * 1e-9, *fields(msg)))
    return np.array(rows, dtype=float).reshape(len(rows), -1)


def _read_rosbag(path: str, kind: str, topic: str | None, mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    """``sensor_msgs/MagneticField`` messages of one topic (tesla) and, where the bag has one ``sensor_msgs/Imu``
    topic, its accelerometer at the nearest stamps (:data:`ROS_JOIN_SHARE`; the samples without one counted)."""
    from optcal.data.readers import bag_topic, open_rosbag

    reader = open_rosbag(path, kind)
    try:
        mag_conns = bag_topic(reader, path, ROS_MAG_TYPE, topic)
        topic = mag_conns[0].topic
        imus = [c for c in reader.connections if c.msgtype == ROS_IMU_TYPE]
        try:
            mag = _stamps(reader, mag_conns,
                          lambda msg: (msg.magnetic_field.x, msg.magnetic_field.y, msg.magnetic_field.z))
            imu_topics = sorted({c.topic for c in imus})
            imu = (_stamps(reader, imus, lambda msg: (msg.linear_acceleration.x, msg.linear_acceleration.y,
                                                      msg.linear_acceleration.z))
                   if len(imu_topics) == 1 else None)
        except Exception as exc:
            raise InputError(f"{path}: the bag is truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc
    finally:
        reader.close()
    if not mag.size:
        raise InputError(f"{path}: topic {topic!r} has no messages")
    mag = mag[np.argsort(mag[:, 0], kind="stable")]
    others: dict[str, NDArray] = {"t": mag[:, 0]}
    notes = [f"ROS topic {topic} (sensor_msgs/MagneticField, tesla)"]
    columns = {k: f"{topic}.magnetic_field.{a}" for k, a in zip(MAG, "xyz")}
    if imu is not None and len(imu) >= 2:
        imu = imu[np.argsort(imu[:, 0], kind="stable")]
        j = np.clip(np.searchsorted(imu[:, 0], mag[:, 0]), 1, len(imu) - 1)
        j = np.where(np.abs(imu[j - 1, 0] - mag[:, 0]) <= np.abs(imu[j, 0] - mag[:, 0]), j - 1, j)
        gap = np.abs(imu[j, 0] - mag[:, 0])
        near = gap <= ROS_JOIN_SHARE * float(np.median(np.diff(imu[:, 0])))
        acc = np.where(near[:, None], imu[j, 1:4], np.nan)
        others["acc"] = acc
        imu_topic = imu_topics[0]
        columns.update({k: f"{imu_topic}.linear_acceleration.{a}" for k, a in zip(("ax", "ay", "az"), "xyz")})
        notes.append(f"accelerometer from {imu_topic} at the nearest stamps: {int(np.count_nonzero(~near))} of "
                     f"{len(mag)} magnetometer samples without an IMU sample within {ROS_JOIN_SHARE:g} of its period "
                     f"(largest gap {float(gap.max()):.3g} s), no accelerometer there")
    elif len(imu_topics) > 1:
        notes.append(f"several sensor_msgs/Imu topics ({', '.join(imu_topics)}): no accelerometer joined")
    return _build(path, mag[:, 1:4], "T", "sensor_msgs/MagneticField (tesla, REP 145)", mag_units, columns, others,
                  notes, keep_rail)
