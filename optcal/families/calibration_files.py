"""Reading any calibration file: the ``cal_type`` registry.

:func:`load` reads a file (or its dictionary) and returns the class its ``cal_type`` names; it
refuses an unknown ``cal_type`` and a newer major ``format_version``
(:func:`optcal.core.jsonio.check_version`).  Files written by
:meth:`optcal.families.accel.result.CalibrationResult.save` are calibrations of their type with the
fit's statistics attached, so :func:`load` reads them too (and the format-1 files of optcal 0.1).

The registry :data:`CAL_TYPES` maps each ``cal_type`` to ``"module:Class"``, imported on first
use; another type registers itself with one line, ``register("magnetometer", "package.module:Class")``.
It sits here, in a module of its own above :mod:`optcal.families.caltypes` and
:mod:`optcal.families.gyro`, rather than in ``caltypes``: the ``imu`` type
(:class:`optcal.families.gyro.result.ImuCalibration`) holds the accelerometer's fit result, which
imports the calibration types, so naming it from ``caltypes`` would close the cycle
``caltypes → gyro → caltypes``.  Nothing below the applications needs to read a file of an
unknown type, so the registry costs no layer anything.

Other tools' files are recognised here too, by their content (:mod:`optcal.families.peer_files`):
imucal's calibration JSON (``cal_type`` ``Ferraris``/``Turntable``, ``_format_version`` 2.x) and
imu_tk's ``.calib`` pair become a ``peer`` calibration
(:class:`~optcal.families.caltypes.peer.PeerCalibration`) that applies exactly what the tool applies;
its description says how the file was read.  Every command that takes a calibration reads it here.
"""

from __future__ import annotations

import importlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from optcal.core.jsonio import check_version, read_json
from optcal.errors import InputError
from optcal.families.caltypes import Calibration, LumpedCalibration, SixPositionCalibration

__all__ = ["CAL_TYPES", "calibration_class", "from_dict", "load", "register"]

#: cal_type → ``"module:Class"`` (imported on first use).  One line per type.
CAL_TYPES: dict[str, str] = {
    "lumped": "optcal.families.caltypes.lumped:LumpedCalibration",
    "sixpos_full": "optcal.families.caltypes.sixpos:SixPositionCalibration",
    "extended": "optcal.families.caltypes.extended:ExtendedCalibration",
    "imu": "optcal.families.gyro.result:ImuCalibration",
    "peer": "optcal.families.caltypes.peer:PeerCalibration",
    "magnetometer": "optcal.families.mag.calibration:MagCalibration",
}


def register(cal_type: str, target: str) -> None:
    """Register a calibration class as ``"module:Class"`` under ``cal_type``.

    Raises
    ------
    ValueError
        ``target`` is not ``"module:Class"``.
    """
    if ":" not in target:
        raise ValueError(f"register({cal_type!r}, ...) needs 'module:Class', got {target!r}")
    CAL_TYPES[cal_type] = target


def calibration_class(cal_type: str) -> type[Calibration]:
    """The class registered under ``cal_type``.

    Raises
    ------
    InputError
        No class is registered under ``cal_type``.
    """
    target = CAL_TYPES.get(cal_type)
    if target is None:
        raise InputError(
            f"unknown cal_type {cal_type!r}; this optcal reads {', '.join(sorted(CAL_TYPES))} "
            "(a newer optcal may know it: upgrade)"
        )
    module, attr = target.split(":")
    return getattr(importlib.import_module(module), attr)


def _from_format_1(d: dict[str, Any]) -> Calibration:
    """A format-1 file (optcal 0.1's CalibrationResult) as the calibration it holds."""
    try:
        units = str(d["units"]["input"])
        extra = d.get("extra") or {}
        if d.get("method") == "sixpos" and "W" in extra and "V" in extra:
            return SixPositionCalibration(np.asarray(extra["W"], float), np.asarray(extra["V"], float), units)
        return LumpedCalibration.from_any_T(np.asarray(d["T"], float), np.asarray(d["o"], float), units)
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"not an optcal calibration file ({exc.__class__.__name__}: {exc})") from exc


def from_dict(d: dict[str, Any]) -> Calibration:
    """The calibration described by a dictionary (a file's JSON object).

    Raises
    ------
    InputError
        Not a calibration, unknown ``cal_type``, newer major ``format_version``.
    """
    if not isinstance(d, dict):
        raise InputError("a calibration is a JSON object (a dictionary)")
    if "format_version" not in d:
        raise InputError("not an optcal calibration file (no format_version)")
    major, _ = check_version(d["format_version"])
    check_numbers(d)
    if major == 1 and "cal_type" not in d:
        return _from_format_1(d)
    if "cal_type" not in d:
        raise InputError("not an optcal calibration file (no cal_type)")
    return calibration_class(str(d["cal_type"])).from_dict(d)


#: The range of a calibration's scale, the row norms of ``T`` (output units per raw unit).  A MEMS accelerometer's
#: raw unit is between about 1e-6 g (a 24-bit converter's count) and one physical unit (g or m/s², scale ≈ 1..10); this
#: range, three orders beyond both ends, refuses only a file whose correction would overflow or vanish in float64
#: (``T = 1e308·I`` corrects every sample to inf) or a broken edit, never a real sensor's calibration.
SCALE_RANGE: tuple[float, float] = (1e-9, 1e6)


def check_numbers(d: dict[str, Any], where: str = "") -> None:
    """Refuse a calibration dictionary holding a number that is not finite, or a ``T`` out of :data:`SCALE_RANGE`.

    optcal writes a number that is not finite as ``null``; ``NaN`` or ``Infinity`` in a file
    (which Python's JSON parser accepts) come from an edit or another writer.

    Raises
    ------
    InputError
        Naming the entry and its value.
    """
    def walk(value: Any, path: str) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                walk(item, f"{path}.{key}" if path else str(key))
        elif isinstance(value, list):
            for k, item in enumerate(value):
                walk(item, f"{path}[{k}]")
        elif isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"{where}calibration entry {path} = {value}: every number of a calibration must be finite")

    walk(d, "")
    T = d.get("T")
    if isinstance(T, list):
        try:
            rows = np.asarray(T, dtype=float)
        except (TypeError, ValueError):
            return  # the calibration class says what is wrong with its shape
        if rows.ndim == 2 and rows.size:
            with np.errstate(over="ignore"):
                scales = np.sqrt(np.sum(rows * rows, axis=1))
            low, high = SCALE_RANGE
            if not np.all((scales >= low) & (scales <= high)):
                raise InputError(
                    f"{where}calibration T has row norms {', '.join(f'{v:.3g}' for v in scales)} (output units per raw "
                    f"unit); a sensor's lie between {low:g} and {high:g}: the file is broken"
                )


def load(source: str | Path | dict[str, Any], *, gyro: str | Path | None = None,
         gravity: float | None = None) -> Calibration:
    """Read a calibration file (or its dictionary) as the class named by its ``cal_type``.

    Another tool's file (imucal's JSON, imu_tk's ``.calib``) is recognised by its content and
    read as a ``peer`` calibration (:mod:`optcal.families.peer_files`).

    Parameters
    ----------
    source : str, Path or dict
    gyro : str or Path, optional
        imu_tk: the gyroscope's ``.calib`` (default: the name with ``acc`` replaced by ``gyro``,
        next to ``source``).
    gravity : float, optional
        A peer file: the g (m/s²) its accelerometer output was scaled to (default: the tool's own
        default, 9.81 for imucal and imu_tk, or what an optcal-written file states).

    Raises
    ------
    InputError
        Missing or broken file, unknown ``cal_type``, newer major ``format_version``.
    """
    from optcal.families.peer_files import from_imucal, is_imucal, parse_imutk, read_imutk

    if isinstance(source, dict):
        return from_imucal(source, "a dictionary", gravity) if is_imucal(source) else from_dict(source)
    p = Path(source)
    if p.is_file():  # read and parsed once: optcal's JSON, imucal's JSON or imu_tk's .calib
        try:
            text = p.read_text()
        except (OSError, UnicodeDecodeError):
            text = ""
        try:
            d = json.loads(text)
        except json.JSONDecodeError:
            d = None
        try:
            if isinstance(d, dict):
                return from_imucal(d, str(p), gravity) if is_imucal(d) else from_dict(d)
            if d is None and parse_imutk(text) is not None:
                return read_imutk(p, gyro, gravity)
        except InputError as exc:
            raise InputError(f"{source}: {exc}" if not str(exc).startswith(str(source)) else str(exc)) from exc
    # a missing file, or not one of those: read_json says which
    read_json(source, hint="optcal reads its own calibration files, imucal's JSON and imu_tk's .calib")
    raise InputError(f"{source}: not an optcal calibration file")
