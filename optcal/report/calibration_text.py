"""The text report of an accelerometer calibration (``optcal calibrate`` without ``--json``).

lmfit's ``fit_report`` layout: the fit statistics, the solver, each parameter with its standard
error, then the engineering parameters (scale factors, non-orthogonality angles, biases;
:mod:`optcal.report.parameters`), ``A = TᵀT`` with its standard errors, the identifiability,
what was excluded before the fit and the notes.
"""

from __future__ import annotations

import numpy as np

from optcal.core.identifiability import IdentifiabilityReport
from optcal.data.units import nominal_conversion
from optcal.families.accel.result import CalibrationResult
from optcal.report.parameters import result_parameters

__all__ = ["calibration_report", "engineering_text"]


def engineering_text(result: CalibrationResult) -> str:
    """The block of scale factors, non-orthogonality angles and biases (:mod:`optcal.report.parameters`).

    Parameters
    ----------
    result : CalibrationResult

    Returns
    -------
    str
        Lines of text; the bias in mg is measured from the nominal zero reading of the input
        units (:func:`optcal.data.units.nominal_conversion`) when the fit's poses are known.
    """
    zero = nominal_conversion(result.units, result.fitted_on.acc).offset if result.fitted_on is not None else None
    params = result_parameters(result, zero)
    lines = ["[[Scale factors, non-orthogonality, bias]]"]
    for q in params.rows:
        lines.append(f"    {q.symbol:<5s} = {q.value:>13.7g} +/- {q.stderr:<8.2g} {q.unit:<9s} {q.name}")
    if np.any(params.zero):
        lines.append(f"    (bias in mg measured from the nominal zero reading {', '.join(f'{z:g}' for z in params.zero)} {result.units})")
    lines.append("    (mounting misalignment: not determined by static poses; the frame is the sensor's x axis and xy plane)")
    return "\n".join(lines)


def calibration_report(result: CalibrationResult) -> str:
    """Readable text report of a calibration.

    Parameters
    ----------
    result : CalibrationResult

    Returns
    -------
    str
        Parameters ± standard error, scale factors and angles, fit statistics, solver,
        identifiability, exclusions and notes.
    """
    se = result.stderr
    lines = [
        f"[[Calibration: method {result.method}]]",
        f"    poses              = {result.n_poses}",
        f"    parameters         = {result.n_params}",
        f"    units              = {result.units} in, g out",
        f"    rms |a|-1          = {result.rms_norm_residual_g * 1e3:.4f} mg",
        f"    max ||a|-1|        = {np.max(np.abs(result.residuals)) * 1e3:.4f} mg" if result.n_poses else "",
        f"    chi-square         = {result.chisqr:.6g}",
        f"    reduced chi-square = {result.redchi:.6g}" if result.dof > 0 else "    reduced chi-square = n/a (no degrees of freedom)",
        f"    Akaike info crit   = {result.aic:.4f}",
        f"    Bayesian info crit = {result.bic:.4f}",
        f"    covariance         = {'absolute (noise given)' if result.sigma_known else 'scaled by reduced chi-square'}",
        "[[Solver]]",
        f"    {result.solver.name}: {result.solver.status}, {result.solver.iterations} iterations, "
        f"{result.solver.solve_time_s * 1e3:.2f} ms" + (f" ({result.solver.message})" if result.solver.message else ""),
        "[[Parameters]]",
    ]
    for name, value in zip(result.param_names, result.params):
        e = se.get(name, float("nan"))
        rel = f"({abs(e / value) * 100:.2g} %)" if value != 0 and np.isfinite(e) else ""
        lines.append(f"    {name:<12s} = {value: .8g} +/- {e:.3g} {rel}")
    lines.append(engineering_text(result))
    lines.append(f"[[A = T'T, g² per {result.units}²]]")
    A_se = result.A_stderr
    for i in range(3):
        lines.append("    " + "  ".join(
            f"{result.A[i, j]: .6e}" + (f" +/- {A_se[i, j]:.2g}" if np.isfinite(A_se[i, j]) else "") for j in range(3)))
    idf = result.identifiability
    if idf is not None:
        lines.append("[[Identifiability]]")
        lines.append(f"    Fisher rank {idf.rank}/{idf.n_params}, condition number {idf.condition_number:.3g}")
        if isinstance(idf, IdentifiabilityReport):
            for item in idf.unidentified:
                lines.append(f"    not determined: {item['text']}")
            for item in idf.weak:
                lines.append(f"    weakly determined: {item['text']} (standard error {item['stderr'] * 100:.2g} % of full scale)")
    if result.exclusions:
        lines.append("[[Excluded before the fit]]")
        lines.extend(f"    {k}: {v}" for k, v in result.exclusions.items())
    if result.notes:
        lines.append("[[Notes]]")
        lines.extend(f"    - {n}" for n in result.notes)
    return "\n".join(line for line in lines if line != "")
