"""The per-axis model of ArduPilot and PX4, built from an optcal calibration, and what it loses.

Both firmwares correct each accelerometer axis on its own, in m/s² of the driver's output::

    a_i = (raw_i − thermal_i(T) − offset_i) · scale_i        (m/s² in, m/s² out)

(ArduPilot ``AP_InertialSensor_Backend::_rotate_and_correct_accel``; PX4
``calibration::Accelerometer::Correct`` in ``src/lib/sensor_calibration/Accelerometer.hpp``),
with ``thermal_i(T)`` a polynomial in the temperature clamped to the calibrated range.

From optcal's ``ā = T (a − o)`` (g out, raw units in) the model keeps the bias ``o`` and, per
axis, the scale ``s_i = √A_ii`` (``A = TᵀT``): the norm of column i of ``T``, so that a force
along one sensor axis keeps its magnitude; the cross-axis terms of ``A`` (non-orthogonality)
are lost.  With ``k`` the factor from raw units to m/s² (1 for m/s², g for g, g/counts_per_g for
counts), ``z`` the raw reading the driver subtracts before scaling (counts only: 32768 for
unsigned 16-bit data around mid-scale, else 0; :func:`driver_zero`) and ``g`` standard gravity,
the driver's output is ``raw_ms2 = k (a − z)`` and::

    offset_i = k (o_i − z),     scale_i = g s_i / k

An extended calibration's ``temperature_bias`` terms are exact offset polynomials: optcal adds
``S_i Σ_p k_ip (T − T_ref)^p`` (raw units, ``S_i`` the axis sensitivity) to output i, so
``thermal_i(T) = k S_i Σ_p k_ip (T − T_ref)^p``.  ``temperature_scale``, ``bias_drift`` and
``scale_nonlinearity`` have no firmware parameter and are dropped.  :func:`measure_loss` says, on
the calibration's own poses, what all of this costs; :func:`write_firmware` writes the parameter
file of a :class:`FirmwareFormat` (ArduPilot's, PX4's).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.families.caltypes.base import Calibration, FitPoses
from optcal.families.caltypes.extended import ExtendedCalibration
from optcal.data.units import nominal_conversion
from optcal.errors import InputError
from optcal.applications.export.base import ExportOptions, ExportResult, LossReport
from optcal.core.model import AXES, STANDARD_GRAVITY
from optcal.core.stats import rms

#: Highest order of the firmwares' thermal offset polynomials (ArduPilot ACC1..3, PX4 X1..X3).
THERMAL_ORDER: int = 3


def ms2_per_raw_unit(units: str, counts_per_g: float | None) -> float:
    """The factor ``k`` from the calibration's raw units to m/s² of the driver's output."""
    if units == "m/s^2":
        return 1.0
    if units == "g":
        return STANDARD_GRAVITY
    if counts_per_g is None or not counts_per_g > 0:
        raise InputError(
            "the calibration takes raw counts, but firmware parameters are in m/s² of the driver's output: "
            "give counts_per_g (the sensitivity the driver divides by, e.g. 16384 for an MPU-6050 at ±2 g; "
            "see the sensor's datasheet)"
        )
    return STANDARD_GRAVITY / float(counts_per_g)


@dataclass(frozen=True)
class ThermalOffset:
    """``thermal_i(T) = Σ_p c_ip (clamp(T, tmin, tmax) − temp_ref)^p``, m/s².

    Attributes
    ----------
    coefficients : ndarray, shape (3, 3)
        Row i: axis i, orders 1..3, m/s²/°C^p.
    temp_ref, tmin, tmax : float
        °C.
    """

    coefficients: NDArray[np.float64]
    temp_ref: float
    tmin: float
    tmax: float

    def __call__(self, temp: ArrayLike) -> NDArray[np.float64]:
        dT = np.clip(np.asarray(temp, dtype=float), self.tmin, self.tmax) - self.temp_ref
        powers = np.column_stack([dT**p for p in range(1, THERMAL_ORDER + 1)])
        return powers @ self.coefficients.T


@dataclass(frozen=True)
class DiagonalModel:
    """Offsets, diagonal scales and an optional thermal offset: the firmware model (module docstring).

    Attributes
    ----------
    offset_ms2 : ndarray, shape (3,)
    scale : ndarray, shape (3,)
    thermal : ThermalOffset or None
    ms2_per_raw : float
        ``k``: raw units of the calibration → m/s².
    raw_zero : float
        ``z``: the raw reading the driver subtracts before scaling (counts; 0 otherwise).
    zero_reason : str or None
        Why ``raw_zero`` is not 0 (given, or found in the poses).
    mapped, dropped : tuple of str
        optcal terms kept, and terms the model cannot hold (with the reason).
    """

    offset_ms2: NDArray[np.float64]
    scale: NDArray[np.float64]
    thermal: ThermalOffset | None
    ms2_per_raw: float
    raw_zero: float
    zero_reason: str | None
    mapped: tuple[str, ...]
    dropped: tuple[str, ...]

    def raw_to_ms2(self, raw: ArrayLike) -> NDArray[np.float64]:
        """The driver's output ``k (a − z)``, m/s², of samples ``raw`` in the calibration's units."""
        return (np.asarray(raw, dtype=float) - self.raw_zero) * self.ms2_per_raw

    def correct_ms2(self, raw_ms2: ArrayLike, temp: ArrayLike | None = None) -> NDArray[np.float64]:
        """``(raw − thermal(T) − offset) · scale`` per axis, m/s²."""
        a = np.asarray(raw_ms2, dtype=float).reshape(-1, 3)
        if self.thermal is not None:
            if temp is None:
                raise InputError("the exported model has thermal terms: give the temperature of each sample")
            a = a - self.thermal(temp)
        return (a - self.offset_ms2) * self.scale


def driver_zero(cal: Calibration, options: ExportOptions) -> tuple[float, str | None]:
    """``z``, the raw reading the driver subtracts before scaling, and why it is not 0.

    ``options.counts_zero`` when given; else, for a calibration in counts whose poses are
    unsigned 16-bit counts around mid-scale (:func:`optcal.data.units.nominal_conversion`, the
    test of ``optcal check``), the mid-scale 32768: a driver that outputs m/s² has removed it.
    """
    if cal.units != "counts":
        if options.counts_zero:
            raise InputError(f"counts_zero applies to a calibration in counts; this one is in {cal.units}")
        return 0.0, None
    if options.counts_zero is not None:
        z = float(options.counts_zero)
        return z, (f"counts zero {z:g} (given): subtracted from the offsets, as the driver subtracts it" if z else None)
    mid_scale = nominal_conversion("counts", loss_poses(cal, options).acc).offset
    if not np.any(mid_scale):
        return 0.0, None
    z = float(mid_scale[0])
    return z, (f"the poses are unsigned 16-bit counts around mid-scale {z:g} (as optcal check finds); a driver that "
               f"outputs m/s² has removed it, so it is subtracted from the offsets")


def diagonal_model(cal: Calibration, options: ExportOptions) -> DiagonalModel:
    """The per-axis firmware model of ``cal`` (module docstring)."""
    k = ms2_per_raw_unit(cal.units, options.counts_per_g)
    z, zero_reason = driver_zero(cal, options)
    lumped = cal.lumped()
    A = lumped.T.T @ lumped.T
    s = np.sqrt(np.diag(A))
    mapped = ["bias o (offsets)", "scale: sqrt(A_ii) per axis (scales)"]
    dropped = ["cross-axis terms of T (non-orthogonality A_xy, A_xz, A_yz): the scales are per axis"]
    thermal = None
    if isinstance(cal, ExtendedCalibration) and cal.terms:
        S = cal.model.sensitivity()
        c = np.zeros((3, THERMAL_ORDER))
        for term in cal.terms:
            name = f"{term.effect} on {term.axis} (order {term.order})"
            if term.effect == "temperature_bias":
                i = AXES.index(term.axis)
                c[i, : term.order] = k * S[i] * np.asarray(term.coefficients)
                mapped.append(f"{name} (thermal offset polynomial)")
            else:
                why = {
                    "temperature_scale": "the firmware's thermal correction is an offset only",
                    "bias_drift": "the firmware has no time-dependent correction",
                    "scale_nonlinearity": "the firmware model is linear",
                }[term.effect]
                dropped.append(f"{name}: {why}")
        if np.any(c):
            if cal.validity.temp is None or cal.temp_ref is None:
                raise InputError("the calibration has temperature terms but no fitted temperature range (validity.temp)")
            thermal = ThermalOffset(c, float(cal.temp_ref), *cal.validity.temp)
    return DiagonalModel(k * (lumped.o - z), STANDARD_GRAVITY * s / k, thermal, k, z, zero_reason, tuple(mapped),
                         tuple(dropped))


def loss_poses(cal: Calibration, options: ExportOptions) -> FitPoses:
    """The poses to measure the loss on: ``options.poses``, else the calibration's own."""
    poses = options.poses if options.poses is not None else cal.fitted_on
    if poses is None:
        raise InputError(
            "the calibration file holds no fitted poses (fitted_on), so the loss of the simpler model cannot be "
            "measured: pass poses= (the pose table or recording it was fitted on)"
        )
    for column in cal.needs:
        if getattr(poses, column) is None:
            raise InputError(f"the poses have no {column!r} column, which the calibration needs")
    return poses


def measure_loss(cal: Calibration, model: DiagonalModel, options: ExportOptions, firmware: str) -> LossReport:
    """rms ``|a| − 1`` of ``cal`` and of ``model`` on the poses; refused above ``options.max_loss_g``."""
    poses = loss_poses(cal, options)
    full = cal.norm_errors(poses.acc, poses.temp, poses.t)
    exported = np.linalg.norm(model.correct_ms2(model.raw_to_ms2(poses.acc), poses.temp), axis=1) / STANDARD_GRAVITY - 1.0
    report = LossReport(poses.n, rms(full), rms(exported))
    if report.loss_g > options.max_loss_g:
        raise InputError(
            f"the {firmware} model (per-axis offsets and scales) would lose too much: {report.describe()}, more "
            f"than max_loss_g = {options.max_loss_g * 1e3:g} mg; it cannot hold "
            + "; ".join(model.dropped)
            + ". Raise max_loss_g to export anyway, or use the c exporter, which keeps the whole model"
        )
    return report


#: The IMU instances both firmwares name in their classic parameters (ArduPilot's first three IMUs,
#: PX4's calibration slots 0-2).
INSTANCES: tuple[int, ...] = (0, 1, 2)
#: Device ids are unsigned 32-bit numbers that both firmwares store in an int32 parameter.
DEVICE_ID_LIMIT: int = 2**32


@dataclass(frozen=True)
class Param:
    """One firmware parameter: its name, its value and whether the firmware stores it as an int32."""

    name: str
    value: float
    integer: bool = False

    def text(self) -> str:
        """The value as written: an integer's digits, a float to 9 significant digits (float32 exactly)."""
        return str(int(self.value)) if self.integer else f"{self.value:.9g}"


def per_axis(template: str, values: ArrayLike) -> list[Param]:
    """One float parameter per axis: ``template`` with ``{axis}`` (X, Y, Z) filled in."""
    return [Param(template.format(axis=axis), float(v)) for axis, v in zip("XYZ", np.asarray(values, dtype=float))]


def device_id_param(name: str, device_id: int, what: str) -> tuple[Param, str | None]:
    """The int32 parameter of an unsigned 32-bit device id, and a note when the two spellings differ."""
    if not 0 < device_id < DEVICE_ID_LIMIT:
        raise InputError(f"the {what} device id must be a positive 32-bit number, got {device_id}")
    stored = device_id - DEVICE_ID_LIMIT if device_id >= DEVICE_ID_LIMIT // 2 else device_id
    note = None if stored == device_id else f"{name} = {device_id} is written as the int32 the firmware stores, {stored}"
    return Param(name, stored, integer=True), note


def device_id_entry(name: str, device_id: int | None, what: str, missing: str, params: list[Param], mapped: list[str],
                    notes: list[str]) -> Param | None:
    """One sensor's device id into a parameter file: its parameter (appended to ``params``, and returned), the line
    saying it was mapped and the note on its int32 spelling; or, without an id, the note ``missing`` (what the
    firmware needs)."""
    if device_id is None:
        notes.append(missing)
        return None
    param, note = device_id_param(name, device_id, what)
    params.append(param)
    mapped.append(f"{what} device id ({name} = {device_id})")
    notes += [note] if note else []
    return param


@dataclass(frozen=True)
class FirmwareNames:
    """The parameter names of one IMU instance (``{axis}``: X, Y, Z) and of its thermal group."""

    acc_offset: str
    acc_scale: str
    acc_id: str
    gyro_offset: str
    gyro_id: str
    thermal: str


@dataclass(frozen=True)
class FirmwareFormat:
    """How one firmware's parameter file writes the per-axis model.

    Attributes
    ----------
    name : str
        The export format (``"ardupilot"``), named in the loss refusal and the result.
    header : tuple of str
        The file's first comments; ``{source}``, ``{imu}`` (1, 2, 3) and the :class:`FirmwareNames`
        fields are filled in.
    names : callable
        The :class:`FirmwareNames` of an instance (0, 1, 2).
    note : str
        What the user must always know about the file (frames).
    id_missing, gyro_id_missing : str
        The notes when the accelerometer's (gyroscope's) device id is not given (names filled in).
    gyro_note : str
        What the user must know about the gyro offsets.
    thermal_untouched : str
        The note when the file writes no thermal terms (names filled in).
    gyro_header : str
        The comment saying how the firmware applies the gyro offsets (``imu`` calibrations).
    thermal_block : callable
        ``(thermal, names, acc_id_param)`` → the parameters and notes of the thermal offset polynomial.
    render : callable
        ``(comments, params, options)`` → the file's text.
    """

    name: str
    header: tuple[str, ...]
    names: Callable[[int], FirmwareNames]
    note: str
    id_missing: str
    gyro_id_missing: str
    gyro_note: str
    thermal_untouched: str
    gyro_header: str
    thermal_block: Callable[[ThermalOffset, FirmwareNames, "Param | None"], tuple[list[Param], list[str]]]
    render: Callable[[list[str], list[Param], ExportOptions], str]


def write_firmware(cal: Calibration, options: ExportOptions, firmware: FirmwareFormat) -> ExportResult:
    """The parameter file of ``firmware`` for ``cal``: its per-axis model, refused above ``options.max_loss_g``.

    The comments are the header, the loss figures, the zero reading subtracted from counts (when
    one is) and every term the file cannot hold, with what it costs; the parameters are the
    device ids (when given), the accelerometer's offsets and scales, the gyroscope's offsets (an
    ``imu`` calibration, :mod:`.firmware_gyro`) and the thermal block (when the model has one).
    The notes say what the firmware needs besides the file (device ids, its own settings).

    Parameters
    ----------
    cal : Calibration
    options : ExportOptions
    firmware : FirmwareFormat

    Returns
    -------
    ExportResult
    """
    from optcal.applications.export.firmware_gyro import gyro_offsets

    if options.instance not in INSTANCES:
        raise InputError(f"instance must be one of {', '.join(map(str, INSTANCES))} (the first, second or third IMU), "
                         f"got {options.instance}")
    names = firmware.names(options.instance)
    fill = {"imu": options.instance + 1, "instance": options.instance,
            **{k: v.replace("{axis}", "*") for k, v in names.__dict__.items()}}  # CAL_ACC0_*OFF in prose
    model = diagonal_model(cal, options)
    loss = measure_loss(cal, model, options, firmware.name)
    gyro = gyro_offsets(cal, options, model.raw_zero)
    if gyro is None and (options.gyro_device_id is not None or options.gyro_counts_per_dps() is not None):
        raise InputError(f"gyro_device_id and counts_per_dps apply to an imu calibration (accelerometer and gyroscope); "
                         f"this is a {cal.cal_type!r} calibration, which has no gyroscope")
    if gyro is None and options.recording is not None:
        raise InputError("a recording's moves measure a gyroscope's loss; this is a "
                         f"{cal.cal_type!r} calibration, which has no gyroscope")
    mapped = list(model.mapped) + (list(gyro.mapped) if gyro is not None else [])
    dropped = list(model.dropped) + (list(gyro.dropped) if gyro is not None else [])
    comments = [line.format(source=options.source, **fill) for line in firmware.header]
    comments += [firmware.gyro_header.format(**fill)] if gyro is not None else []
    comments.append(loss.describe())
    if gyro is not None and gyro.moves_line is not None:
        comments.append(gyro.moves_line)
    if model.zero_reason:
        comments.append(model.zero_reason)
    comments += [f"not exported: {d}" for d in dropped]
    notes = [firmware.note]
    params: list[Param] = []
    acc_id = device_id_entry(names.acc_id, options.device_id, "accelerometer", firmware.id_missing.format(**fill),
                             params, mapped, notes)
    params += per_axis(names.acc_offset, model.offset_ms2) + per_axis(names.acc_scale, model.scale)
    if model.zero_reason:
        notes.append(f"{model.zero_reason}; counts_zero=VALUE sets another zero reading")
    if gyro is not None:
        device_id_entry(names.gyro_id, options.gyro_device_id, "gyroscope", firmware.gyro_id_missing.format(**fill),
                        params, mapped, notes)
        params += per_axis(names.gyro_offset, gyro.offset_rad_s)
        notes.append(firmware.gyro_note.format(**fill))
        notes += [gyro.moves_line] if gyro.moves_line is not None else []
    if model.thermal is not None:
        thermal_params, thermal_notes = firmware.thermal_block(model.thermal, names, acc_id)
        params += thermal_params
        notes += thermal_notes
    else:
        notes.append(firmware.thermal_untouched.format(**fill))
    return ExportResult(firmware.name, firmware.render(comments, params, options), loss, mapped, dropped, notes)


def render_lines(prefix: str, separator: str) -> Callable[[list[str], list[Param], ExportOptions], str]:
    """A renderer writing ``# comment`` lines, then ``prefix NAME separator VALUE`` per parameter."""

    def render(comments: list[str], params: list[Param], options: ExportOptions) -> str:
        lines = [f"# {c}" for c in comments] + [f"{prefix}{p.name}{separator}{p.text()}" for p in params]
        return "\n".join(lines) + "\n"

    return render
