"""The content of an HTML report, built from optcal's public result objects.

A :class:`ReportDocument` is the verdict, then sections of paragraphs, tables and figures,
then the data decisions, the exact command and the versions.  One builder per command:
:func:`calibration_document`, :func:`diagnosis_document`, :func:`check_document`,
:func:`segmentation_document`.  Rendering is :mod:`optcal.report.render`.
"""

from __future__ import annotations

import datetime as _dt
import platform
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

import numpy as np

from optcal.core.poses import PoseTable
from optcal.applications.quality.evidence import Evidence, gather, pose_name
from optcal.report.figures import (
    EmbeddedFigure,
    before_after_figure,
    embed,
    residual_figure,
    sphere_map_figure,
)
from optcal.report.parameters import EngineeringParameters, Quantity, engineering_parameters, result_parameters
from optcal.report.segmentation_figure import segmentation_figure
from optcal.applications.quality.verdict import DEFAULT_TOLERANCE_MG, Verdict, judge, judge_check, judge_segmentation
from optcal.families.accel.result import CalibrationResult
from optcal.report.calibration_text import calibration_report
from optcal.report.diagnosis_text import diagnosis_report

#: Packages whose versions every report states.
VERSIONED_PACKAGES: tuple[str, ...] = ("optcal", "numpy", "scipy", "casadi", "cvxpy", "clarabel", "pandas", "matplotlib", "jinja2")


@dataclass(frozen=True)
class Table:
    """A table of strings: ``header`` and ``rows`` of the same width; ``caption`` says what it is."""

    header: list[str]
    rows: list[list[str]]
    caption: str = ""


@dataclass(frozen=True)
class Section:
    """One titled part of a report."""

    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    figures: list[EmbeddedFigure] = field(default_factory=list)
    preformatted: str = ""


@dataclass(frozen=True)
class ReportDocument:
    """Everything an HTML report shows.

    Attributes
    ----------
    title : str
    subject : str
        What was judged (the data file, the calibration).
    verdict : Verdict
    sections : list of Section
    command : str
        The exact command line that produced it.
    versions : list of (str, str)
    created : str
        UTC time stamp.
    """

    title: str
    subject: str
    verdict: Verdict
    sections: list[Section]
    command: str
    versions: list[tuple[str, str]]
    created: str


# ----------------------------------------------------------------------------- shared pieces
def versions() -> list[tuple[str, str]]:
    """Python and the versions of the packages that shaped the numbers."""
    out = [("python", platform.python_version())]
    for name in VERSIONED_PACKAGES:
        try:
            out.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            out.append((name, "not installed"))
    return out


def now_utc() -> str:
    """The time stamp of a report (UTC, to the minute)."""
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def significant(x: float, digits: int = 4) -> str:
    """A number with the significant digits it needs (``n/a`` when not finite)."""
    return f"{x:.{digits}g}" if np.isfinite(x) else "n/a"


def data_section(data_path: str, poses: PoseTable) -> Section:
    """The data decisions: kind, columns, units, rate, what was excluded (each counted), and the flag that overrides each."""
    meta = poses.meta
    if poses.decisions is not None:  # the data layer's typed decisions, each with its reason and its flag
        rows = [["file", data_path]]
        rows += [line.split(": ", 1) if ": " in line else ["", line] for line in poses.decisions.lines()]
        rows.append(["static poses", str(poses.n)])
        rows.append(["temperature", "recorded" if poses.temp is not None else "not recorded"])
        rows += [[f"excluded: {k}", str(v)] for k, v in poses.exclusions.items()] or [["excluded", "nothing"]]
        return Section("Data decisions", [str(n) for n in meta.get("notes", [])], [Table(["decision", "value"], rows)])
    rows = [
        ["file", data_path],
        ["read as", poses.source + (f" ({meta['kind_reason']})" if meta.get("kind_reason") else "")],
        ["units", poses.units + (f" ({meta['units_reason']})" if meta.get("units_reason") else "")],
    ]
    if poses.source == "raw recording":
        seg = meta.get("segmentation", {})
        rows += [
            ["samples", f"{seg.get('n_samples', 'n/a')}"],
            ["rate", f"{significant(float(meta.get('rate_hz', float('nan'))))} Hz" + (f" ({meta['time']})" if meta.get("time") else "")],
            ["duration", f"{significant(float(meta.get('duration_s', float('nan'))))} s"],
        ]
    rows.append(["static poses", str(poses.n)])
    rows.append(["temperature", "recorded" if poses.temp is not None else "not recorded"])
    if poses.exclusions:
        rows += [[f"excluded: {k}", str(v)] for k, v in poses.exclusions.items()]
    else:
        rows.append(["excluded", "nothing"])
    notes = [str(n) for n in meta.get("notes", [])]
    return Section("Data decisions", notes, [Table(["decision", "value"], rows)])


def _quantity_rows(quantities: list[Quantity], digits: int = 6) -> list[list[str]]:
    rows = []
    for q in quantities:
        lo, hi = q.ci95
        ci = f"{significant(lo, digits)} .. {significant(hi, digits)}" if np.isfinite(q.stderr) else "n/a"
        rows.append([q.name, q.symbol, significant(q.value, digits), significant(q.stderr, 2), ci, q.unit])
    return rows


def parameters_section(params: EngineeringParameters, T: np.ndarray, errors_from: str) -> Section:
    """The calibration as scale factors, angles and biases with 95 % confidence intervals.

    ``T`` is the calibration matrix printed below the tables; ``errors_from`` says where the
    standard errors come from.
    """
    header = ["parameter", "symbol", "value", "standard error", "95 % interval", "unit"]
    zero = params.zero
    zero_text = "0" if not np.any(zero) else ", ".join(significant(z, 6) for z in zero) + f" {params.units}"
    paragraphs = [
        "Scale factors are the sensor's output per g; the angles are the non-orthogonality of the sensing axes "
        "(Lu 2017, eq. 1: ρ tilts y towards x, φ and λ tilt z towards x and y). The mounting misalignment is not "
        "determined by static poses (any rotation of the sensor frame fits equally well), so the calibrated frame "
        "is defined by the sensor's own x axis and xy plane.",
        f"Bias in mg is measured from the raw reading that nominally means zero ({zero_text}).",
        f"Standard errors: {errors_from}; intervals are ±1.96 standard errors.",
    ]
    tables = [Table(header, _quantity_rows(params.scale + params.scale_error), "Scale factors"),
              Table(header, _quantity_rows(params.angles, 4), "Non-orthogonality"),
              Table(header, _quantity_rows(params.bias_raw + params.bias_mg), "Bias")]
    matrix = "\n".join("  ".join(f"{T[i, j]: .6e}" for j in range(3)) for i in range(3))
    return Section("Calibration parameters", paragraphs, tables,
                   preformatted=f"ā = T (a − o), T (g per {params.units}):\n{matrix}")


def result_parameters_section(result: CalibrationResult, poses: PoseTable) -> Section:
    """:func:`parameters_section` of a fit, bias in mg from the nominal zero of ``poses``."""
    errors_from = ("absolute, from the per-pose noise" if result.sigma_known
                   else "scaled by the reduced χ² (no per-pose noise given)")
    return parameters_section(result_parameters(result, _zero_of(poses)), result.T, errors_from)


def _pose_table(result: CalibrationResult, poses: PoseTable, noise: np.ndarray | None, residuals: np.ndarray) -> Table:
    header = ["pose", "t (s)", "samples", "residual (mg)", "noise σ (mg)"]
    rows = []
    for k in range(poses.n):
        rows.append([
            pose_name(poses, k),
            significant(float(poses.t[k]), 5) if poses.t is not None else "",
            str(int(poses.n_samples[k])) if poses.n_samples is not None else "",
            f"{residuals[k] * 1e3:+.4f}",
            f"{noise[k] * 1e3:.4f}" if noise is not None else "",
        ])
    return Table(header, rows, "Norm residual ‖T(a − o)‖ − 1 of each pose")


def _evidence_sections(ev: Evidence, poses: PoseTable) -> list[Section]:
    from optcal.applications.quality.evidence import noise_floor
    from optcal.applications.quality.simulation_band import band_text

    result = ev.result
    labels = [pose_name(poses, k).split(" (")[0].replace("pose ", "") for k in range(poses.n)]
    noise = noise_floor(result, poses)
    flagged_names = set(ev.outliers.poses)
    flagged = [k for k in range(poses.n) if pose_name(poses, k) in flagged_names]
    suggestions = ev.determination.suggestion_directions if ev.determination.suggestions else None
    fit = Section(
        "Fit",
        [
            f"{result.n_poses} poses, {result.n_params} parameters, method {result.method}; rms of |a| − 1 g "
            f"{result.rms_norm_residual_g * 1e3:.3g} mg in sample"
            + (f", {ev.held_out.rms_g * 1e3:.3g} mg held out ({ev.held_out.source})" if ev.held_out.available else "")
            + (f"; noise floor {ev.noise_floor_g * 1e3:.3g} mg" if np.isfinite(ev.noise_floor_g) else "") + ".",
            f"χ² {significant(result.chisqr)} with {result.dof} degrees of freedom"
            + (f" (reduced χ² {significant(result.redchi)})" if result.dof > 0 else "")
            + f"; solver {result.solver.name}: {result.solver.status}, {result.solver.iterations} iterations.",
            *[band_text(check)[0].upper() + band_text(check)[1:] + "." for check in ev.simulated],
            *([f"χ² against simulations of the fitted model: not computed ({ev.simulation_note})."]
              if ev.simulation_note else []),
        ],
        [_pose_table(result, poses, noise, result.residuals)],
        [embed(residual_figure(result.residuals, labels, noise, flagged),
               "Norm residual of each pose after calibration, with ±2σ of its noise")],
    )
    coverage = Section(
        "Orientation coverage",
        [f"{ev.coverage.distinct} distinct orientations (directions more than 15° apart); the largest region "
         f"without a pose has a radius of {ev.coverage.largest_gap_deg:.0f}°."
         + (" The pose planner's next poses (stars): " + "; ".join(ev.determination.suggestions) + "."
            if suggestions is not None else "")],
        figures=[embed(sphere_map_figure(ev.coverage.directions, suggestions),
                       "Sphere map of the poses: direction of gravity in sensor axes")],
    )
    return [fit, coverage]


def _zero_of(poses: PoseTable) -> np.ndarray:
    from optcal.data.units import nominal_conversion

    return nominal_conversion(poses.units, poses.acc).offset


# ----------------------------------------------------------------------------- builders
def calibration_document(
    result: CalibrationResult,
    poses: PoseTable,
    data_path: str,
    command: str,
    method: str | None = None,
    settings: dict[str, Any] | None = None,
    tolerance_mg: float = DEFAULT_TOLERANCE_MG,
) -> ReportDocument:
    """Report of ``optcal calibrate``: verdict, parameters, fit, coverage, data, command.

    Parameters
    ----------
    result : CalibrationResult
    poses : PoseTable
        The poses it was fitted to.
    data_path, command : str
        The data file and the exact command line, as printed in the report.
    method, settings : optional
        Estimator and its settings, for the held-out refits.
    tolerance_mg : float
        Accuracy asked of the calibrated norm (see :mod:`optcal.applications.quality.verdict`).
    """
    ev = gather(result, poses, method, settings)
    verdict = judge(ev, tolerance_mg)
    sections = [result_parameters_section(result, poses), *_evidence_sections(ev, poses), data_section(data_path, poses),
                Section("Text report", preformatted=calibration_report(result))]
    return ReportDocument(f"Calibration of {data_path}", data_path, verdict, sections, command, versions(), now_utc())


def diagnosis_document(diag: Any, poses: PoseTable, data_path: str, command: str,
                       tolerance_mg: float = DEFAULT_TOLERANCE_MG, gyro: Any = None) -> ReportDocument:
    """Report of ``optcal diagnose``: the verdict on the paper's model, the findings and their size, the figures."""
    from optcal.families.accel.calibration import calibrate

    result = calibrate(poses, method="mle", allow_degenerate=True)
    ev = gather(result, poses, diagnosis=diag)
    verdict = judge(ev, tolerance_mg)
    findings_rows = [[e.effect, e.axis or "", e.coefficient, significant(e.size_mg, 3) if np.isfinite(e.size_mg) else "", e.over]
                     for e in ev.effects]
    from optcal.report.diagnosis_figures import residual_figure as diagnosis_residual_figure
    from optcal.report.diagnosis_figures import simulation_figure

    figures = [embed(diagnosis_residual_figure(diag),
                     "Norm residuals against temperature, time and each axis: the paper's model and the final model")]
    sim_fig = simulation_figure(diag)
    if sim_fig is not None:
        figures.append(embed(sim_fig, "Simulation check of the paper's model: each residual statistic against its simulated band"))
    gain = diag.gain()
    diagnosis = Section(
        "Diagnosis",
        [f"Final model: {diag.final.describe()}; held-out rms {diag.baseline_heldout_rms() * 1e3:.3g} mg with the paper's "
         f"model, {diag.final_heldout_rms() * 1e3:.3g} mg with the final model (gain {gain:.3g}×)."]
        + [f"Not tested: {k} ({v})." for k, v in diag.skipped.items()],
        [Table(["effect", "axis", "coefficient", "size over the range (mg)", "range"], findings_rows, "Findings")]
        if findings_rows else [],
        figures,
    )
    peer = [peer_section(diag.peer)] if getattr(diag, "peer", None) is not None else []
    if gyro is not None:  # optcal diagnose --imu: the gyroscope's moves against their band, its findings
        from optcal.report.diagnosis_figures import gyro_figure

        rows = [[f.effect, ",".join(f.axes) or "-", ", ".join(f"{k} {float(v):.3g}" for k, v in f.estimate.items())]
                for f in gyro.findings]
        peer.append(Section(
            "Gyroscope",
            [gyro.report_lines()[1], f"Held-out gravity prediction {gyro.heldout_baseline_deg:.3f}° with the paper's "
             f"model, {gyro.heldout_final_deg:.3f}° with the final model (gain {gyro.gain:.3g}×)."]
            + ([gyro.accelerometer_frame.line().strip()] if getattr(gyro.accelerometer_frame, "relevant", False) else []),
            [Table(["effect", "axes", "estimate (SI)"], rows, "Gyroscope findings")] if rows else [],
            [embed(gyro_figure(gyro), "Each move's gravity prediction against its noise band, before and after")],
            "\n".join(gyro.report_lines())))
    sections = [diagnosis, *peer, result_parameters_section(result, poses), *_evidence_sections(ev, poses),
                data_section(data_path, poses),
                Section("Text report", preformatted=diagnosis_report(diag))]
    return ReportDocument(f"Diagnosis of {data_path}", data_path, verdict, sections, command, versions(), now_utc())


def peer_section(comparison: Any) -> Section:
    """A peer's calibration next to optcal's own (:class:`optcal.applications.quality.peer.PeerComparison`)."""
    c = comparison
    lines = c.lines()

    def mg(r: Any, k: int) -> str:
        return "" if r is None else f"{r[k] * 1e3:+.4f}"

    table = Table(["pose", f"{c.peer} (mg)", "optcal in sample (mg)", "optcal held out (mg)", "noise σ (mg)"],
                  [[f"pose {int(c.rows[k])}", mg(c.peer_after, k), mg(c.own_after, k), mg(c.own_heldout, k),
                    "" if c.noise is None else f"{c.noise[k] * 1e3:.4f}"] for k in range(c.rows.size)],
                  f"|a| − 1 of each pose under {c.peer}'s calibration ({c.source}) and optcal's own")
    return Section(f"{c.peer} next to optcal", [lines[0]] + [line for line in lines[1:] if not line.startswith("  ")],
                   [table], [], "\n".join(lines))


def check_document(cal: Any, cal_path: str, poses: PoseTable, check: Any, data_path: str, command: str,
                   tolerance_mg: float = DEFAULT_TOLERANCE_MG, comparison: Any = None) -> ReportDocument:
    """Report of ``optcal check``: a saved calibration (any :mod:`optcal.families.caltypes` type) on other data, before and after.

    ``poses`` are in the calibration's units; ``check`` is :func:`optcal.applications.quality.validation.check_calibration`'s result;
    ``comparison`` (a peer's calibration) sets optcal's own calibration of the data next to it.
    """
    verdict = judge_check(check.rms_after, check.rms_noise, check.rows.size, tolerance_mg)
    labels = [str(int(r)) for r in check.rows]
    table = Table(
        ["pose", "before (mg)", "after (mg)", "noise σ (mg)"],
        [[f"pose {int(check.rows[k])}", f"{check.before[k] * 1e3:+.4g}", f"{check.after[k] * 1e3:+.4f}",
          f"{check.noise[k] * 1e3:.4f}" if check.noise is not None else ""] for k in range(check.rows.size)],
    )
    section = Section(
        "Before and after",
        [f"Calibration {cal_path}: {cal.describe()}.",
         f"Before: {check.nominal.description}.",
         f"rms of |a| − 1 g over {check.rows.size} poses: before {check.rms_before * 1e3:.4g} mg, after "
         f"{check.rms_after * 1e3:.4g} mg" + (f" (pose noise alone: {check.rms_noise * 1e3:.4g} mg)." if np.isfinite(check.rms_noise) else ".")],
        [table],
        [embed(before_after_figure(labels, check.before, check.after, check.noise),
               "Norm error of each pose before (nominal conversion) and after calibration")],
    )
    lumped = cal.lumped()
    params = parameters_section(engineering_parameters(lumped.model, cal.units, None, _zero_of(poses)),
                                lumped.model.T_canonical, "not stored in the calibration file (see the report of its fit)")
    peer = [peer_section(comparison)] if comparison is not None else []
    return ReportDocument(f"Check of {cal_path} on {data_path}", f"{cal_path} on {data_path}", verdict,
                          [section, *peer, params, data_section(data_path, poses)], command, versions(), now_utc())


def segmentation_document(poses: PoseTable, segmentation: Any, data_path: str, command: str, text: str) -> ReportDocument:
    """Report of ``optcal segment``: whether the static poses found can make a calibration, the trace, the table."""
    from optcal.data.units import nominal_conversion

    directions = nominal_conversion(poses.units, poses.acc).apply(poses.acc)
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    from optcal.applications.quality.evidence import distinct_orientations

    distinct = distinct_orientations(directions)
    verdict = judge_segmentation(poses.n, distinct)
    figures = []
    if segmentation is not None:
        figures.append(embed(segmentation_figure(segmentation), "The recording: |a|, the detector's statistics and the static intervals",
                             fmt="png"))
    figures.append(embed(sphere_map_figure(directions), "Sphere map of the static poses (nominal conversion)"))
    sections = [Section("Static intervals", [], [], figures, text), data_section(data_path, poses)]
    return ReportDocument(f"Static intervals of {data_path}", data_path, verdict, sections, command, versions(), now_utc())
