"""imucal: a calibration as imucal's ``FerrarisCalibrationInfo`` JSON (``_format_version`` 2.0.0).

Upstream (mad-lab-fau/imucal, ``imucal/ferraris_calibration_info.py``, ``_calibrate_acc`` and
``_calibrate_gyr``; the file written by ``CalibrationInfo.to_json_file``)::

    acc = R_a⁻¹ K_a⁻¹ (raw − b_a)                          m/s²
    gyr = R_g⁻¹ K_g⁻¹ (raw − K_ga acc − b_g)               deg/s

optcal's calibration ``ā = M (a − o)`` (``M`` the matrix ``optcal apply`` applies, in its own frame:
``W`` of a full-matrix type, an ``imu`` calibration's accelerometer ``T`` (full for the Ferraris
method), else the lumped ``T``; g per raw unit; :func:`~.base.linear_part`) is written with ``M_a = g M`` in m/s² per raw unit split as
``M_a⁻¹ = K_a R_a`` (``K_a`` diagonal, the norms of the rows of ``M_a⁻¹``; ``R_a`` then has unit
rows, as imucal's own ``R_a = K_a⁻¹ U_a_d / 2g``, ``ferraris_calibration.py`` eq. 22), and
``b_a = o``: imucal's output is then optcal's in m/s², ``g = 9.80665`` (what ``optcal apply
--units m/s^2`` writes), or a peer calibration's own g when it came from imucal or imu_tk.  The
gyroscope ``ω = T_g (g − b_g − G_g ā)`` (rad/s) likewise: ``M_g = (180/π) T_g`` in deg/s per
gyro unit, ``b_g``, ``K_ga = G_g / g``.  The comment states the g, so that optcal reads the file
back exactly (:mod:`optcal.families.peer_files`).  An ``extended`` calibration is written as its lumped part, and
the loss of its dropped terms measured on its poses (:func:`~.intrinsics.accel_loss`).
"""

from __future__ import annotations

import json
from importlib import metadata

import numpy as np
from numpy.typing import NDArray

from optcal.applications.export.base import ExportOptions, ExportResult, linear_part
from optcal.applications.export.intrinsics import accel_loss
from optcal.core.jsonio import jsonable
from optcal.core.model import STANDARD_GRAVITY
from optcal.families.caltypes.base import Calibration

#: imucal's file format version (``imucal/calibration_info.py``, ``_CAL_FORMAT_VERSION``).
IMUCAL_FORMAT_VERSION: str = "2.0.0"
#: deg/s per rad/s.
DEG_PER_RAD: float = float(180.0 / np.pi)


def split(M: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``K``, ``R`` with ``M = R⁻¹ K⁻¹``: ``K`` diagonal positive, ``R`` with unit rows (imucal's form)."""
    inv = np.linalg.inv(M)
    k = np.linalg.norm(inv, axis=1)
    return np.diag(k), inv / k[:, None]


def _version() -> str:
    try:
        return metadata.version("optcal")
    except metadata.PackageNotFoundError:
        return "(version unknown)"


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """imucal's calibration JSON of ``cal`` (module docstring)."""
    g = float(getattr(cal, "gravity_m_s2", STANDARD_GRAVITY))
    M, o, matrix = linear_part(cal)  # its own frame, in which the gyroscope's T_g is stated
    K_a, R_a = split(g * M)
    mapped = [f"accelerometer {matrix} x {g:g} m/s^2 -> K_a, R_a (m/s^2 per {cal.units}); o -> b_a ({cal.units})"]
    dropped: list[str] = []
    notes = [f"imucal calibrate(acc, gyr, acc_unit={cal.units!r}, ...) returns m/s^2 at g = {g:g} m/s^2 and deg/s"]
    loss = None
    if cal.cal_type == "extended":
        dropped.append("the extended terms (temperature, drift, nonlinearity): imucal's Ferraris model has none; "
                       "the lumped part at the reference temperature and time is written")
        # what that costs, measured on the poses as for every format that drops terms (refused above max_loss_g)
        loss = accel_loss(cal, options, lambda raw: (raw - o) @ M.T, "imucal")
    gyro = getattr(cal, "gyro", None)
    gyro_units = getattr(cal, "gyro_units", None)
    if gyro is not None and gyro_units is not None:
        K_g, R_g = split(DEG_PER_RAD * gyro.T)
        b_g = gyro.bias
        G = gyro.g_sensitivity
        K_ga = np.zeros((3, 3)) if G is None else G / g  # gyro units per g -> per m/s^2
        mapped.append(f"gyroscope T_g x 180/pi -> K_g, R_g (deg/s per {gyro_units}); b_g; "
                      + ("G_g / g -> K_ga" if G is not None else "no g-sensitivity: K_ga = 0"))
        from_gyr = gyro_units
    else:
        K_g, R_g, b_g, K_ga = np.eye(3), np.eye(3), np.zeros(3), np.zeros((3, 3))
        from_gyr = "deg/s"
        notes.append("the calibration has no gyroscope: K_g = R_g = I, b_g = 0, K_ga = 0 (imucal passes deg/s through; "
                     "its calibrate() needs every matrix)")
    d = {
        "acc_unit": "m/s^2",
        "gyr_unit": "deg/s",
        "from_acc_unit": cal.units,
        "from_gyr_unit": from_gyr,
        "comment": f"g = {g!r} m/s^2; exported by optcal {_version()} from {options.source}: {cal.describe()}",
        "K_a": K_a, "R_a": R_a, "b_a": o, "K_g": K_g, "R_g": R_g, "K_ga": K_ga, "b_g": b_g,
        "cal_type": "Ferraris",
        "_format_version": IMUCAL_FORMAT_VERSION,
    }
    if cal.cal_type == "imu" or cal.fitted_on is not None:
        dropped.append("the fit's statistics and poses (imucal's file holds the matrices only)")
    # indented by 4, as imucal's own to_json_file writes it
    return ExportResult("imucal", json.dumps(jsonable(d), indent=4, allow_nan=False) + "\n", loss, mapped, dropped, notes)
