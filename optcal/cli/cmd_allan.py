"""``optcal allan DATA``: Allan deviation and noise parameters of a static log (Yin 2014, section 2.2)."""

from __future__ import annotations

import json
from typing import Any

import click
import numpy as np

from optcal.cli.data_options import DATA_PATH

#: Largest step between samples, in median steps, before the log counts as having a gap.
MAX_STEP_RATIO: float = 1.5


def static_log(
    data: str,
    columns: str | None,
    units: str | None,
    topic: str | None,
    rate: float | None,
) -> tuple[np.ndarray, float, str, str, dict[str, int]]:
    """Read a raw static recording: samples (n, 3), rate, units, how the units were decided, exclusions.

    Unusable samples (non-finite, duplicated, saturated) are dropped and counted; a log with
    a gap in time is refused, because the Allan deviation needs uniform sampling.
    """
    from optcal.data import load_recording
    from optcal.errors import InputError

    rec = load_recording(data, columns=columns, units=units, topic=topic, rate=rate)
    t = rec.t[rec.usable]
    samples = rec.acc[rec.usable]
    steps = np.diff(t)
    if steps.size and np.max(steps) > MAX_STEP_RATIO * np.median(steps):
        at = int(np.argmax(steps))
        raise InputError(
            f"{data}: the log has a gap of {steps[at]:.4g} s at t = {t[at]:.6g} s (sampling step "
            f"{np.median(steps):.4g} s); the Allan deviation needs an uninterrupted, uniformly sampled static log"
        )
    return samples, rec.rate_hz, rec.units, rec.units_reason, dict(rec.exclusions)


@click.command()
@click.argument("data", type=DATA_PATH)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (SI units) instead of the table.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), default=None,
              help="Save the log-log Allan deviation with the fitted lines (PNG, PDF, SVG).")
@click.option("--rate", type=click.FloatRange(min=0, min_open=True), default=None, metavar="HZ",
              help="Sampling rate of a log without a time column (overrides an 'Fs' header line).")
@click.option("--units", type=click.Choice(["g", "m/s^2", "counts"]), default=None,
              help="Units of the accelerometer data (default: from the column names or file, else from the norm).")
@click.option("--counts-per-g", type=click.FloatRange(min=0, min_open=True), default=None, metavar="N",
              help="Scale of raw counts, needed for counts (16384 for an MPU-6050 at ±2 g).")
@click.option("--columns", metavar="NAME=COLUMN,...", default=None,
              help="Map the file's column names, e.g. ax=acc_x,ay=acc_y,az=acc_z,t=time.")
@click.option("--topic", default=None, help="ROS bag / ULog topic of the accelerometer.")
@click.option("--max-tau", type=click.FloatRange(min=0, min_open=True), default=None, metavar="S",
              help="Largest averaging time τ (default: the largest octave τ leaving 9 clusters).")
def allan(
    data: str,
    as_json: bool,
    plot_path: str | None,
    rate: float | None,
    units: str | None,
    counts_per_g: float | None,
    columns: str | None,
    topic: str | None,
    max_tau: float | None,
) -> None:
    """Allan deviation of a static log: velocity random walk, bias instability, rate random walk.

    DATA is a raw recording of a still sensor (CSV with ax, ay, az, a time column or a rate;
    Parquet, ROS bag or ULog).  Overlapping Allan deviation on octave-spaced τ with
    confidence intervals (allantools); the noise parameters are read from the fitted
    −1/2, 0 and +1/2 slope lines as in Yin 2014.
    """
    from optcal.yin2014.allan import analyse_static_log, plot_allan, si_per_unit
    from optcal.result import jsonable

    samples, rate_hz, units_used, units_reason, exclusions = static_log(data, columns, units, topic, rate)
    si_per_unit(units_used, counts_per_g)  # fail early on counts without a scale
    analysis = analyse_static_log(samples, rate_hz, units_used, counts_per_g, max_tau)
    if plot_path is not None:
        plot_allan(analysis, plot_path, title=f"Allan deviation of {data}")
    if as_json:
        out: dict[str, Any] = analysis.summary()
        out["log"].update({"path": data, "units_reason": units_reason, "exclusions": exclusions})
        click.echo(json.dumps(jsonable(out), allow_nan=False))
        if plot_path is not None:
            click.echo(f"figure saved to {plot_path}", err=True)
        return
    click.echo(f"DATA: {data}, units {units_used} ({units_reason})")
    if exclusions:
        click.echo("excluded: " + "; ".join(f"{k}: {v}" for k, v in exclusions.items()))
    click.echo(analysis.report())
    if plot_path is not None:
        click.echo(f"figure saved to {plot_path}")
