"""``optcal check CAL.json DATA``: evaluate a saved calibration (any ``cal_type``) on other data."""

from __future__ import annotations

import json
from typing import Any

import click
import numpy as np

from optcal.cli.data_options import DATA_PATH, data_line, data_options, data_summary, load_data
from optcal.cli.report_option import command_line, report_options, write_report


@click.command()
@click.argument("calibration", type=click.Path(dir_okay=False), metavar="CAL.json")
@click.argument("data", type=DATA_PATH)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text report.")
@report_options
@data_options
def check(calibration: str, data: str, as_json: bool, report_path: str | None, tolerance: float,
          **data_opts: Any) -> None:
    """Apply the calibration in CAL.json (any cal_type) to the static poses of DATA; report |a|−1 before and after.

    DATA is a pose table or a raw recording (its static intervals are found as by
    ``optcal segment``).  "Before" is the nominal conversion to g (exact unit factors for g
    and m/s²; for counts, mid-scale offset if unsigned and one sensitivity from the median norm).
    """
    import optcal.families.caltypes as caltypes
    from optcal.applications.quality.validation import check_calibration
    from optcal.core.fit_result import jsonable

    cal = caltypes.load(calibration)
    fitted = cal.fitted_on.n if cal.fitted_on is not None else None
    poses = load_data(data, **data_opts)
    result = check_calibration(cal, poses)
    if report_path:
        from optcal.applications.quality.validation import convert_to_units
        from optcal.report.document import check_document

        write_report(check_document(cal, calibration, convert_to_units(poses, cal.units), result, data, command_line(),
                                    tolerance), report_path)
    gyro_lines, gyro_out = [], {}
    if cal.cal_type == "imu":  # the gyro: gravity predicted across the moves, before and after
        from optcal.cli.gyro_commands import gravity_check_lines

        gyro_lines, gyro_out = gravity_check_lines(cal, data, data_opts)
    if as_json:
        out = {
            "calibration": {"path": calibration, "cal_type": cal.cal_type, "units": cal.units, "n_poses": fitted},
            "data": data_summary(data, poses),
            **result.summary(),
            **gyro_out,
        }
        click.echo(json.dumps(jsonable(out), allow_nan=False))
        return
    click.echo(f"calibration: {calibration}: {cal.describe()}")
    click.echo(data_line(data, poses))
    if poses.units != cal.units:
        click.echo(f"DATA converted from {poses.units} to {cal.units}")
    click.echo(f"before: {result.nominal.description}")
    click.echo(
        f"rms |a|-1 over {result.rows.size} poses: before {result.rms_before * 1e3:.4f} mg, "
        f"after {result.rms_after * 1e3:.4f} mg"
        + (f" (pose noise alone: {result.rms_noise * 1e3:.4f} mg)" if np.isfinite(result.rms_noise) else "")
    )
    for line in gyro_lines:
        click.echo(line)
    click.echo(
        f"max ||a|-1|: before {np.max(np.abs(result.before)) * 1e3:.4f} mg, after {np.max(np.abs(result.after)) * 1e3:.4f} mg"
    )
    click.echo("")
    has_t = result.t is not None
    click.echo(f"{'pose':>5} {'t (s)':>9} {'n':>7} {'before (mg)':>12} {'after (mg)':>11} {'noise (mg)':>11}")
    for k in range(result.rows.size):
        t = f"{result.t[k]:9.2f}" if has_t else f"{'':>9}"
        n = f"{int(result.n_samples[k]):7d}" if result.n_samples is not None else f"{'':>7}"
        noise = f"{result.noise[k] * 1e3:11.4f}" if result.noise is not None else f"{'':>11}"
        click.echo(f"{int(result.rows[k]):>5} {t} {n} {result.before[k] * 1e3:12.4f} {result.after[k] * 1e3:11.4f} {noise}")
    if poses.exclusions:
        click.echo("excluded: " + "; ".join(f"{k}: {v}" for k, v in poses.exclusions.items()))
