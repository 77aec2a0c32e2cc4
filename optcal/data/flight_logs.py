"""Flight controllers' logs (ArduPilot DataFlash, PX4 ULog): their IMU, read by :mod:`optcal.data.dataflash` and
:mod:`optcal.data.ulog`, as a :class:`~optcal.data.source.Source`.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

from pathlib import Path

from optcal.data.source import Source
from optcal.data.ulog import read_ulog_imu


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
