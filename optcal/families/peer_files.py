"""Reading other tools' calibration files: imucal's JSON and imu_tk's ``.calib`` pair.

Both are recognised by their content, never by their name, and converted exactly into a
:class:`~optcal.families.caltypes.peer.PeerCalibration` (the equations and the conversion are in
that module's docstring):

* **imucal** (mad-lab-fau/imucal, ``imucal/calibration_info.py``, ``ferraris_calibration_info.py``):
  a JSON object with ``cal_type`` ``Ferraris`` or ``Turntable``, ``_format_version`` 2.x and the
  matrices ``K_a, R_a, b_a, K_g, R_g, K_ga, b_g``; ``from_acc_unit``/``from_gyr_unit`` name the
  raw units it was made from, ``acc_unit``/``gyr_unit`` its output (m/s², deg/s).  imucal
  scales the accelerometer to its ``grav`` (9.81 m/s² unless the user changed it,
  ``imucal/ferraris_calibration.py``); the file does not record it, so optcal takes 9.81 unless
  the file's ``comment`` states ``g = … m/s^2`` (as optcal's exporter writes) or the user gives
  ``gravity``.
* **imu_tk** (``include/imu_tk/calibration.h``, ``CalibratedTriad_::save``/``load``): 21 numbers,
  the misalignment ``T`` (3×3, row-major, unit diagonal), the scale ``K`` (3×3 diagonal) and the
  bias ``B``; ``X' = T K (X − B)``.  One file per sensor (``test_imu_acc.calib``,
  ``test_imu_gyro.calib`` in ``apps/test_imu_calib.cpp``): optcal reads the accelerometer's and
  takes the gyroscope's from the same folder (the name with ``acc`` replaced by ``gyro``), or
  from ``gyro`` when given.  imu_tk scales the accelerometer to its ``g_mag`` (9.81 m/s² by
  default, ``src/calibration.cpp``, ``MultiPosCalibration_``; the file does not record it).  The
  file does not say its raw units either: they are read from the size of ``K`` (below).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import STANDARD_GRAVITY
from optcal.core.units import RAD_PER_UNIT, UNIT_ALIASES
from optcal.core.gyro_model import GyroModel
from optcal.errors import InputError
from optcal.families.caltypes.peer import PeerCalibration

__all__ = ["IMUCAL_GRAVITY", "IMUTK_GRAVITY", "from_imucal", "is_imucal", "parse_imutk", "read_imutk"]

#: imucal's default ``grav`` (``FerrarisCalibration.__init__``, ``imucal/ferraris_calibration.py``), m/s².
IMUCAL_GRAVITY: float = 9.81
#: imu_tk's default ``g_mag`` (``MultiPosCalibration_`` constructor, ``src/calibration.cpp``), m/s².
IMUTK_GRAVITY: float = 9.81
#: imucal's calibration types (``FerrarisCalibrationInfo``, ``TurntableCalibrationInfo``).
IMUCAL_TYPES: tuple[str, ...] = ("Ferraris", "Turntable")
#: The major version of imucal's file format this reader knows (``_CAL_FORMAT_VERSION`` 2.0.0).
IMUCAL_FORMAT_MAJOR: int = 2
#: A sensitivity within this factor of a unit's own scale is read as that unit: a factor of two is
#: no scale error a calibration corrects (MEMS scale errors are a few per cent), so a matrix that far
#: from 1 m/s² per m/s² (or 1 rad/s per rad/s) converts counts.
UNIT_SCALE_FACTOR: float = 2.0
#: The g optcal's exporter states in an imucal file's comment (``g = 9.80665 m/s^2``).
_COMMENT_GRAVITY = re.compile(r"\bg\s*=\s*([0-9]+(?:\.[0-9]*)?)\s*m/s\^?2")
#: imucal's names of the raw, unscaled units (its docstring's ``"a.u."``) and other unit words, to optcal's.
_RAW_WORDS: tuple[str, ...] = ("a.u.", "au", "arbitrary units", "digits", "raw", "counts", "lsb")


def is_imucal(d: dict[str, Any]) -> bool:
    """An imucal calibration: its ``cal_type`` and matrices, and no optcal ``format_version``."""
    return "format_version" not in d and d.get("cal_type") in IMUCAL_TYPES and "K_a" in d and "R_a" in d


def _unit(spelling: Any, sensor: str, what: str, notes: list[str]) -> str:
    """optcal's name of an imucal unit string (``None`` and ``a.u.`` are raw counts, said in ``notes``)."""
    if spelling is None:
        notes.append(f"the file does not say which units its {what} data were in: read as raw counts")
        return "counts"
    key = str(spelling).strip().lower()
    if key in _RAW_WORDS:
        return "counts"
    aliases = UNIT_ALIASES[sensor]
    if key not in aliases:
        raise InputError(f"imucal's {what} unit {spelling!r} is none optcal knows ({', '.join(dict.fromkeys(aliases.values()))}, a.u.)")
    return aliases[key]


def _matrix(d: dict[str, Any], key: str, shape: tuple[int, ...]) -> NDArray[np.float64]:
    if d.get(key) is None:
        raise InputError(f"the imucal calibration has no {key}")
    a = np.asarray(d[key], dtype=float)
    if a.size != int(np.prod(shape)) or not np.all(np.isfinite(a)):
        raise InputError(f"the imucal calibration's {key} is not {shape} finite numbers")
    return a.reshape(shape)


def from_imucal(d: dict[str, Any], source: str, gravity: float | None = None) -> PeerCalibration:
    """imucal's calibration JSON object as a :class:`PeerCalibration` (exact: module docstring).

    Parameters
    ----------
    d : dict
        The file's JSON object.
    source : str
        The file, named in the description.
    gravity : float, optional
        The g imucal's calibration was scaled to (its ``grav``), m/s².

    Raises
    ------
    InputError
        Another format version, a missing matrix, an unknown unit.
    """
    version = d.get("_format_version")
    if version is None:
        raise InputError("an imucal calibration without _format_version (imucal 1.x): convert it with imucal.legacy first")
    try:
        major = int(str(version).split(".")[0])
    except ValueError as exc:
        raise InputError(f"imucal _format_version {version!r} is not a version") from exc
    if major != IMUCAL_FORMAT_MAJOR:
        raise InputError(f"imucal _format_version {version}: this optcal reads imucal's format 2.x")
    notes: list[str] = []
    acc_in = _unit(d.get("from_acc_unit"), "accelerometer", "accelerometer", notes)
    gyr_in = _unit(d.get("from_gyr_unit"), "gyro", "gyroscope", notes)
    acc_out = str(d.get("acc_unit") or "m/s^2")
    gyr_out = str(d.get("gyr_unit") or "deg/s")
    out_acc = UNIT_ALIASES["accelerometer"].get(acc_out.strip().lower())
    out_gyr = UNIT_ALIASES["gyro"].get(gyr_out.strip().lower())
    if out_acc not in ("m/s^2", "g") or out_gyr not in RAD_PER_UNIT:
        raise InputError(f"imucal output units {acc_out!r}, {gyr_out!r}: optcal reads m/s^2 or g, and deg/s or rad/s")
    comment = str(d.get("comment") or "")
    stated = _COMMENT_GRAVITY.search(comment)
    if out_acc == "g":
        g, reason = 1.0, "imucal's output is in g"
    elif gravity is not None:
        g, reason = float(gravity), "given"
    elif stated:
        g, reason = float(stated.group(1)), "stated in the file's comment"
    else:
        g, reason = IMUCAL_GRAVITY, "imucal's default grav; the file does not record it"
    K_a, R_a, b_a = _matrix(d, "K_a", (3, 3)), _matrix(d, "R_a", (3, 3)), _matrix(d, "b_a", (3,))
    # imucal/ferraris_calibration_info.py, _calibrate_acc: acc = R_a⁻¹ K_a⁻¹ (raw − b_a)  [m/s²]
    M = np.linalg.inv(R_a) @ np.linalg.inv(K_a)
    gyro = None
    if all(d.get(k) is not None for k in ("K_g", "R_g", "b_g")):
        K_g, R_g, b_g = _matrix(d, "K_g", (3, 3)), _matrix(d, "R_g", (3, 3)), _matrix(d, "b_g", (3,))
        # _calibrate_gyr: gyr = R_g⁻¹ K_g⁻¹ (raw − K_ga acc − b_g)  [deg/s], acc the calibrated m/s²
        K_ga = _matrix(d, "K_ga", (3, 3)) if d.get("K_ga") is not None else None
        gyro = GyroModel(RAD_PER_UNIT[out_gyr] * (np.linalg.inv(R_g) @ np.linalg.inv(K_g)), b_g,
                         None if K_ga is None else K_ga * g)
    else:
        notes.append("the file has no gyroscope matrices (K_g, R_g, b_g): the accelerometer only")
    peer = {k: d.get(k) for k in ("cal_type", "_format_version", "from_acc_unit", "from_gyr_unit", "acc_unit", "gyr_unit",
                                  "comment", "K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g")}
    return PeerCalibration(
        "imucal", str(d["cal_type"]), M / g, b_a, acc_in, g, reason, gyro, gyr_in if gyro is not None else None, source,
        f"read as imucal's calibration JSON (cal_type {d['cal_type']}, _format_version {version})", peer, notes)


# ------------------------------------------------------------------------------------ imu_tk
def parse_imutk(text: str) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None:
    """``T``, ``K``, ``B`` of an imu_tk ``.calib`` text, or ``None`` when it is not one.

    ``CalibratedTriad_::load`` reads 9 + 9 + 3 numbers (row-major ``T`` and ``K``, then ``B``);
    ``T`` has a unit diagonal and ``K`` is diagonal by construction (``CalibratedTriad_``).
    """
    try:
        values = np.array([float(w) for w in text.split()])
    except ValueError:
        return None
    if values.size != 21 or not np.all(np.isfinite(values)):
        return None
    T, K, B = values[:9].reshape(3, 3), values[9:18].reshape(3, 3), values[18:]
    if not np.all(np.diag(T) == 1.0) or np.any(K[~np.eye(3, dtype=bool)] != 0.0) or np.any(np.diag(K) <= 0):
        return None
    return T, K, B


def _raw_units(scale: NDArray[np.float64], stated: dict[str, float], what: str) -> tuple[str, str]:
    """The input units whose own scale the peer's sensitivity lies within :data:`UNIT_SCALE_FACTOR` of, else counts."""
    mean = float(np.exp(np.mean(np.log(scale))))
    for unit, factor in stated.items():
        if 1.0 / UNIT_SCALE_FACTOR < mean / factor < UNIT_SCALE_FACTOR:
            return unit, f"its {what} scale {mean:.6g} per input unit is that of {unit}"
    return "counts", f"its {what} scale {mean:.6g} per input unit is no unit's own (within a factor {UNIT_SCALE_FACTOR:g}): counts"


def _pair(path: Path, gyro: str | Path | None) -> tuple[Path, Path | None, str]:
    """The accelerometer's and the gyroscope's files of an imu_tk pair, and how they were found."""
    name = path.name
    if gyro is not None:
        return path, Path(gyro), "gyroscope file given"
    if "gyro" in name.lower() and "acc" not in name.lower():
        i = name.lower().rfind("gyro")
        acc = path.with_name(name[:i] + "acc" + name[i + 4:])
        if not acc.is_file():
            raise InputError(f"{path} is imu_tk's gyroscope .calib; give the accelerometer's ({acc.name} not found next to it)")
        return acc, path, f"the gyroscope's file given; the accelerometer's {acc.name} found next to it"
    i = name.lower().rfind("acc")
    if i >= 0:
        candidate = path.with_name(name[:i] + "gyro" + name[i + 3:])
        if candidate.is_file():
            return path, candidate, f"the gyroscope's {candidate.name} found next to it"
        return path, None, f"no {candidate.name} next to it: the accelerometer only"
    return path, None, "no gyroscope file named (its name has no 'acc' to pair by): the accelerometer only"


def read_imutk(path: str | Path, gyro: str | Path | None = None, gravity: float | None = None) -> PeerCalibration:
    """imu_tk's ``.calib`` pair as a :class:`PeerCalibration` (module docstring).

    Raises
    ------
    InputError
        A file that is not imu_tk's ``.calib``.
    """
    acc_path, gyro_path, paired = _pair(Path(path), gyro)
    parsed = parse_imutk(acc_path.read_text(errors="replace")) if acc_path.is_file() else None
    if parsed is None:
        raise InputError(f"{acc_path}: not imu_tk's .calib (21 numbers: T with a unit diagonal, diagonal K, B)")
    T, K, B = parsed
    g, reason = (float(gravity), "given") if gravity is not None else (IMUTK_GRAVITY, "imu_tk's default g_mag; the file does not record it")
    notes: list[str] = []
    # calibration.h, unbiasNormalize: X' = T K (X − B), m/s² at g_mag
    units, why = _raw_units(np.diag(K), {"m/s^2": 1.0, "g": STANDARD_GRAVITY}, "accelerometer")
    notes.append(f"accelerometer input read as {units}: {why}")
    model, gyro_units = None, None
    if gyro_path is not None:
        if not gyro_path.is_file():
            raise InputError(f"{gyro_path}: no such imu_tk gyroscope .calib")
        parsed_g = parse_imutk(gyro_path.read_text(errors="replace"))
        if parsed_g is None:
            raise InputError(f"{gyro_path}: not imu_tk's .calib (21 numbers: T with a unit diagonal, diagonal K, B)")
        Tg, Kg, Bg = parsed_g
        gyro_units, why = _raw_units(np.diag(Kg), {"rad/s": 1.0, "deg/s": RAD_PER_UNIT["deg/s"]}, "gyroscope")
        notes.append(f"gyroscope input read as {gyro_units}: {why}")
        model = GyroModel(Tg @ Kg, Bg)  # rad/s in the accelerometer's calibrated frame (calibrateAccGyro)
        peer_g = {"T": Tg.tolist(), "K": Kg.tolist(), "B": Bg.tolist(), "file": str(gyro_path)}
    source = str(acc_path) + (f" + {gyro_path}" if gyro_path is not None else "")
    peer: dict[str, Any] = {"accelerometer": {"T": T.tolist(), "K": K.tolist(), "B": B.tolist(), "file": str(acc_path)}}
    if model is not None:
        peer["gyroscope"] = peer_g
    return PeerCalibration("imu_tk", "multi-position", T @ K / g, B, units, g, reason, model, gyro_units, source,
                           f"read as imu_tk's .calib (T, K, B; {paired})", peer, notes)
