"""``optcal calibrate DATA``: fit the lumped model to static poses."""

from __future__ import annotations

import json

import click

from optcal.calibration import METHOD_CHOICES


def echo_json(obj: dict) -> None:
    """Print exactly one JSON object on standard output."""
    from optcal.result import jsonable

    click.echo(json.dumps(jsonable(obj), allow_nan=False))


@click.command()
@click.argument("data", type=click.Path(dir_okay=False))
@click.option("--method", type=click.Choice(METHOD_CHOICES), default="default", show_default=True,
              help="Estimator: convex+mle (default), svd, convex, mle, exact, gd, sixpos.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text report.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Save the calibration as JSON.")
@click.option("--allow-degenerate", is_flag=True, help="Proceed (with a warning) when the poses do not identify every parameter.")
@click.option("--loss", type=click.Choice(["squared", "huber", "cauchy"]), default="squared", show_default=True,
              help="Loss of the mle fit; huber/cauchy down-weight corrupt poses.")
@click.option("--scale-range", nargs=2, type=float, default=None, metavar="LOW HIGH",
              help="Known range of the scale factors (raw units per g), a bound in the mle fit.")
@click.option("--units", type=click.Choice(["g", "m/s^2", "counts"]), default=None, help="Units of the data (guessed when omitted).")
def calibrate(data: str, method: str, as_json: bool, output: str | None, allow_degenerate: bool,
              loss: str, scale_range: tuple[float, float] | None, units: str | None) -> None:
    """Calibrate the accelerometer from the static poses in DATA (CSV with ax, ay, az)."""
    from optcal.calibration import calibrate as run_calibration
    from optcal.data import load
    from optcal.errors import InputError

    poses = load(data, units=units)
    settings: dict = {"allow_degenerate": allow_degenerate}
    if method in ("default", "mle"):
        settings["loss"] = loss
        if scale_range:
            settings["scale_range"] = tuple(scale_range)
    elif loss != "squared" or scale_range:
        raise InputError("--loss and --scale-range apply to the mle method only")
    result = run_calibration(poses, method=method, **settings)
    if output:
        result.save(output)
    if as_json:
        summary = result.summary()
        summary["data"] = {"path": data, "kind": poses.source, "units": poses.units}
        echo_json(summary)
        return
    click.echo(f"DATA: {data} read as a {poses.source} ({poses.n} poses, units {poses.units})")
    click.echo(result.report())
    if output:
        click.echo(f"saved to {output}")
