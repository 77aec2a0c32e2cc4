"""``optcal segment DATA``: show the static intervals found in a raw recording."""

from __future__ import annotations

from typing import Any

import click

from optcal.cli.data_options import DATA_PATH, data_line, data_options, data_summary, load_data_detailed
from optcal.cli.report_option import check_report_path, command_line, write_report
from optcal.cli.outputs import echo_json, plot_file, plot_option
from optcal.cli.quiet import quiet_option
from optcal.report.segmentation_figure import segmentation_figure
from optcal.core.stats import rms

#: File name of the figure when ``--plot`` names a folder.
FIGURE_NAME = "segments.png"


@click.command()
@click.argument("data", type=DATA_PATH)
@plot_option(f"a figure of |a|, the detector's statistics and the intervals ({FIGURE_NAME})")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the table.")
@click.option("--report", "report_path", type=click.Path(dir_okay=False), default=None, metavar="FILE.html",
              callback=check_report_path, help="Write a self-contained HTML report: whether the static poses can make a calibration, the trace, the table.")
@data_options
@quiet_option
def segment(data: str, plot_path: str | None, as_json: bool, report_path: str | None, **data_opts: Any) -> None:
    """Find the static intervals of a raw recording and the pose each one gives.

    DATA is a CSV/Parquet time series, a ROS 1/ROS 2 bag (sensor_msgs/Imu) or a PX4 ULog
    file (sensor_accel).  A pose table is recognised and reported as such.
    """
    figure = plot_file(plot_path, FIGURE_NAME) if plot_path is not None else None
    loaded = load_data_detailed(data, **data_opts)
    poses, seg = loaded.poses, loaded.segmentation
    if figure is not None:
        if seg is None:
            click.echo(f"no plot: {data} is a pose table, not a time series", err=True)
            figure = None
        else:
            from optcal.cli.outputs import writing

            with writing(figure, "--plot") as tmp:  # whole or not at all
                segmentation_figure(seg).savefig(tmp, dpi=120)
    if report_path is not None:
        from optcal.report.document import segmentation_document

        text = segmentation_report(poses.meta, seg) if seg is not None else f"nothing to segment: {poses.n} poses, one per row"
        write_report(segmentation_document(poses, seg, data, command_line(), text), report_path)
    if as_json:
        out: dict[str, Any] = {"data": data_summary(data, poses)}
        if seg is not None:
            out["segmentation"] = poses.meta["segmentation"]
        else:
            out["poses"] = {"acc": poses.acc, "rows": poses.rows}
        if figure is not None:
            out["plot"] = str(figure)
        echo_json(out)
        return
    click.echo(data_line(data, poses))
    if seg is None:
        click.echo(f"nothing to segment: {poses.n} poses, one per row")
        return
    click.echo(segmentation_report(poses.meta, seg))
    if figure is not None:
        click.echo(f"figure saved to {figure}")


def _independent(s: Any, has_gyro: bool) -> str:
    """The fewest independent samples a rest holds, as the detector applies them."""
    acc, gyro = s.independent_minimums()
    of_gyro = f" ({gyro:g} of the gyro)" if has_gyro and s.use_gyro and gyro != acc else ""
    return f"at least {acc:g} independent samples{of_gyro}"


def _noise_unit(key: str, rec: Any) -> str:
    """The unit of a measured noise figure: colours are ratios; per-sample noise in the accelerometer's unit,
    the gyro's wander in the gyro's."""
    if key.startswith(("rest_noise", "acc_rounding")):
        return f" {rec.units}"
    if key.startswith(("gyro_wander", "gyro_rounding", "gyro_bias_drift")):
        return f" {rec.gyro_units or 'gyro units'}"
    return ""


def segmentation_report(meta: dict[str, Any], seg: Any) -> str:
    """Text report: how time and units were read, thresholds, the interval table, exclusions."""
    rec = seg.recording
    s = seg.settings
    lines = [
        f"time: {meta.get('time')}; units: {rec.units} ({rec.units_reason})",
        f"detector: blocks of {s.window_s:g} s ({seg.trace['window_samples']} samples), tests at false-alarm "
        f"{s.false_alarm:g} (steps ×{s.threshold:g}, drift ×{s.drift_threshold:g}"
        + (f", gyro ×{s.gyro_threshold:g})" if rec.gyro is not None and s.use_gyro else "; no gyro evidence)")
        + f", minimum dwell {s.min_dwell_s:g} s, {_independent(s, rec.gyro is not None)}, trim {s.trim_s:g} s",
        *([f"gyro: {seg.gyro_unit}"] if seg.gyro_unit else []),
        *([f"rest bounds: {seg.rest_bounds}"] if seg.rest_bounds else []),
        "noise measured: " + "; ".join(f"{k} {v:.4g}{_noise_unit(k, rec)}" for k, v in seg.noise_floor.items()),
        "critical values: " + "; ".join(f"{k} {v:.4g}" for k, v in seg.thresholds.items()),
        "",
        f"{'#':>3} {'rows':>13} {'t start':>9} {'dur s':>6} {'n':>6} {'mean x':>11} {'mean y':>11} {'mean z':>11}"
        f" {'std':>8} {'σ mean':>9}" + (f" {'temp':>6}" if rec.temp is not None else ""),
    ]
    for iv in seg.intervals:
        lines.append(
            f"{iv.number:>3} {iv.first_row:>6}-{iv.last_row:<6} {iv.t_start:>9.2f} {iv.duration_s:>6.2f} {iv.n_samples:>6}"
            f" {iv.mean[0]:>11.5g} {iv.mean[1]:>11.5g} {iv.mean[2]:>11.5g} {rms(iv.std):>8.3g}"
            f" {iv.sigma:>9.3g}" + (f" {iv.temp_mean:>6.2f}" if iv.temp_mean is not None else "")
        )
    lines.append("")
    lines.append(f"{len(seg.intervals)} static intervals, {seg.n_used} of {rec.n} samples in poses"
                 + (f" ({seg.joined} interrupted stretch(es) joined to the pose before)" if seg.joined else ""))
    for note in meta.get("notes", []):
        lines.append(f"note: {note}")
    if seg.exclusions:
        lines.append("excluded: " + "; ".join(f"{k}: {v}" for k, v in seg.exclusions.items()))
    return "\n".join(lines)
