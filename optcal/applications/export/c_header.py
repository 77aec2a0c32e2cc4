"""C99: a header that applies the calibration, with the numbers baked in and a test vector.

``optcal_apply_accel(const double raw[3], double out_g[3])`` reproduces
:meth:`Calibration.correct <optcal.families.caltypes.base.Calibration.correct>` (and so ``optcal apply``)
to round-off: ``T (raw − o)`` for ``lumped``, ``W raw + V`` for ``sixpos_full``.  For
``extended`` the header also declares ``optcal_apply_accel_tt(raw, temp_c, t_s, out_g)``, the
per-axis closed-form inversion of :func:`optcal.core.extended_model.invert_axis` followed by ``T y``;
``optcal_apply_accel`` then applies it at the reference temperature and time.  The functions
are ``static inline`` so that the header can be included in several translation units.  No
validity-range check is made in C: the range is written in a comment.
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from optcal.families.caltypes.base import Calibration, ValidityRangeWarning
from optcal.families.caltypes.extended import ExtendedCalibration
from optcal.families.caltypes.sixpos import SixPositionCalibration
from optcal.core.extended_model import MAX_ORDER
from optcal.applications.export.base import ExportOptions, ExportResult

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
    lumped = cal.lumped()
    return [
        "/* out_g = T (raw - o) (Lu 2017, eq. 6) */",
        f"static const double OPTCAL_T[3][3] = {c_array(lumped.T)};",
        f"static const double OPTCAL_O[3] = {c_array(lumped.o)};",
        "",
        "static inline void optcal_apply_accel(const double raw[3], double out_g[3])",
        "{",
        "    const double d[3] = {raw[0] - OPTCAL_O[0], raw[1] - OPTCAL_O[1], raw[2] - OPTCAL_O[2]};",
        "    for (int i = 0; i < 3; ++i) {",
        "        out_g[i] = OPTCAL_T[i][0] * d[0] + OPTCAL_T[i][1] * d[1] + OPTCAL_T[i][2] * d[2];",
        "    }",
        "}",
    ]


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
    lines = [
        f"/* optcal accelerometer calibration exported from {options.source}: {cal.describe()}.",
        f" * raw in {cal.units}, out_g in g.  Generated by optcal export --format c.",
        f" * Test vector: {call}",
        f" *   -> out_g = {c_array(out)}",
    ]
    if isinstance(cal, ExtendedCalibration):
        v = cal.validity
        ranges = [f"{name} {span[0]:.6g}..{span[1]:.6g} {unit}" for name, span, unit in
                  (("temperature", v.temp, "C"), ("time", v.t, "s"), ("|a|", v.norm_g, "g")) if span is not None]
        terms = ", ".join(f"{term.effect}({term.axis}, order {term.order})" for term in cal.terms) or "none"
        lines.append(f" * Terms: {terms}.  Fitted on: {'; '.join(ranges) or 'no range stored'} (not checked here).")
    lines += [" */", f"#ifndef {GUARD}", f"#define {GUARD}", "", "#include <math.h>", ""]
    lines += extended_body(cal) if isinstance(cal, ExtendedCalibration) else linear_body(cal)
    lines += ["", f"#endif /* {GUARD} */"]
    mapped = ["the whole model"] + [f"{term.effect} on {term.axis}" for term in getattr(cal, "terms", ())]
    return ExportResult("c", "\n".join(lines) + "\n", None, mapped, [], [])
