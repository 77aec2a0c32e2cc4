"""The text report of a whole-IMU calibration (``optcal calibrate --imu`` without ``--json``).

The accelerometer's report (:func:`optcal.report.calibration_text.calibration_report`), then the
gyroscope's: units, the gravity-prediction residual before and after calibration (Tedaldi 2014,
eq. 13), scale and axis misalignment, the solver, the gyro parameters with their standard
errors, the identifiability verdict, exclusions and notes.
"""

from __future__ import annotations

from optcal.families.gyro.result import ImuCalibration
from optcal.report.calibration_text import calibration_report

__all__ = ["imu_report"]


def imu_report(cal: ImuCalibration) -> str:
    """Readable report: the accelerometer's, then the gyro's parameters and the gravity-prediction residual.

    Parameters
    ----------
    cal : ImuCalibration

    Returns
    -------
    str
    """
    se = cal.stderr
    phys = cal.gyro.physical()
    lines = [calibration_report(cal.accelerometer), f"[[Gyroscope: Tedaldi 2014, accelerometer {cal.accelerometer_mode}]]",
             f"    units              = {cal.gyro_units} in ({cal.gyro_units_reason}), rad/s out",
             f"    moves              = {cal.angles_after_deg.size}",
             f"    gravity prediction = {cal.rms_angle_before_deg:.3f}° rms before ({cal.before}), "
             f"{cal.rms_angle_after_deg:.3f}° after",
             f"    scale K_g          = {', '.join(f'{s:.6g}' for s in phys.scale)} {cal.gyro_units} per rad/s",
             f"    axis misalignment  = {', '.join(f'{m:.3f}' for m in phys.misalignment_deg)}° (x, y, z)",
             f"    solver             = {cal.solver.name}: {cal.solver.status}, {cal.solver.iterations} iterations, "
             f"{cal.solver.solve_time_s * 1e3:.1f} ms",
             "[[Gyro parameters]]"]
    for name, value in zip(cal.param_names, cal.params):
        lines.append(f"    {name:<8s} = {value: .8g} +/- {se.get(name, float('nan')):.3g}")
    if cal.identifiability is not None:
        lines.append(f"    identifiability: {cal.identifiability.describe()}")
    if cal.exclusions:
        lines.append("[[Excluded (gyro)]]")
        lines.extend(f"    {k}: {v}" for k, v in cal.exclusions.items())
    if cal.notes:
        lines.append("[[Notes (gyro)]]")
        lines.extend(f"    - {n}" for n in cal.notes)
    return "\n".join(lines)
