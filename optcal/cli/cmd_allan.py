"""``optcal allan DATA``: Allan deviation and noise parameters of a static log (Yin 2014, section 2.2)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import click
import numpy as np

from optcal.cli.data_options import DATA_PATH, read_options, reading_kwargs
from optcal.cli.outputs import echo_json, plot_file, plot_option

#: File name of the figure when ``--plot`` names a folder.
FIGURE_NAME = "allan.png"

#: Missing samples tolerated in a log (a few dropped samples barely change the Allan deviation),
#: as a fraction of its samples; the log is treated as uniformly sampled and the count reported.
MAX_MISSING_FRACTION: float = 1e-3
#: Longest tolerated run of missing samples.
MAX_MISSING_RUN: int = 5
#: Share of a still log's samples that static detection must find at rest.
MIN_STILL_FRACTION: float = 0.9
DROPPED = "samples missing from the log (gaps of a few samples, treated as uniformly sampled)"


@dataclass
class StillLog:
    """A still log read for the Allan deviation.

    Attributes
    ----------
    samples : ndarray, shape (n, 3)
    rate_hz : float
    units, units_reason : str
    exclusions : dict of str to int
    decisions : DataDecisions
    """

    samples: np.ndarray
    rate_hz: float
    units: str
    units_reason: str
    exclusions: dict[str, int]
    decisions: Any


def static_log(
    data: str,
    columns: str | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
) -> tuple[np.ndarray, float, str, str, dict[str, int]]:
    """Samples, rate, units, how the units were decided and exclusions of a still log (:func:`read_still_log`)."""
    log = read_still_log(data, columns=columns, units=units, topic=topic, rate=rate)
    return log.samples, log.rate_hz, log.units, log.units_reason, log.exclusions


def read_still_log(data: str, sensor: str = "acc", **read_options: Any) -> StillLog:
    """Read a still log for the Allan deviation.

    Unusable samples (non-finite, duplicated, saturated) are dropped and counted; a few
    dropped samples (at most :data:`MAX_MISSING_FRACTION` of the log, runs of at most
    :data:`MAX_MISSING_RUN`) are counted and the log treated as uniformly sampled; a longer
    gap is refused, because the Allan deviation needs uniform sampling.  A log that static
    detection does not find at rest (at least :data:`MIN_STILL_FRACTION` of it) is refused:
    the Allan deviation of a moving sensor measures the motion.  ``sensor="gyro"`` takes the
    gyro samples (``units`` then says the gyro units as the file states them, or ``None``).
    """
    from optcal.cli.data_options import decisions_on_error
    from optcal.data import load_recording
    from optcal.data.static import detect_static
    from optcal.errors import InputError

    with decisions_on_error(data):  # the decisions made before a refusal are printed with it
        rec = load_recording(data, required_by="the allan command", **read_options)
    t = rec.t[rec.usable]
    samples = rec.acc[rec.usable]
    if sensor == "gyro":
        if rec.gyro is None:
            raise InputError(f"{data}: no gyro columns (gx, gy, gz); map them with --columns gx=...,gy=...,gz=...")
        samples = rec.gyro[rec.usable]
    exclusions = dict(rec.exclusions)
    steps = np.diff(t)
    if steps.size:
        step = float(np.median(steps))
        missing = np.round(steps / step).astype(int) - 1 if step > 0 else np.zeros(steps.size, int)
        total = int(np.clip(missing, 0, None).sum())
        if total and (missing.max() > MAX_MISSING_RUN or total > MAX_MISSING_FRACTION * t.size):
            at = int(np.argmax(steps))
            raise InputError(
                f"{data}: the log has a gap of {steps[at]:.4g} s at t = {t[at]:.6g} s ({total} samples missing in all; "
                f"sampling step {step:.4g} s); the Allan deviation needs an uninterrupted, uniformly sampled still log: "
                "cut the log at the gap"
            )
        if total:
            exclusions[DROPPED] = total
    seg = detect_static(rec)
    still = seg.n_used / max(1, samples.shape[0])
    if still < MIN_STILL_FRACTION:
        raise InputError(
            f"{data}: the log is not still: static detection finds only {100 * still:.0f} % of its samples at rest "
            f"({len(seg.intervals)} static interval(s)); the Allan deviation needs a log of a sensor that does not move"
        )
    if sensor == "gyro":
        return StillLog(samples, rec.rate_hz, rec.gyro_units or "", "stated by the file" if rec.gyro_units else "",
                        exclusions, rec.decisions)
    return StillLog(samples, rec.rate_hz, rec.units, rec.units_reason, exclusions, rec.decisions)


@click.command()
@click.argument("data", type=DATA_PATH)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (SI units) instead of the table.")
@plot_option(f"the log-log Allan deviation with the fitted lines ({FIGURE_NAME})")
@click.option("--counts-per-g", type=click.FloatRange(min=0, min_open=True), default=None, metavar="N",
              help="Scale of raw counts, needed for counts (16384 for an MPU-6050 at ±2 g).")
@click.option("--sensor", type=click.Choice(["acc", "gyro"]), default="acc", show_default=True,
              help="Channels analysed: the accelerometer, or the gyro (angle random walk, bias instability, rate random walk).")
@click.option("--gyro-units", type=click.Choice(["counts", "rad/s", "deg/s"]), default=None,
              help="--sensor gyro: units of the gyro columns (default: from the column names or file, else from the data).")
@click.option("--counts-per-rad-s", type=click.FloatRange(min=0, min_open=True), default=None, metavar="N",
              help="--sensor gyro: scale of raw gyro counts (e.g. K_g of an IMU calibration).")
@read_options
@click.option("--max-tau", type=click.FloatRange(min=0, min_open=True), default=None, metavar="S",
              help="Largest averaging time τ (default: the largest octave τ leaving 9 clusters).")
def allan(
    data: str,
    as_json: bool,
    plot_path: str | None,
    counts_per_g: float | None,
    sensor: str,
    gyro_units: str | None,
    counts_per_rad_s: float | None,
    max_tau: float | None,
    **reading: Any,
) -> None:
    """Allan deviation of a static log: velocity random walk, bias instability, rate random walk.

    DATA is a raw recording of a still sensor (CSV with ax, ay, az, a time column or a rate;
    Parquet, ROS bag or ULog).  Overlapping Allan deviation on octave-spaced τ with
    confidence intervals (allantools); the noise parameters are read from the fitted
    −1/2, 0 and +1/2 slope lines as in Yin 2014.
    """
    from optcal.families.noise.analysis import analyse_static_log, plot_allan
    from optcal.families.noise.sensors import ACCELEROMETER

    figure = plot_file(plot_path, FIGURE_NAME) if plot_path is not None else None
    if sensor == "gyro":
        allan_gyro(data, as_json, gyro_units, counts_per_rad_s, max_tau, reading_kwargs(reading))
        return
    log = read_still_log(data, **reading_kwargs(reading))
    samples, rate_hz, units_used, units_reason, exclusions, decisions = (
        log.samples, log.rate_hz, log.units, log.units_reason, log.exclusions, log.decisions)
    ACCELEROMETER.si_per_unit(units_used, counts_per_g)  # fail early on counts without a scale
    analysis = analyse_static_log(samples, rate_hz, units_used, counts_per_g, max_tau)
    if figure is not None:
        plot_allan(analysis, figure, title=f"Allan deviation of {data}")
    if as_json:
        out: dict[str, Any] = analysis.summary()
        out["log"].update({"path": data, "units_reason": units_reason, "exclusions": exclusions,
                           "decisions": decisions.to_dict()})
        echo_json(out)
        if figure is not None:
            click.echo(f"figure saved to {figure}", err=True)
        return
    click.echo(f"DATA: {data}, a still log of {samples.shape[0]} samples at {rate_hz:.6g} Hz, units {units_used}")
    for line in decisions.lines():
        click.echo("  " + line)
    if exclusions:
        click.echo("excluded: " + "; ".join(f"{k}: {v}" for k, v in exclusions.items()))
    click.echo(analysis.report())
    if figure is not None:
        click.echo(f"figure saved to {figure}")


def allan_gyro(data: str, as_json: bool, gyro_units: str | None, counts_per_rad_s: float | None,
               max_tau: float | None, reading: dict[str, Any]) -> None:
    """``optcal allan DATA --sensor gyro``: the gyro's noise parameters (and Kalibr's two numbers).

    Parameters
    ----------
    data : str
        The still log, with gyro columns.
    as_json : bool
        Print one JSON object instead of the table.
    gyro_units : str, optional
        Units of the gyro columns (``--gyro-units``; default: decided from the file and the data).
    counts_per_rad_s : float, optional
        Scale of raw gyro counts.
    max_tau : float, optional
        Largest averaging time τ, s.
    reading : dict
        Keywords of :func:`optcal.data.load_recording` (:func:`optcal.cli.data_options.reading_kwargs`).
    """
    from optcal.families.noise.analysis import analyse_static_log
    from optcal.families.noise.sensors import GYROSCOPE
    from optcal.data.units import decide_gyro_units

    log = read_still_log(data, sensor="gyro", **reading)
    decision = decide_gyro_units(log.samples, log.samples.mean(axis=0), gyro_units, log.units or None)
    analysis = analyse_static_log(log.samples, log.rate_hz, decision.units, counts_per_rad_s, max_tau, GYROSCOPE)
    if as_json:
        out = analysis.summary()
        out["log"].update({"path": data, "units_reason": decision.reason, "exclusions": log.exclusions})
        echo_json(out)
        return
    click.echo(f"DATA: {data}, a still log of {log.samples.shape[0]} samples at {log.rate_hz:.6g} Hz, "
               f"gyro units {decision.units} ({decision.reason})")
    if log.exclusions:
        click.echo("excluded: " + "; ".join(f"{k}: {v}" for k, v in log.exclusions.items()))
    click.echo(analysis.report())
