"""ArduPilot DataFlash logs (``.bin``): the IMU's samples, read with pymavlink's ``DFReader``.

A DataFlash log is a stream of messages ``0xA3 0x95 id payload``, each type described by a ``FMT`` message (name,
``struct`` format, column names; ArduPilot's ``libraries/AP_Logger/LogStructure.h``).  The IMU is logged as

* ``IMU`` (current firmware: one type, the instance in its ``I`` column; before, ``IMU``, ``IMU2``, ``IMU3``):
  ``TimeUS`` (µs; ``TimeMS`` in logs before 2015), ``GyrX..Z`` in rad/s, ``AccX..Z`` in m/s², the error counts
  ``EG``/``EA`` (``ErrG``/``ErrA``), the temperature ``T`` (``Temp``, °C) and the health flags ``GH``/``AH``
  (``GyHlt``/``AcHlt``): LogStructure.h's units string for IMU is ``s#EEEooo--O--zz`` (E rad/s, o m/s/s, O degC);
  the samples at the main loop's rate, filtered;
* ``ACC``/``GYR`` (``ACC1``, ``GYR1``... before): ``SampleUS``, the accelerometer's and the gyro's own samples at
  the sensor's rate where the log holds them (``INS_LOG_BAT_OPT``/raw logging), units ``s#sooo`` and ``s#sEEE``;
* ``VIBE``: ``Clip`` (``Clip0..2`` before), the number of the accelerometer's samples beyond its clip limit so far.

Both carry ArduPilot's accelerometer calibration (``INS_ACC*OFFS``, ``INS_ACC*SCAL``) applied: what is fitted is what
that calibration left, as PX4's ``sensor_combined``.  ``IMU`` instance 0 is read by default, ``--topic IMU:N`` /
``IMU2`` / ``ACC[:N]`` another; the read line says which and what else is logged.

What the log's own flags mean, from LogStructure.h's field descriptions: ``AH`` is the accelerometer's health as
ArduPilot judged it (0: its samples are not used by the vehicle), so such rows are left out and counted; ``GH`` is
the gyro's (0: its rates are not used), and the two sensors are judged apart: such a row keeps its accelerometer
sample (``AH`` decides it) and its gyro sample is left out of every use of the gyro (the rests it gates, the moves
it integrates, its noise: :attr:`optcal.data.recording.Recording.gyro_usable`), counted apart
(``--keep-unhealthy`` keeps both); ``EA``/``EG``
count the bus's read errors (a sample that failed to read is not logged, so no logged sample is wrong by it: the
count is said, nothing is excluded); a rise of ``VIBE.Clip`` between two VIBE messages means a sample in between
reached the clip limit, so every IMU sample in that interval is flagged saturated (which one is not logged;
``--keep-clipped`` keeps them).
"""

from __future__ import annotations

import re
import struct
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.ulog import UlogImu
from optcal.errors import InputError

__all__ = ["DATAFLASH_TOPICS", "dataflash_instances", "dataflash_messages", "open_dataflash", "read_dataflash_imu"]

#: The message families read: the IMU's filtered samples, and the accelerometer's raw ones.
DATAFLASH_TOPICS: tuple[str, ...] = ("IMU", "ACC")
#: Health flag below which a row is left out: ``AH``/``GH`` are booleans (1 healthy), LogStructure.h.
_HEALTHY = 1
#: pymavlink's format characters that hold numbers (DFReader.FORMAT_TO_STRUCT): strings are not read.
_NUMERIC = set("bBghHiIfcCeELdMqQ")


def open_dataflash(path: str | Path) -> Any:
    """pymavlink's ``DFReader_binary`` on ``path`` (indexed, not yet read), or an :class:`InputError`."""
    try:
        from pymavlink.DFReader import DFReader_binary
    except ImportError as exc:  # a declared dependency: only a broken install lacks it
        raise InputError("reading ArduPilot DataFlash logs needs pymavlink: pip install pymavlink") from exc
    try:
        return DFReader_binary(str(path), zero_time_base=True)
    except Exception as exc:
        raise InputError(f"{path}: not a readable DataFlash log, truncated or corrupt "
                         f"({exc.__class__.__name__}: {exc})") from exc


def dataflash_messages(log: Any, name: str) -> dict[str, NDArray[np.float64]] | None:
    """Every message of type ``name`` as numeric columns (pymavlink's multipliers applied), or ``None``.

    Reads the payloads at the offsets DFReader indexed, with the type's own ``struct`` format: one unpack a
    message, no per-message object."""
    tid = log.name_to_id.get(name)
    if tid is None or not log.counts[tid]:
        return None
    fmt = log.formats[tid]
    st = struct.Struct(fmt.msg_struct)
    data = log.data_map
    rows = [st.unpack_from(data, off + 3) for off in log.offsets[tid]]
    out: dict[str, NDArray[np.float64]] = {}
    for j, (col, ch) in enumerate(zip(fmt.columns, fmt.format)):
        if ch not in _NUMERIC:
            continue
        v = np.array([r[j] for r in rows], dtype=float)
        if fmt.msg_mults[j] is not None:
            v *= fmt.msg_mults[j]
        out[col] = v
    return out


def _first(d: dict[str, NDArray[np.float64]], *keys: str) -> str | None:
    return next((k for k in keys if k in d), None)


def dataflash_instances(log: Any, base: str) -> dict[int, dict[str, NDArray[np.float64]]]:
    """The instances of ``base`` (``IMU``, ``ACC``, ``GYR``, ``MAG``): by the ``I`` column of one message type
    (current firmware), or as ``IMU``/``IMU2``/``IMU3`` and ``ACC1``/``ACC2`` (older logs)."""
    found: dict[int, dict[str, NDArray[np.float64]]] = {}
    for name in sorted(log.name_to_id):
        m = re.fullmatch(rf"{base}(\d?)", name)
        if m is None or (d := dataflash_messages(log, name)) is None:
            continue
        if "I" in d:
            for i in np.unique(d["I"]).astype(int):
                sel = d["I"] == i
                found[int(i)] = {k: v[sel] for k, v in d.items()}
        else:  # IMU, IMU2, IMU3; ACC1, ACC2 (1-based where the first has a digit)
            digit = m.group(1)
            found[int(digit) - 1 if digit else 0] = d
    return found


def _times(d: dict[str, NDArray[np.float64]], name: str) -> tuple[NDArray[np.float64], str]:
    key = _first(d, "SampleUS", "TimeUS", "TimeMS")
    if key is None:
        raise InputError(f"DataFlash {name} has no TimeUS, SampleUS or TimeMS column")
    return d[key] * (1e-3 if key == "TimeMS" else 1e-6), f"{name}.{key} in {'ms' if key == 'TimeMS' else 'µs'}"


def _parse_topic(topic: str | None) -> tuple[str, int]:
    if topic is None:
        return "IMU", 0
    name, _, inst = topic.upper().partition(":")
    m = re.fullmatch(r"(IMU|ACC)(\d?)", name)
    if m is None or (inst and not inst.isdigit()):
        raise InputError(f"--topic {topic!r}: a DataFlash log's IMU is read from IMU[:N] or ACC[:N] "
                         f"(IMU2, ACC1... in older logs)")
    if inst:
        return m.group(1), int(inst)
    digit = m.group(2)
    return m.group(1), (int(digit) - 1 if digit else 0)


def _rate(t: NDArray[np.float64]) -> float:
    return (t.size - 1) / float(t[-1] - t[0]) if t.size > 1 and t[-1] > t[0] else 0.0


def read_dataflash_imu(path: str | Path, topic: str | None, *, keep_unhealthy: bool = False,
                       keep_clipped: bool = False) -> UlogImu:
    """Read the accelerometer (and gyro) of an ArduPilot DataFlash log (module docstring).

    Parameters
    ----------
    path : str or Path
        The ``.bin`` log.
    topic : str or None
        ``IMU[:N]`` (``IMU2``...), ``ACC[:N]`` (``ACC1``...; the matching ``GYR`` interpolated onto its times), or
        ``None``: ``IMU`` instance 0.
    keep_unhealthy : bool
        Keep the rows whose ``AH``/``GH`` say ArduPilot judged the accelerometer or the gyro unhealthy
        (``--keep-unhealthy``); by default they are counted and left out: an ``AH`` = 0 row whole, a ``GH`` = 0
        row's gyro sample (``UlogImu.gyro_unhealthy``), its accelerometer sample kept.
    keep_clipped : bool
        Do not flag the samples in an interval over which ``VIBE.Clip`` rose (``--keep-clipped``).

    Returns
    -------
    UlogImu
        The samples in the same frame as a ULog topic's (m/s², rad/s, °C, seconds).
    """
    log = open_dataflash(path)
    base, instance = _parse_topic(topic)
    imus, accs = dataflash_instances(log, "IMU"), dataflash_instances(log, "ACC")
    logged = [f"IMU:{i} ({_rate(_times(d, 'IMU')[0]):.4g} Hz)" for i, d in sorted(imus.items())]
    logged += [f"ACC:{i} ({_rate(_times(d, 'ACC')[0]):.4g} Hz)" for i, d in sorted(accs.items())]
    chosen = (imus if base == "IMU" else accs).get(instance)
    if chosen is None:
        raise InputError(f"{path}: no DataFlash {base} instance {instance} (logged: {', '.join(logged) or 'no IMU'}); "
                         f"choose one with --topic (IMU[:N] or ACC[:N])")
    name = f"{base}:{instance}"
    t, time_reason = _times(chosen, base)
    frame: dict[str, NDArray[np.float64]] = {"t": t}
    acc_keys = [f"Acc{a}" for a in "XYZ"]
    if any(k not in chosen for k in acc_keys):
        raise InputError(f"{path}: DataFlash {base} has no AccX, AccY, AccZ columns; choose another with --topic")
    frame.update({c: chosen[k] for c, k in zip(("ax", "ay", "az"), acc_keys)})
    gyro_src = chosen if base == "IMU" else dataflash_instances(log, "GYR").get(instance)
    has_gyro = gyro_src is not None and all(f"Gyr{a}" in gyro_src for a in "XYZ")
    notes = [f"DataFlash {name} read, {t.size} samples at {_rate(t):.4g} Hz (logged: {', '.join(logged)}); "
             f"{'the default, ' if topic is None else ''}ArduPilot's samples with its accelerometer calibration "
             f"(INS_ACC*OFFS, INS_ACC*SCAL) applied, so the fit is of what that calibration left; "
             f"--topic IMU:N or ACC:N reads another"]
    if has_gyro and gyro_src is not None:
        if base == "IMU":
            frame.update({c: gyro_src[f"Gyr{a}"] for c, a in zip(("gx", "gy", "gz"), "XYZ")})
        else:
            tg, _ = _times(gyro_src, "GYR")
            order = np.argsort(tg)
            frame.update({c: np.interp(t, tg[order], gyro_src[f"Gyr{a}"][order]) for c, a in zip(("gx", "gy", "gz"), "XYZ")})
            notes.append(f"GYR:{instance} interpolated onto the ACC:{instance} times")
    if (tk := _first(chosen, "T", "Temp")) is not None:
        frame["temp"] = chosen[tk]
    exclusions: dict[str, int] = {}
    keep = np.ones(t.size, dtype=bool)
    gyro_sick: NDArray[np.bool_] | None = None  # rows kept for the accelerometer, their gyro sample not used
    unhealthy: list[str] = []
    for flag, what in (((_first(chosen, "AH", "AcHlt")), "accelerometer"), ((_first(chosen, "GH", "GyHlt")), "gyro")):
        if flag is None or (bad := (chosen[flag] < _HEALTHY) & keep).sum() == 0:
            continue  # a row both flags mark is counted once, under the accelerometer's
        reason = f"DataFlash {base} rows with {flag}=0 (ArduPilot judged the {what} unhealthy)"
        unhealthy.append(f"{int(bad.sum())} {base} rows with {flag}=0 (the {what} unhealthy)")
        if keep_unhealthy:
            continue
        exclusions[reason] = int(bad.sum())
        if what == "accelerometer":
            keep &= ~bad
        elif has_gyro:  # the row's accelerometer sample is sound (its AH says so): only the gyro's sample goes
            gyro_sick = bad
    if unhealthy:
        notes.append(f"{' and '.join(unhealthy)}: " + (
            "kept (--keep-unhealthy): ArduPilot did not use them" if keep_unhealthy else
            "left out, as ArduPilot left them out of its own use: an unhealthy accelerometer's row whole, an "
            "unhealthy gyro's sample alone (no rest it gates, no move it integrates, not its noise; the row's "
            "accelerometer sample is used); --keep-unhealthy keeps them"))
    for err, what in (("EA", "accelerometer"), ("ErrA", "accelerometer"), ("EG", "gyro"), ("ErrG", "gyro")):
        if err in chosen and chosen[err].size and (rise := float(chosen[err][-1] - chosen[err][0])) > 0:
            notes.append(f"the {what}'s bus read errors ({base}.{err}) rose by {rise:.0f} over the log; a failed read "
                         f"logs no sample, so none is excluded")
    saturated = _clipped(log, instance, t) if base in ("IMU", "ACC") else None
    if saturated is not None and saturated.any():
        if keep_clipped:
            notes.append(f"VIBE's clip count rose around {int(saturated.sum())} {name} samples: kept (--keep-clipped; "
                         f"the accelerometer reached its clip limit somewhere in those intervals)")
            saturated = None
        else:
            notes.append(f"VIBE's clip count rose around {int(saturated.sum())} {name} samples: flagged saturated "
                         f"(the accelerometer reached its clip limit in those intervals; --keep-clipped keeps them)")
    if not keep.all():
        frame = {k: v[keep] for k, v in frame.items()}
        saturated = None if saturated is None else saturated[keep]
        gyro_sick = None if gyro_sick is None else gyro_sick[keep]
    return UlogImu(name, frame, {"t": time_reason.split(" in ")[0],
                                 **{c: f"{base}.{k}" for c, k in zip(("ax", "ay", "az"), acc_keys)}},
                   time_reason, f"ArduPilot's {base}.AccX..Z is in m/s^2 (LogStructure.h: o, m/s/s)", has_gyro,
                   saturated, None, tuple(notes), exclusions, gyro_sick)


def _clipped(log: Any, instance: int, t: NDArray[np.float64]) -> NDArray[np.bool_] | None:
    """Samples at times inside an interval between two VIBE messages over which the clip count of accelerometer
    ``instance`` rose (``VIBE.Clip`` of the message with ``IMU == instance``; ``Clip0..2`` in older logs)."""
    vibe = dataflash_messages(log, "VIBE")
    if vibe is None:
        return None
    if "Clip" in vibe:
        sel = vibe["IMU"] == instance if "IMU" in vibe else np.ones(vibe["Clip"].size, dtype=bool)
        tv, clip = vibe["TimeUS"][sel] * 1e-6, vibe["Clip"][sel]
    elif f"Clip{instance}" in vibe:
        key = _first(vibe, "TimeUS", "TimeMS")
        if key is None:
            return None
        tv, clip = vibe[key] * (1e-3 if key == "TimeMS" else 1e-6), vibe[f"Clip{instance}"]
    else:
        return None
    flagged = np.zeros(t.size, dtype=bool)
    for j in np.flatnonzero(np.diff(clip) > 0) + 1:
        flagged |= (t > tv[j - 1]) & (t <= tv[j])
    return flagged
