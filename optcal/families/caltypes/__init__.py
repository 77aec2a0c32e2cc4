"""The calibration type family: one versioned file format, one class per ``cal_type``.

===============  ==========================================================  =======================
``cal_type``     equation                                                    class
===============  ==========================================================  =======================
``lumped``       ``ā = T (a − o)``, T canonical lower-triangular (Lu 2017)    :class:`LumpedCalibration`
``sixpos_full``  ``ā = W a + V``, W full (Yin 2014, eq. 3)                   :class:`SixPositionCalibration`
``extended``     lumped + temperature, drift and nonlinearity terms          :class:`ExtendedCalibration`
``imu``          lumped + gyro ``ω = T_g (g − b_g − G_g ā)`` (Tedaldi 2014)  :class:`optcal.families.gyro.result.ImuCalibration`
===============  ==========================================================  =======================

:func:`load` reads a file (or a dictionary) and returns the right class; it refuses an unknown
``cal_type`` and a newer major ``format_version``.  The registry :data:`CAL_TYPES` maps each
``cal_type`` to ``"module:Class"`` and is imported lazily; another type registers itself with one
line, ``register("imu", "optcal.families.gyro.calibration:ImuCalibration")``.  Files written by
:meth:`optcal.core.fit_result.CalibrationResult.save` are calibrations of their type with the fit's
statistics attached, so :func:`load` reads them too (and the format-1 files of optcal 0.1).
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from optcal.families.caltypes.base import (
    FORMAT_VERSION,
    Calibration,
    FitPoses,
    ValidityRangeWarning,
    check_version,
)
from optcal.families.caltypes.extended import ExtendedCalibration, ExtendedTerm, ValidityRange
from optcal.families.caltypes.lumped import LumpedCalibration
from optcal.families.caltypes.sixpos import SixPositionCalibration
from optcal.errors import InputError

__all__ = [
    "CAL_TYPES",
    "ExtendedCalibration",
    "ExtendedTerm",
    "LumpedCalibration",
    "SixPositionCalibration",
    "ValidityRange",
    "FORMAT_VERSION",
    "Calibration",
    "FitPoses",
    "ValidityRangeWarning",
    "calibration_class",
    "from_dict",
    "load",
    "read_json",
    "register",
]

#: cal_type → ``"module:Class"`` (imported on first use).  One line per type.
CAL_TYPES: dict[str, str] = {
    "lumped": "optcal.families.caltypes.lumped:LumpedCalibration",
    "sixpos_full": "optcal.families.caltypes.sixpos:SixPositionCalibration",
    "extended": "optcal.families.caltypes.extended:ExtendedCalibration",
    "imu": "optcal.families.gyro.result:ImuCalibration",
}


def register(cal_type: str, target: str) -> None:
    """Register a calibration class as ``"module:Class"`` under ``cal_type``."""
    if ":" not in target:
        raise ValueError(f"register({cal_type!r}, ...) needs 'module:Class', got {target!r}")
    CAL_TYPES[cal_type] = target


def calibration_class(cal_type: str) -> type[Calibration]:
    """The class registered under ``cal_type``."""
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
    """The calibration described by a dictionary (a file's JSON object)."""
    if not isinstance(d, dict):
        raise InputError("a calibration is a JSON object (a dictionary)")
    if "format_version" not in d:
        raise InputError("not an optcal calibration file (no format_version)")
    major, _ = check_version(d["format_version"])
    if major == 1 and "cal_type" not in d:
        return _from_format_1(d)
    if "cal_type" not in d:
        raise InputError("not an optcal calibration file (no cal_type)")
    return calibration_class(str(d["cal_type"])).from_dict(d)


def read_json(path: str | Path) -> dict[str, Any]:
    """The JSON object of a calibration file, with one clear error for a missing or broken file."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such calibration file")
    try:
        d = json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: not a JSON calibration file ({exc})") from exc
    if not isinstance(d, dict):
        raise InputError(f"{p}: not an optcal calibration file (not a JSON object)")
    return d


def load(source: str | Path | dict[str, Any]) -> Calibration:
    """Read a calibration file (or its dictionary) as the class named by its ``cal_type``.

    Raises
    ------
    InputError
        Missing or broken file, unknown ``cal_type``, newer major ``format_version``.
    """
    if isinstance(source, dict):
        return from_dict(source)
    try:
        return from_dict(read_json(source))
    except InputError as exc:
        if str(exc).startswith(str(source)):
            raise
        raise InputError(f"{source}: {exc}") from exc
