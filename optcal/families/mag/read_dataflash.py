"""A magnetometer's samples from an ArduPilot DataFlash log's ``MAG`` messages."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import MAG
from optcal.errors import InputError
from optcal.families.mag.sample_set import MagSamples, _build


def _read_dataflash(path: str, topic: str | None, mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    """An ArduPilot DataFlash log's ``MAG`` messages (``MAG[:N]``; ``MAG2``... in older logs): ``MagX..Z`` in
    milligauss (LogStructure.h: unit G, multiplier C = 1e-3), the rows ArduPilot marked unhealthy left out and
    counted, the IMU's accelerometer interpolated onto their times for the dip."""
    from optcal.data.dataflash import dataflash_instances, open_dataflash

    log = open_dataflash(path)
    name, _, inst = (topic or "MAG").upper().partition(":")
    digit = name[3:] if name.startswith("MAG") else None
    if digit is None or (digit and not digit.isdigit()) or (inst and not inst.isdigit()):
        raise InputError(f"--topic {topic!r}: a DataFlash log's magnetometer is read from MAG[:N] (MAG2... in older logs)")
    instance = int(inst) if inst else (int(digit) - 1 if digit else 0)
    mags = dataflash_instances(log, "MAG")
    d = mags.get(instance)
    if d is None or any(f"Mag{a}" not in d for a in "XYZ"):
        raise InputError(f"{path}: no DataFlash MAG instance {instance} (logged: "
                         f"{', '.join(f'MAG:{i}' for i in sorted(mags)) or 'none'}); choose one with --topic MAG:N")
    key = "TimeUS" if "TimeUS" in d else "TimeMS"
    t = d[key] * (1e-6 if key == "TimeUS" else 1e-3)
    m = np.column_stack([d[f"Mag{a}"] for a in "XYZ"])
    exclusions: dict[str, int] = {}
    if "Health" in d and (sick := d["Health"] < 1).any():  # LogStructure.h: Health, true if the compass is considered healthy
        exclusions["DataFlash MAG rows with Health=0 (ArduPilot judged the compass unhealthy)"] = int(sick.sum())
        t, m = t[~sick], m[~sick]
    others: dict[str, NDArray] = {"t": t}
    imu = dataflash_instances(log, "IMU").get(0)
    if imu is not None and t.size and all(f"Acc{a}" in imu for a in "XYZ"):
        ta = imu["TimeUS"] * 1e-6 if "TimeUS" in imu else imu["TimeMS"] * 1e-3
        order = np.argsort(ta)
        others["acc"] = np.column_stack([np.interp(t, ta[order], imu[f"Acc{a}"][order]) for a in "XYZ"])
    samples = _build(path, m, "mgauss", "ArduPilot's MAG (milligauss, LogStructure.h)", mag_units,
                     {k: f"MAG.Mag{a}" for k, a in zip(MAG, "XYZ")}, others,
                     [f"DataFlash MAG:{instance} ({', '.join(f'MAG:{i}' for i in sorted(mags))} logged; --topic MAG:N)"], keep_rail)
    samples.exclusions.update(exclusions)
    return samples
