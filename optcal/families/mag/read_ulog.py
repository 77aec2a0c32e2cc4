"""A magnetometer's samples from a PX4 ULog: ``sensor_mag`` (or, where it is not logged, a topic with PX4's
calibration applied), with the accelerometer interpolated onto its times."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import MAG
from optcal.errors import InputError
from optcal.families.mag.sample_set import MagSamples, _build

#: PX4's magnetometer topics with their calibration (``CAL_MAG*``) applied, read where ``sensor_mag`` (the driver's
#: samples) is not logged: ``vehicle_magnetometer`` (PX4 v1.10 on) and ``sensor_combined``'s ``magnetometer_ga``
#: (before), both in gauss.
PX4_CALIBRATED_MAG: tuple[str, ...] = ("vehicle_magnetometer", "sensor_combined")
#: ``sensor_combined``'s relative stamp of a row without that sensor's sample (PX4's ``RELATIVE_TIMESTAMP_INVALID``).
_RELATIVE_INVALID = 2**31 - 1


def _ulog_field(d: dict[str, NDArray], stem: str, rel: str | None) -> tuple[NDArray, NDArray] | None:
    """Times (s) and the 3 axes of a ULog topic's ``stem`` fields (``x``/``y``/``z`` or ``stem[0..2]``), the rows
    without the sensor's sample (``rel`` invalid) left out."""
    keys = [f"{stem}[{i}]" for i in range(3)] if stem else list("xyz")
    if any(k not in d for k in keys):
        return None
    t = d["timestamp"].astype(float)
    ok = np.ones(t.size, dtype=bool)
    if rel is not None and rel in d:
        r = d[rel].astype(np.int64)
        ok = r != _RELATIVE_INVALID
        t = t + np.where(ok, r, 0)
    return t[ok] * 1e-6, np.column_stack([d[k].astype(float)[ok] for k in keys])


def _read_ulog(path: str, topic: str | None, mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    from optcal.data.ulog import import_pyulog

    ULog = import_pyulog()
    name, instance = (topic or "sensor_mag"), 0
    if ":" in name:
        name, inst = name.split(":", 1)
        if not inst.isdigit():
            raise InputError(f"--topic {topic!r}: the instance after ':' must be a number")
        instance = int(inst)
    names = [name, "sensor_accel", *PX4_CALIBRATED_MAG] if topic is None else [name, "sensor_accel", "sensor_combined"]
    try:
        log = ULog(str(path), message_name_filter_list=names)
    except Exception as exc:
        raise InputError(f"{path}: not a readable ULog file ({exc.__class__.__name__}: {exc})") from exc

    def dataset(topic_name: str) -> dict[str, NDArray] | None:
        try:
            return dict(log.get_dataset(topic_name, instance).data)
        except (KeyError, IndexError, ValueError):
            return None

    notes: list[str] = []
    d, read = dataset(name), None
    if d is not None:
        read = _ulog_field(d, "" if name == "sensor_mag" else "magnetometer_ga", "magnetometer_timestamp_relative")
    if read is None and topic is None:
        for other in PX4_CALIBRATED_MAG:
            if (od := dataset(other)) is not None and (read := _ulog_field(
                    od, "magnetometer_ga", "magnetometer_timestamp_relative")) is not None:
                notes.append(f"{name} is not logged; {other}:{instance} read, PX4's magnetometer with its calibration "
                             f"(CAL_MAG*) applied, so the fit is of what that calibration left")
                name = other
                break
    if read is None:
        logged = sorted({f"{x.name}:{x.multi_id}" for x in ULog(str(path)).data_list if "mag" in x.name
                         or x.name == "sensor_combined"})
        raise InputError(f"{path}: no ULog topic {name} instance {instance} with a magnetometer (logged: "
                         f"{', '.join(logged) or 'none'}); choose one with --topic (sensor_mag[:N], vehicle_magnetometer or "
                         f"sensor_combined)")
    t, m = read
    others: dict[str, NDArray] = {"t": t}
    if d is not None and "temperature" in d and name == "sensor_mag":
        others["temp"] = d["temperature"].astype(float)
    acc = dataset("sensor_accel")
    acc_read = (_ulog_field(acc, "", None) if acc is not None else None) or (
        _ulog_field(c, "accelerometer_m_s2", "accelerometer_timestamp_relative")
        if (c := dataset("sensor_combined")) is not None else None)
    if acc_read is not None and acc_read[0].size > 1:
        ta, av = acc_read
        order = np.argsort(ta)
        others["acc"] = np.column_stack([np.interp(t, ta[order], av[order, k]) for k in range(3)])
    stem = "" if name == "sensor_mag" else "magnetometer_ga"
    columns = {k: f"{name}.{a if not stem else f'{stem}[{i}]'}" for i, (k, a) in enumerate(zip(MAG, "xyz"))}
    return _build(path, m, "gauss", f"PX4's {name} (gauss)", mag_units, columns, others,
                  [f"ULog topic {name}:{instance}", *notes], keep_rail)
