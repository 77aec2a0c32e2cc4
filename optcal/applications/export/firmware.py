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


@dataclass(frozen=True)
class FirmwareFormat:
    """How one firmware's parameter file writes the per-axis model.

    Attributes
    ----------
    name : str
        The export format (``"ardupilot"``), named in the loss refusal and the result.
    header : tuple of str
        The file's first lines; ``{source}`` is filled in with where the calibration came from.
    offset_line, scale_line : str
        :func:`per_axis` templates of one offset and one scale parameter.
    note : str
        What the user must always know about the file (frames, ids optcal cannot fill in).
    thermal_block : callable
        The lines and notes of the thermal offset polynomial, from the model's :class:`ThermalOffset`.
    """

    name: str
    header: tuple[str, ...]
    offset_line: str
    scale_line: str
    note: str
    thermal_block: Callable[[ThermalOffset], tuple[list[str], list[str]]]


def write_firmware(cal: Calibration, options: ExportOptions, firmware: FirmwareFormat) -> ExportResult:
    """The parameter file of ``firmware`` for ``cal``: its per-axis model, refused above ``options.max_loss_g``.

    The file is the header (``{source}`` filled in), the loss figures, the zero reading subtracted
    from counts (when one is) and every term the model cannot hold as comments, then the offsets
    and scales, then the thermal block when the model has one.  The notes are the format's own
    note, the zero reading's and the thermal block's.

    Parameters
    ----------
    cal : Calibration
    options : ExportOptions
    firmware : FirmwareFormat

    Returns
    -------
    ExportResult
    """
    model = diagonal_model(cal, options)
    loss = measure_loss(cal, model, options, firmware.name)
    lines = [line.format(source=options.source) for line in firmware.header] + [f"# {loss.describe()}"]
    if model.zero_reason:
        lines.append(f"# {model.zero_reason}")
    lines += [f"# not exported: {d}" for d in model.dropped]
    lines += per_axis(firmware.offset_line, model.offset_ms2) + per_axis(firmware.scale_line, model.scale)
    notes = [firmware.note]
    if model.zero_reason:
        notes.append(f"{model.zero_reason}; counts_zero=VALUE sets another zero reading")
    if model.thermal is not None:
        thermal_lines, thermal_notes = firmware.thermal_block(model.thermal)
        lines += thermal_lines
        notes += thermal_notes
    return ExportResult(firmware.name, "\n".join(lines) + "\n", loss, list(model.mapped), list(model.dropped), notes)


def per_axis(template: str, values: ArrayLike) -> list[str]:
    """One line per axis: ``template`` with ``{axis}`` (X, Y, Z) and ``{value}`` filled in."""
    return [template.format(axis=axis, value=float(v)) for axis, v in zip("XYZ", np.asarray(values, dtype=float))]
