"""The calibration type family: one versioned file format, one class per ``cal_type``.

===============  ==========================================================  =======================
``cal_type``     equation                                                    class
===============  ==========================================================  =======================
``lumped``       ``ā = T (a − o)``, T canonical lower-triangular (Lu 2017)    :class:`LumpedCalibration`
``sixpos_full``  ``ā = W a + V``, W full (Yin 2014, eq. 3)                   :class:`SixPositionCalibration`
``extended``     lumped + temperature, drift and nonlinearity terms          :class:`ExtendedCalibration`
``imu``          lumped + gyro ``ω = T_g (g − b_g − G_g ā)`` (Tedaldi 2014)  :class:`optcal.families.gyro.result.ImuCalibration`
===============  ==========================================================  =======================

Reading a file of any type is :func:`optcal.families.calibration_files.load`, which looks the
``cal_type`` up in its registry; the registry lives there, above this package and
:mod:`optcal.families.gyro`, because the ``imu`` type holds the accelerometer's fit result
(:mod:`optcal.families.accel.result`), which imports these types.  The file format (format version,
JSON writing) is :mod:`optcal.core.jsonio`'s.
"""

from __future__ import annotations

from optcal.families.caltypes.base import Calibration, FitPoses, ValidityRangeWarning
from optcal.families.caltypes.extended import ExtendedCalibration, ExtendedTerm, ValidityRange
from optcal.families.caltypes.lumped import LumpedCalibration
from optcal.families.caltypes.sixpos import SixPositionCalibration

__all__ = [
    "Calibration",
    "ExtendedCalibration",
    "ExtendedTerm",
    "FitPoses",
    "LumpedCalibration",
    "SixPositionCalibration",
    "ValidityRange",
    "ValidityRangeWarning",
]
