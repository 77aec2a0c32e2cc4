"""The magnetometer's calibration as the firmware's compass parameters: ArduPilot and PX4.

Upstream conventions:

* ArduPilot ``libraries/AP_Compass/AP_Compass_Backend.cpp``, ``correct_field``: ``field += offsets``
  then ``field = mat * field`` with ``mat`` the symmetric matrix of ``COMPASS_DIA_{X,Y,Z}`` on the
  diagonal and ``COMPASS_ODI_{X,Y,Z}`` = (xy, xz, yz) off it; the field in milligauss.  So
  ``corrected = M (raw + OFS)``: ``M = F T``, ``OFS = −k o`` with F the field strength and k the
  milligauss per data unit (the corrected field keeps the Earth's strength, as ArduPilot's own
  calibrator leaves it).  Names: ``COMPASS_OFS_*``, ``COMPASS_DIA_*``, ``COMPASS_ODI_*``,
  ``COMPASS_DEV_ID``; the second and third compass ``COMPASS_OFS2_*``/``DIA2``/``ODI2``/``DEV_ID2``
  and ``...3`` (``AP_Compass.cpp``, ``var_info``).
* PX4 ``src/lib/sensor_calibration/Magnetometer.cpp``: ``Correct`` returns
  ``_rotation * (_scale * (data − _offset))`` in gauss; ``set_offdiagonal`` fills the symmetric
  ``_scale`` from ``CAL_MAGn_{X,Y,Z}SCALE`` and ``CAL_MAGn_{X,Y,Z}ODIAG`` = (xy, xz, yz).  So
  ``S = F T``, ``OFF = k o`` with k the gauss per data unit; ``CAL_MAGn_ID`` the device id.

optcal's ``T`` is symmetric (:mod:`optcal.families.mag.fit`), the form both firmwares hold: the
file reproduces optcal's calibrated field exactly.  What it cannot hold is the rotation between
the magnetometer's and the accelerometer's frames (``R_mag_to_acc``, only 90° steps in
``COMPASS_ORIENT``/``CAL_MAGn_ROT``): reported with its angle.  A calibration in counts has no
field unit the firmware reads, and is refused naming ``--mag-units``.
"""

from __future__ import annotations

import numpy as np

from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.firmware import Param, device_id_param, per_axis, render_lines
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration
from optcal.families.mag.units import UT_PER_UNIT

#: The formats that hold a magnetometer calibration.
MAG_FORMATS: tuple[str, ...] = ("ardupilot", "px4", "px4-shell", "c")


def c_header(cal: Calibration, options: ExportOptions) -> str:
    """A C99 header applying the magnetometer's calibration (``optcal apply``'s ``T (m − o)``, unit norm for the
    undisturbed field), its numbers baked in, the field strength and a test vector (the raw sample that reads the
    field along +x)."""
    from optcal.applications.export.c_header import c_array, c_number

    T: np.ndarray = np.array(getattr(cal, "T"), dtype=np.float64)
    o: np.ndarray = np.array(getattr(cal, "o"), dtype=np.float64)
    raw = o + np.linalg.solve(T, [1.0, 0.0, 0.0])
    out = T @ (raw - o)
    guard = "OPTCAL_MAG_CALIBRATION_H"
    lines = [
        f"/* magnetometer calibration exported by optcal from {options.source} */",
        f"/* m_cal = T (m - o): |m_cal| = 1 for the undisturbed field; m in {cal.units}; the field strength "
        f"{cal.field_strength:.9g} {cal.units} (multiply m_cal by it for the field in {cal.units}) */",  # type: ignore[attr-defined]
        f"#ifndef {guard}", f"#define {guard}", "",
        f"#define OPTCAL_MAG_FIELD_STRENGTH {c_number(cal.field_strength)}  /* {cal.units} */",  # type: ignore[attr-defined]
        f"static const double OPTCAL_MAG_T[3][3] = {c_array(T)};  /* per {cal.units} */",
        f"static const double OPTCAL_MAG_O[3] = {c_array(o)};  /* {cal.units} (hard iron) */",
        *_c_planar_lines(cal),
        "",
        "static inline void optcal_apply_mag(const double raw[3], double out[3])",
        "{",
        "    double d[3];",
        "    for (int i = 0; i < 3; ++i) d[i] = raw[i] - OPTCAL_MAG_O[i];",
        "    for (int i = 0; i < 3; ++i)",
        "        out[i] = OPTCAL_MAG_T[i][0] * d[0] + OPTCAL_MAG_T[i][1] * d[1] + OPTCAL_MAG_T[i][2] * d[2];",
        "}",
        "",
        f"/* the field in {cal.units}, as optcal apply writes it: field_strength T (m - o) */",
        "static inline void optcal_apply_mag_field(const double raw[3], double out[3])",
        "{",
        "    optcal_apply_mag(raw, out);",
        "    for (int i = 0; i < 3; ++i) out[i] *= OPTCAL_MAG_FIELD_STRENGTH;",
        "}",
        "",
        f"/* test vector: optcal_apply_mag({c_array(raw)}) = {c_array(out)} */",
        f"#define OPTCAL_MAG_TEST_RAW {c_array(raw)}",
        f"#define OPTCAL_MAG_TEST_OUT {c_array(out)}",
        "",
        f"#endif /* {guard} */",
    ]
    return "\n".join(lines) + "\n"
def _c_planar_lines(cal: Calibration) -> list[str]:
    """A planar calibration's plane normal and what the header's ``T`` does along it (C lines; none for a 3-D one)."""
    from optcal.applications.export.c_header import c_array

    n = getattr(cal, "plane_normal", None)
    if n is None:
        return []
    return [f"/* planar (heading) calibration: in the plane normal to OPTCAL_MAG_PLANE_NORMAL the field is calibrated; "
            f"along it T holds 1/field_strength, so the field's normal component passes through uncalibrated (its hard "
            f"iron undetermined, 0 in O) */",
            f"static const double OPTCAL_MAG_PLANE_NORMAL[3] = {c_array(np.asarray(n, dtype=float))};"]


#: ArduPilot's largest accepted offset (COMPASS_OFFS_MAX's default, milligauss): beyond it the
#: firmware's pre-arm check fails ("Compass offsets too high").
ARDUPILOT_OFFS_MAX_MG: float = 1800.0


def _scaled(cal: Calibration, ut_per_out: float) -> tuple[np.ndarray, np.ndarray, float]:
    """``(F T, k o, k)``: the matrix and offset for a firmware reading the field in a unit of ``ut_per_out`` µT."""
    units = cal.units
    if units not in UT_PER_UNIT:
        raise InputError(f"the magnetometer calibration is in {units}, which the firmware cannot read; recalibrate "
                         f"with --mag-units (uT, nT, gauss, mgauss) stating the driver's units")
    k = UT_PER_UNIT[units] / ut_per_out
    M = cal.field_strength * np.asarray(cal.T)  # type: ignore[attr-defined]
    return M, k * np.asarray(cal.o), k  # type: ignore[attr-defined]


def ardupilot_names(instance: int) -> tuple[str, str, str, str]:
    """``COMPASS_OFS``, ``COMPASS_DIA``, ``COMPASS_ODI``, ``COMPASS_DEV_ID`` for compass ``instance`` (0, 1, 2)."""
    if instance not in (0, 1, 2):
        raise InputError(f"ArduPilot keeps three compasses' calibrations (instance 0, 1, 2), not {instance}")
    n = "" if instance == 0 else str(instance + 1)
    return f"COMPASS_OFS{n}", f"COMPASS_DIA{n}", f"COMPASS_ODI{n}", f"COMPASS_DEV_ID{n}"


def _rotation_note(cal: Calibration) -> list[str]:
    R = getattr(cal, "R_mag_to_acc", None)
    if R is None:
        return []
    angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))
    return [f"not held: the {angle:.2f} deg rotation of the magnetometer's frame into the accelerometer's "
            f"(R_mag_to_acc in the calibration): the firmware's orientation parameter takes 90 deg steps only"]


def _planar_note(cal: Calibration) -> str | None:
    """What a planar (heading) calibration leaves out of a 3-D one (:mod:`optcal.families.mag.planar`), or None."""
    if getattr(cal, "plane_normal", None) is None:
        return None
    p = getattr(cal, "info", {}).get("planar", {})
    n = ", ".join(f"{v:+.3f}" for v in getattr(cal, "plane_normal"))
    return (f"the hard iron along the plane's normal [{n}] is undetermined (written as 0) and the field strength is the "
            f"field in the plane; {p.get('tilt_heading_error', 'a hard iron ε along the normal moves the heading by about ε sin θ / H at a tilt θ')}")


def export(cal: Calibration, fmt: str, options: ExportOptions) -> ExportResult:
    """The compass parameters of a ``magnetometer`` calibration in ``fmt`` (module docstring).

    Raises
    ------
    InputError
        A format that holds no magnetometer calibration, a calibration in counts, or a planar (heading) calibration
        for a 3-D firmware without ``options.accept_planar``.
    """
    if fmt not in MAG_FORMATS:
        raise InputError(f"--format {fmt} holds no magnetometer calibration; export a magnetometer with "
                         f"--format {', '.join(MAG_FORMATS)}")
    comments = [f"magnetometer calibration exported by optcal from {options.source}"]
    notes = _rotation_note(cal)
    planar = _planar_note(cal)
    if fmt == "c":
        return ExportResult(format=fmt, text=c_header(cal, options), mapped=["T", "o", "field_strength"], dropped=[],
                            notes=notes + ([planar] if planar else []))
    if planar and not options.accept_planar:
        raise InputError(f"--format {fmt} needs a 3-D magnetometer calibration and this one is planar: {planar}; "
                         f"--accept-planar writes it anyway (--format c holds it exactly)")
    if planar:
        notes.append(planar)
    if fmt == "ardupilot":
        M, ko, _ = _scaled(cal, 0.1)  # milligauss
        ofs, dia, odi, dev = ardupilot_names(options.instance)
        offsets = -ko
        params = per_axis(ofs + "_{axis}", offsets) + per_axis(dia + "_{axis}", np.diag(M)) \
            + per_axis(odi + "_{axis}", [M[0, 1], M[0, 2], M[1, 2]])
        comments.append("applied upstream as field = M (raw + OFS), milligauss (AP_Compass_Backend.cpp, correct_field)")
        if np.max(np.abs(offsets)) > ARDUPILOT_OFFS_MAX_MG:
            notes.append(f"an offset of {np.max(np.abs(offsets)):.0f} mG exceeds COMPASS_OFFS_MAX ({ARDUPILOT_OFFS_MAX_MG:.0f}): "
                         f"ArduPilot's pre-arm check will refuse it unless COMPASS_OFFS_MAX is raised")
        if options.device_id is not None:
            param, note = device_id_param(dev, options.device_id, "compass")
            params.append(param)
            notes += [note] if note else []
        else:
            notes.append(f"{dev} is not written (device_id=N writes it): ArduPilot applies the calibration to the "
                         f"compass whose id is in {dev}")
        text = render_lines("", ",")(comments + notes, params, options)
    else:
        M, ko, _ = _scaled(cal, 100.0)  # gauss
        p = f"CAL_MAG{options.instance}_"
        params = per_axis(p + "{axis}OFF", ko) + per_axis(p + "{axis}SCALE", np.diag(M)) \
            + per_axis(p + "{axis}ODIAG", [M[0, 1], M[0, 2], M[1, 2]])
        comments.append("applied upstream as field = S (raw - OFF), gauss (Magnetometer.cpp, Correct)")
        if options.device_id is not None:
            param, note = device_id_param(p + "ID", options.device_id, "compass")
            params.append(param)
            notes += [note] if note else []
        else:
            notes.append(f"{p}ID is not written (device_id=N writes it): PX4 applies the calibration to the sensor "
                         f"whose id is in {p}ID")
        if fmt == "px4":
            from optcal.applications.export.px4 import render_qgc

            text = render_qgc(comments + notes, params, options)
        else:
            text = render_lines("param set ", " ")(comments + notes, params, options)
    return ExportResult(format=fmt, text=text, mapped=[q.name for q in params], dropped=[], notes=notes)
