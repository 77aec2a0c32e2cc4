"""C99: a header that applies the calibration, with the numbers baked in and a test vector.

``optcal_apply_accel(const double raw[3], double out_g[3])`` reproduces
:meth:`Calibration.correct <optcal.families.caltypes.base.Calibration.correct>` (and so ``optcal apply``)
to round-off: ``T (raw − o)`` for ``lumped``, ``W raw + V`` for ``sixpos_full``.  For
``extended`` the header also declares ``optcal_apply_accel_tt(raw, temp_c, t_s, out_g)``, the
per-axis closed-form inversion of :func:`optcal.core.extended_model.invert_axis` followed by ``T y``;
``optcal_apply_accel`` then applies it at the reference temperature and time.  The accelerometer's
matrix is the one ``apply`` applies (:func:`~optcal.applications.export.base.linear_part`: a full
``W`` of a Ferraris ``imu`` or a peer's file kept, never turned into the canonical ``T``).  For a
calibration with a gyroscope (``imu``; a ``peer`` read from imucal's or imu_tk's files) the header
also declares ``optcal_apply_gyro(raw, out_rad_s)``, ``T_g (g − b_g)`` (Tedaldi 2014, eq. 9; :meth:`ImuCalibration.correct_gyro
<optcal.families.gyro.result.ImuCalibration.correct_gyro>`), or with a g-sensitivity
``optcal_apply_gyro(raw, raw_acc, out_rad_s)``, ``T_g (g − b_g − G_g ā)`` with ``ā`` the
calibrated accelerometer sample.  The functions are ``static inline`` so that the header can be
included in several translation units.  No validity-range check is made in C: the range is
written in a comment.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.families.caltypes.base import Calibration, ValidityRangeWarning
from optcal.families.caltypes.extended import ExtendedCalibration
from optcal.families.caltypes.sixpos import SixPositionCalibration
from optcal.core.extended_model import MAX_ORDER
from optcal.applications.export.base import ExportOptions, ExportResult, linear_part

GUARD = "OPTCAL_ACCEL_CALIBRATION_H"


def c_number(x: float) -> str:
    """A double written so that a C compiler reads back exactly the same value."""
    text = repr(float(x))
    return text if any(c in text for c in ".en") else text + ".0"


def c_array(a: NDArray[np.float64]) -> str:
    """A nested C initialiser ``{{...}, {...}}`` for a 1-D or 2-D array."""
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        return "{" + ", ".join(c_number(v) for v in a) + "}"
    return "{" + ", ".join(c_array(row) for row in a) + "}"


def sample_vector(cal: Calibration) -> tuple[NDArray[np.float64], float | None, float | None, NDArray[np.float64]]:
    """A raw sample (the first fitted pose, else the one reading +1 g on z), its temperature/time and output."""
    lumped = cal.lumped()
    temp = t = None
    if cal.fitted_on is not None:
        raw = cal.fitted_on.acc[0]
        temp = None if cal.fitted_on.temp is None else float(cal.fitted_on.temp[0])
        t = None if cal.fitted_on.t is None else float(cal.fitted_on.t[0])
    else:
        raw = lumped.o + np.linalg.solve(lumped.T, [0.0, 0.0, 1.0])
    if isinstance(cal, ExtendedCalibration):  # a column the model does not use: its reference value
        temp = cal.model.temp_ref if temp is None or "temp" not in cal.needs else temp
        t = cal.model.t_ref if t is None or "t" not in cal.needs else t
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityRangeWarning)
        out = cal.correct(raw, temp, t)[0]
    return np.asarray(raw, float), temp, t, out


def linear_body(cal: Calibration) -> list[str]:
    """Constants and the function of a lumped or six-position calibration."""
    if isinstance(cal, SixPositionCalibration):
        return [
            "/* out_g = W raw + V (Yin 2014, eq. 3) */",
            f"static const double OPTCAL_W[3][3] = {c_array(cal.W)};",
            f"static const double OPTCAL_V[3] = {c_array(cal.V)};",
            "",
            "static inline void optcal_apply_accel(const double raw[3], double out_g[3])",
            "{",
            "    for (int i = 0; i < 3; ++i) {",
            "        out_g[i] = OPTCAL_W[i][0] * raw[0] + OPTCAL_W[i][1] * raw[1] + OPTCAL_W[i][2] * raw[2] + OPTCAL_V[i];",
            "    }",
            "}",
        ]
    M, o, _ = linear_part(cal)  # the matrix apply applies (a peer's full W), not the canonical T of another frame
    return accel_lines(M, o)


def accel_lines(T: NDArray[np.float64], o: NDArray[np.float64]) -> list[str]:
    """The accelerometer's constants and ``optcal_apply_accel``: ``out_g = T (raw − o)``."""
    return [
        "/* out_g = T (raw - o) (Lu 2017, eq. 6) */",
        f"static const double OPTCAL_T[3][3] = {c_array(T)};",
        f"static const double OPTCAL_O[3] = {c_array(o)};",
        "",
        "static inline void optcal_apply_accel(const double raw[3], double out_g[3])",
        "{",
        "    const double d[3] = {raw[0] - OPTCAL_O[0], raw[1] - OPTCAL_O[1], raw[2] - OPTCAL_O[2]};",
        "    for (int i = 0; i < 3; ++i) {",
        "        out_g[i] = OPTCAL_T[i][0] * d[0] + OPTCAL_T[i][1] * d[1] + OPTCAL_T[i][2] * d[2];",
        "    }",
        "}",
    ]


def imu_body(cal: Calibration) -> list[str]:
    """Constants and functions of a calibration with a gyroscope (``imu``, a peer's): the accelerometer's
    ``T (a − o)`` as apply applies it (:func:`~.base.linear_part`) and the gyroscope's."""
    M, o, _ = linear_part(cal)
    gyro = getattr(cal, "gyro")
    G = gyro.g_sensitivity
    lines = [
        *accel_lines(M, o),
        "",
        "/* out_rad_s = Tg (raw - bg" + (" - Gg out_g(raw_acc)" if G is not None else "")
        + ") (Tedaldi 2014, eq. 9), rad/s in the calibrated accelerometer frame */",
        f"static const double OPTCAL_TG[3][3] = {c_array(gyro.T)};",
        f"static const double OPTCAL_BG[3] = {c_array(gyro.bias)};",
    ]
    if G is not None:
        lines += [
            f"static const double OPTCAL_GG[3][3] = {c_array(G)};",
            "",
            "static inline void optcal_apply_gyro(const double raw[3], const double raw_acc[3], double out_rad_s[3])",
            "{",
            "    double f[3], d[3];",
            "    optcal_apply_accel(raw_acc, f);",
            "    for (int i = 0; i < 3; ++i) {",
            "        d[i] = raw[i] - OPTCAL_BG[i] - (OPTCAL_GG[i][0] * f[0] + OPTCAL_GG[i][1] * f[1] + OPTCAL_GG[i][2] * f[2]);",
            "    }",
        ]
    else:
        lines += [
            "",
            "static inline void optcal_apply_gyro(const double raw[3], double out_rad_s[3])",
            "{",
            "    const double d[3] = {raw[0] - OPTCAL_BG[0], raw[1] - OPTCAL_BG[1], raw[2] - OPTCAL_BG[2]};",
        ]
    return lines + [
        "    for (int i = 0; i < 3; ++i) {",
        "        out_rad_s[i] = OPTCAL_TG[i][0] * d[0] + OPTCAL_TG[i][1] * d[1] + OPTCAL_TG[i][2] * d[2];",
        "    }",
        "}",
    ]


def gyro_vector(cal: Any, raw_acc: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A raw gyro sample reading a turn of (0.1, -0.2, 0.3) rad/s at the accelerometer sample ``raw_acc``, and its output."""
    rate = np.array([0.1, -0.2, 0.3])  # rad/s: a slow turn about every axis at once
    raw = cal.gyro.measure(rate, cal.correct(raw_acc) if cal.gyro.g_sensitivity is not None else None)[0]
    return raw, cal.correct_gyro(raw, raw_acc)[0]


def extended_body(cal: ExtendedCalibration) -> list[str]:
    """Constants and the two functions of an extended calibration."""
    model = cal.model
    c = model.coefficients
    pad = lambda effect: np.pad(c[effect], ((0, 0), (0, 3 - MAX_ORDER[effect])))  # noqa: E731
    return [
        "/* per axis i (optcal.core.extended_model.invert_axis): dT = temp_c - T_REF, dt = t_s - t_REF,",
        " *   bias = sum_p KB[i][p] dT^p + sum_p KD[i][p] dt^p   (g),  scale = sum_p KS[i][p] dT^p,",
        " *   w = (raw[i] - O[i] - S[i] bias) / (1 + scale),  y[i] = 2 w / (1 + sqrt(max(1 + 4 K2[i] w / S[i], 1e-6)));",
        " * then out_g = T y (Lu 2017, eq. 6).  Orders p = 1, 2, 3. */",
        f"static const double OPTCAL_T[3][3] = {c_array(cal.T)};",
        f"static const double OPTCAL_O[3] = {c_array(cal.o)};",
        f"static const double OPTCAL_S[3] = {c_array(model.sensitivity())};",
        f"static const double OPTCAL_TEMP_REF = {c_number(model.temp_ref)};",
        f"static const double OPTCAL_TIME_REF = {c_number(model.t_ref)};",
        f"static const double OPTCAL_KB[3][3] = {c_array(pad('temperature_bias'))};",
        f"static const double OPTCAL_KS[3][3] = {c_array(pad('temperature_scale'))};",
        f"static const double OPTCAL_KD[3][3] = {c_array(pad('bias_drift'))};",
        f"static const double OPTCAL_K2[3] = {c_array(c['scale_nonlinearity'][:, 0])};",
        "",
        "static inline void optcal_apply_accel_tt(const double raw[3], double temp_c, double t_s, double out_g[3])",
        "{",
        "    const double dT = temp_c - OPTCAL_TEMP_REF, dt = t_s - OPTCAL_TIME_REF;",
        "    const double pT[3] = {dT, dT * dT, dT * dT * dT}, pt[3] = {dt, dt * dt, dt * dt * dt};",
        "    double y[3];",
        "    for (int i = 0; i < 3; ++i) {",
        "        double bias = 0.0, scale = 0.0;",
        "        for (int p = 0; p < 3; ++p) {",
        "            bias += OPTCAL_KB[i][p] * pT[p] + OPTCAL_KD[i][p] * pt[p];",
        "            scale += OPTCAL_KS[i][p] * pT[p];",
        "        }",
        "        const double w = (raw[i] - OPTCAL_O[i] - OPTCAL_S[i] * bias) / (1.0 + scale);",
        "        y[i] = 2.0 * w / (1.0 + sqrt(fmax(1.0 + 4.0 * OPTCAL_K2[i] * w / OPTCAL_S[i], 1e-6)));",
        "    }",
        "    for (int i = 0; i < 3; ++i) {",
        "        out_g[i] = OPTCAL_T[i][0] * y[0] + OPTCAL_T[i][1] * y[1] + OPTCAL_T[i][2] * y[2];",
        "    }",
        "}",
        "",
        "/* at the reference temperature and time */",
        "static inline void optcal_apply_accel(const double raw[3], double out_g[3])",
        "{",
        "    optcal_apply_accel_tt(raw, OPTCAL_TEMP_REF, OPTCAL_TIME_REF, out_g);",
        "}",
    ]


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The C99 header of ``cal``."""
    raw, temp, t, out = sample_vector(cal)
    call = f"raw = {c_array(raw)}"
    if isinstance(cal, ExtendedCalibration):
        if temp is None or t is None:  # impossible: sample_vector gives an extended calibration its reference values
            raise AssertionError("the test vector of an extended calibration has no temperature or time")
        call += f", temp_c = {c_number(temp)}, t_s = {c_number(t)}  (optcal_apply_accel_tt)"
    imu = getattr(cal, "gyro", None) is not None  # imu, or a peer's calibration with a gyroscope
    lines = [
        f"/* optcal {'IMU' if imu else 'accelerometer'} calibration exported from {options.source}: {cal.describe()}.",
        f" * raw in {cal.units}, out_g in g.  Generated by optcal export --format c.",
        f" * Test vector: {call}",
        f" *   -> out_g = {c_array(out)}",
    ]
    if imu:
        raw_gyro, out_gyro = gyro_vector(cal, raw)
        with_acc = ", raw_acc = the accelerometer's test vector" if getattr(cal, "gyro").g_sensitivity is not None else ""
        lines += [f" * Gyroscope: raw in {getattr(cal, 'gyro_units')}, out_rad_s in rad/s (accelerometer frame).",
                  f" * Gyro test vector: raw = {c_array(raw_gyro)}{with_acc}",
                  f" *   -> out_rad_s = {c_array(out_gyro)}"]
    if isinstance(cal, ExtendedCalibration):
        v = cal.validity
        ranges = [f"{name} {span[0]:.6g}..{span[1]:.6g} {unit}" for name, span, unit in
                  (("temperature", v.temp, "C"), ("time", v.t, "s"), ("|a|", v.norm_g, "g")) if span is not None]
        terms = ", ".join(f"{term.effect}({term.axis}, order {term.order})" for term in cal.terms) or "none"
        lines.append(f" * Terms: {terms}.  Fitted on: {'; '.join(ranges) or 'no range stored'} (not checked here).")
    lines += [" */", f"#ifndef {GUARD}", f"#define {GUARD}", "", "#include <math.h>", ""]
    if imu:
        lines += imu_body(cal)
        G = getattr(cal, "gyro").g_sensitivity
        mapped = ["the whole accelerometer model T (a - o) (optcal_apply_accel)",
                  "the whole gyroscope model T_g (g - b_g" + (" - G_g a)" if G is not None else ")")
                  + ": scale, misalignment, bias" + (", g-sensitivity" if G is not None else "")
                  + " (optcal_apply_gyro, rad/s)"]
    else:
        lines += extended_body(cal) if isinstance(cal, ExtendedCalibration) else linear_body(cal)
        mapped = ["the whole model (optcal_apply_accel)"] + [f"{term.effect} on {term.axis}" for term in getattr(cal, "terms", ())]
    lines += ["", f"#endif /* {GUARD} */"]
    return ExportResult("c", "\n".join(lines) + "\n", None, mapped, [], [])
