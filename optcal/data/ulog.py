"""PX4 ULog files: the IMU topic to read, and its samples in one frame.

PX4 logs the sensors' own topics, ``sensor_accel`` and ``sensor_gyro`` (the driver's samples, before the
calibration ``CAL_ACC*``/``CAL_GYRO*`` is applied), and ``sensor_combined`` (the vehicle's IMU: the selected
accelerometer and gyro with that calibration applied, averaged over each integration interval).  A calibration
wants the raw topic, which optcal reads by default.  But PX4's default logger profile writes ``sensor_accel`` at
1 Hz only (it is there to be looked at) while ``sensor_combined`` is written at the IMU's rate (200-250 Hz): at
1 Hz no rest the detector accepts (its shortest dwell, 0.5 s, holding a few samples) can be seen, so such a file
is read from ``sensor_combined``, and the decision says so (what is fitted is then what PX4's own calibration
left) with ``--topic sensor_accel`` to keep the raw one.  The same when ``sensor_accel`` is not logged at all.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.rails import clip_flags
from optcal.data.rest_model import MIN_INDEPENDENT_ACC
from optcal.errors import InputError

__all__ = ["COMBINED_TOPIC", "RAW_TOPIC", "TRUNCATED_MESSAGE", "UlogImu", "import_pyulog", "read_ulog_imu",
           "ulog_is_cut"]

#: The raw accelerometer's topic (the driver's samples, uncalibrated) and the vehicle's IMU (calibrated, full rate).
RAW_TOPIC = "sensor_accel"
COMBINED_TOPIC = "sensor_combined"
#: The exclusion key of a message cut off at the end of a truncated file.
TRUNCATED_MESSAGE = "messages cut off at the end of a truncated file"
#: The static detector's shortest dwell by default (s, ``StaticSettings.min_dwell_s``): a rest shorter than this is
#: not taken, and one this long must hold :data:`~optcal.data.rest_model.MIN_INDEPENDENT_ACC` samples at least, so
#: a topic logged below MIN_INDEPENDENT_ACC / SHORTEST_REST_S (4 Hz) can show no rest.
SHORTEST_REST_S = 0.5
#: ``sensor_combined.accelerometer_timestamp_relative`` when the row holds no accelerometer sample (PX4's
#: ``RELATIVE_TIMESTAMP_INVALID``, INT32_MAX).
RELATIVE_TIMESTAMP_INVALID = 2**31 - 1


def import_pyulog() -> Any:
    """pyulog's ``ULog`` class, or an :class:`~optcal.errors.InputError` naming the extra that installs it."""
    try:
        from pyulog import ULog
    except ImportError as exc:
        raise InputError("reading PX4 ULog files needs pyulog: pip install 'optcal[px4]'") from exc
    return ULog


@dataclass(frozen=True)
class UlogImu:
    """The IMU samples of one ULog topic.

    Attributes
    ----------
    topic : str
        ``name:instance`` read.
    frame : dict of str to ndarray
        ``t`` (s), ``ax, ay, az`` (m/s²), and ``gx, gy, gz`` (rad/s) and ``temp`` where logged.
    column_map : dict of str to str
        Canonical name → the topic's field.
    time_reason : str
        The stamp's field and unit.
    units_reason : str
        Why the accelerometer is in m/s².
    has_gyro : bool
        Whether a gyro was read (rad/s, as PX4 logs it).
    saturated, gyro_saturated : ndarray of bool or None
        The topic's own clip flags per row.
    notes : tuple of str
        What the reading decided (the topic chosen and why, interpolation, corruption, truncation).
    exclusions : dict of str to int
        Rows or messages left out, by reason.
    gyro_unhealthy : ndarray of bool or None
        Rows kept for their accelerometer sample whose gyro sample the log marks unusable (a DataFlash ``GH`` = 0):
        left out of every use of the gyro (:attr:`optcal.data.recording.Recording.gyro_usable`).
    """

    topic: str
    frame: dict[str, NDArray[np.float64]]
    column_map: dict[str, str]
    time_reason: str
    units_reason: str
    has_gyro: bool
    saturated: NDArray[np.bool_] | None = None
    gyro_saturated: NDArray[np.bool_] | None = None
    notes: tuple[str, ...] = ()
    exclusions: dict[str, int] = field(default_factory=dict)
    gyro_unhealthy: NDArray[np.bool_] | None = None


def _split_topic(topic: str | None) -> tuple[str | None, int]:
    if topic is None:
        return None, 0
    name, _, inst = topic.partition(":")
    try:
        return name, int(inst) if inst else 0
    except ValueError as exc:
        raise InputError(f"--topic {topic!r}: the instance after ':' must be a number") from exc


def _dataset(log: Any, name: str, instance: int) -> dict[str, NDArray] | None:
    try:
        return dict(log.get_dataset(name, instance).data)
    except (KeyError, IndexError, ValueError):
        return None


def _rate(t_us: NDArray) -> float:
    span = (float(t_us[-1]) - float(t_us[0])) * 1e-6 if t_us.size > 1 else 0.0
    return (t_us.size - 1) / span if span > 0 else 0.0


def _logged(path: str | Path, ULog: Any) -> str:
    names = sorted({f"{d.name}:{d.multi_id}" for d in ULog(str(path)).data_list})
    imu = [n for n in names if n.startswith(("sensor_", "vehicle_imu", "vehicle_acceleration"))]
    return ", ".join(imu or names) or "none"


def _open(path: str | Path, names: list[str], ULog: Any) -> Any:
    try:
        return ULog(str(path), message_name_filter_list=names)
    except Exception as exc:
        raise InputError(f"{path}: not a readable ULog file, truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc


def read_ulog_imu(path: str | Path, topic: str | None) -> UlogImu:
    """Read the accelerometer (and gyro) of a PX4 ULog file.

    Parameters
    ----------
    path : str or Path
        The ULog file.
    topic : str or None
        ``sensor_accel[:N]`` (the matching ``sensor_gyro`` instance interpolated onto its times),
        ``sensor_combined``, or ``None``: ``sensor_accel`` instance 0 unless it is not logged or logged too
        slowly to show a rest (module docstring) while ``sensor_combined`` is, the decision said in the notes.

    Returns
    -------
    UlogImu
    """
    ULog = import_pyulog()
    name, instance = _split_topic(topic)
    log = _open(path, [RAW_TOPIC, RAW_TOPIC.replace("accel", "gyro"), COMBINED_TOPIC] if name is None
                else [name, name.replace("accel", "gyro")], ULog)
    notes: list[str] = []
    if name is None:
        raw, comb = _dataset(log, RAW_TOPIC, 0), _dataset(log, COMBINED_TOPIC, 0)
        min_rate = MIN_INDEPENDENT_ACC / SHORTEST_REST_S
        raw_rate = _rate(raw["timestamp"]) if raw is not None else 0.0
        if comb is not None and (raw is None or raw_rate < min_rate):
            why = (f"{RAW_TOPIC} is not logged" if raw is None else
                   f"{RAW_TOPIC} is logged at {raw_rate:.3g} Hz ({raw['timestamp'].size} samples), below the "
                   f"{min_rate:g} Hz at which a {SHORTEST_REST_S:g}-s rest holds {MIN_INDEPENDENT_ACC:g} samples "
                   f"(PX4's default logger profile writes it at 1 Hz)")
            notes.append(f"topic {COMBINED_TOPIC}:0 read, {comb['timestamp'].size} samples at "
                         f"{_rate(comb['timestamp']):.4g} Hz: {why}; {COMBINED_TOPIC} is PX4's IMU with its "
                         f"calibration (CAL_ACC*, CAL_GYRO*) applied, so the fit is of what that calibration left; "
                         f"--topic {RAW_TOPIC} reads the raw one")
            name = COMBINED_TOPIC
        else:
            name = RAW_TOPIC
    if name == COMBINED_TOPIC:
        imu = _read_combined(log, path, instance, ULog)
    else:
        imu = _read_raw(log, path, name, instance, ULog)
    if log.file_corruption:
        notes.append("the ULog file is corrupt; the readable part was used")
    exclusions = dict(imu.exclusions)
    if ulog_is_cut(path):
        notes.append("the ULog file is truncated (its last message is cut off); the data before it were used")
        exclusions[TRUNCATED_MESSAGE] = 1
    return UlogImu(imu.topic, imu.frame, imu.column_map, imu.time_reason, imu.units_reason, imu.has_gyro,
                   imu.saturated, imu.gyro_saturated, tuple(notes) + imu.notes, exclusions)


def _missing(path: str | Path, name: str, instance: int, ULog: Any) -> InputError:
    return InputError(f"{path}: no ULog topic {name} instance {instance} (logged: {_logged(path, ULog)}); "
                      f"choose one with --topic ({RAW_TOPIC}[:N] or {COMBINED_TOPIC})")


def _read_raw(log: Any, path: str | Path, name: str, instance: int, ULog: Any) -> UlogImu:
    d = _dataset(log, name, instance)
    if d is None:
        raise _missing(path, name, instance, ULog)
    missing = [k for k in ("x", "y", "z") if k not in d]
    if missing:
        raise InputError(f"{path}: ULog topic {name} has no fields {', '.join(missing)}; "
                         f"use --topic {RAW_TOPIC} or --topic {COMBINED_TOPIC}")
    stamp_key = "timestamp_sample" if "timestamp_sample" in d else "timestamp"
    t = d[stamp_key].astype(float) * 1e-6
    frame = {"t": t, "ax": d["x"].astype(float), "ay": d["y"].astype(float), "az": d["z"].astype(float)}
    if "temperature" in d:
        frame["temp"] = d["temperature"].astype(float)
    notes: list[str] = []
    gyro_name = name.replace("accel", "gyro")
    gyro_saturated = None
    g = _dataset(log, gyro_name, instance)
    if g is not None:
        tg = g["timestamp_sample" if "timestamp_sample" in g else "timestamp"].astype(float) * 1e-6
        order = np.argsort(tg)
        for axis in "xyz":
            frame["g" + axis] = np.interp(t, tg[order], g[axis].astype(float)[order])
        if (gclip := clip_flags(g)) is not None:  # a time between two gyro samples takes both: a clipped one spoils it
            gyro_saturated = np.interp(t, tg[order], gclip[order] * 1.0) > 0
        notes.append(f"{gyro_name} instance {instance} interpolated onto the {name} times")
    return UlogImu(f"{name}:{instance}", frame,
                   {"t": f"{name}.{stamp_key}", "ax": f"{name}.x", "ay": f"{name}.y", "az": f"{name}.z"},
                   f"{name}.{stamp_key} in µs", f"PX4 {name} is in m/s^2", g is not None,
                   clip_flags(d), gyro_saturated, tuple(notes))


def _bits(d: dict[str, NDArray], key: str) -> NDArray[np.bool_] | None:
    """Rows whose clipping bitfield (bit i: axis i, PX4's ``accelerometer_clipping``) is set on any axis."""
    return (d[key].astype(np.int64) & 0b111) > 0 if key in d else None


def _read_combined(log: Any, path: str | Path, instance: int, ULog: Any) -> UlogImu:
    name = COMBINED_TOPIC
    d = _dataset(log, name, instance)
    if d is None:
        raise _missing(path, name, instance, ULog)
    acc_keys = [f"accelerometer_m_s2[{i}]" for i in range(3)]
    if any(k not in d for k in acc_keys):
        raise InputError(f"{path}: ULog topic {name} has no accelerometer_m_s2 fields; use --topic {RAW_TOPIC}")
    rel = d.get("accelerometer_timestamp_relative", np.zeros(d["timestamp"].size, dtype=np.int64)).astype(np.int64)
    ok = rel != RELATIVE_TIMESTAMP_INVALID  # a row with the gyro's sample only
    t_gyro = d["timestamp"].astype(float) * 1e-6
    t = t_gyro[ok] + rel[ok] * 1e-6
    frame = {"t": t, **{c: d[k].astype(float)[ok] for c, k in zip(("ax", "ay", "az"), acc_keys)}}
    gyro_keys = [f"gyro_rad[{i}]" for i in range(3)]
    has_gyro = all(k in d for k in gyro_keys)
    if has_gyro:  # the gyro's sample is stamped `timestamp`, the accelerometer's that plus its relative stamp
        for c, k in zip(("gx", "gy", "gz"), gyro_keys):
            frame[c] = np.interp(t, t_gyro, d[k].astype(float))
    acc_clip, gyro_clip = _bits(d, "accelerometer_clipping"), _bits(d, "gyro_clipping")
    exclusions = {f"{name} rows without an accelerometer sample": int((~ok).sum())} if not ok.all() else {}
    return UlogImu(f"{name}:{instance}", frame,
                   {"t": f"{name}.timestamp+accelerometer_timestamp_relative",
                    **{c: f"{name}.{k}" for c, k in zip(("ax", "ay", "az"), acc_keys)}},
                   f"{name}.timestamp in µs", f"PX4 {name}.accelerometer_m_s2 is in m/s^2", has_gyro,
                   None if acc_clip is None else acc_clip[ok], None if gyro_clip is None else gyro_clip[ok],
                   exclusions=exclusions)


def ulog_is_cut(path: str | Path) -> bool:
    """Whether the last message of a ULog file extends past the end of the file.

    Walks the message chain (16-byte file header, then ``uint16 size, uint8 type, payload``).
    """
    data = Path(path).read_bytes()
    pos, end = 16, len(data)
    unpack = struct.Struct("<HB").unpack_from
    while pos + 3 <= end:
        size, _ = unpack(data, pos)
        pos += 3 + size
    return pos != end
