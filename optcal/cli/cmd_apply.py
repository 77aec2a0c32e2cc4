"""``optcal apply CAL DATA -o OUT``: write DATA corrected by a saved calibration of any type."""

from __future__ import annotations

import click

from optcal.cli.data_options import DATA_PATH
from optcal.cli.peer_options import load_calibration, peer_options
from optcal.cli.quiet import quiet_option
from optcal.cli.mag_options import mag_read_options, refuse_mag_options


@click.command()
@click.argument("calibration", type=click.Path(dir_okay=False), metavar="CAL")
@click.argument("data", type=DATA_PATH)
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output file: .csv or .parquet (the format follows the extension).")
@click.option("--units", "units_out", type=click.Choice(["g", "m/s^2"]), default="g", show_default=True,
              help="Units of the calibrated accelerations (columns ax_g.. or ax_m_s2..).")
@click.option("--data-units", type=click.Choice(["g", "m/s^2", "counts"]), default=None,
              help="Units of DATA's accelerations (default: from the column names or file format, else from the norm).")
@click.option("--columns", default=None, metavar="NAME=COLUMN,...",
              help="Map DATA's column names: e.g. ax=acc_x,ay=acc_y,az=acc_z,t=time_s,temp=imu_temp.")
@click.option("--topic", default=None, help="ROS bag: the sensor_msgs/Imu topic; ULog: sensor_accel[:INSTANCE].")
@click.option("--rate", type=click.FloatRange(min=0, min_open=True), default=None, metavar="HZ",
              help="Sampling rate of a recording without a time column (time = row / rate).")
@click.option("--format", "data_format", type=click.Choice(["auto", "poses", "raw"]), default="auto", show_default=True,
              help="Read DATA as a pose table or a raw recording; auto decides and says why.")
@click.option("--gyro-file", type=click.Path(dir_okay=False), default=None, metavar="PATH",
              help="The gyroscope's samples in a second text file (t gx gy gz: imu_tk's layout), interpolated onto "
                   "DATA's times; an imu calibration writes them calibrated after DATA's columns.")
@mag_read_options
@peer_options
@quiet_option
def apply(calibration: str, data: str, output: str, units_out: str, data_units: str | None, columns: str | None,
          topic: str | None, rate: float | None, data_format: str, gyro_file: str | None, accept_mag_fit: bool,
          keep_mag_repeats: bool, keep_mag_spikes: bool, peer_gravity: float | None, gyro_calib: str | None) -> None:
    """Correct every row of DATA with the calibration CAL (any cal_type) and write it to OUT.

    Time and every other column pass through unchanged; the accelerations are replaced by the
    calibrated ones and a column optcal_status marks each row: ok, out_of_range (outside the
    validity range of an extended calibration), excluded (duplicated, repeated timestamp or
    saturated sample of a recording) or non_finite.  No row is dropped.

    CAL may be imucal's calibration JSON or imu_tk's .calib pair (recognised by content): the
    rows are then corrected exactly as that tool corrects them (m/s² at its own g with --units
    m/s^2; the gyro in rad/s).
    """
    from optcal.families.caltypes.apply import apply_to_file, write_table

    from optcal.cli.data_options import build_read_options, decisions_on_error

    options = build_read_options({"columns": columns, "units": data_units, "topic": topic, "rate": rate,
                                  "data_format": data_format, "gyro_file": gyro_file})
    cal = load_calibration(calibration, peer_gravity, gyro_calib)
    if cal.cal_type == "magnetometer":  # its samples are mx, my, mz, read by the magnetometer's reader
        from optcal.cli.cmd_mag import apply_mag

        return apply_mag(cal, calibration, data, output, columns, topic, accept_mag_fit, keep_mag_repeats, keep_mag_spikes)
    refuse_mag_options(accept_mag_fit, keep_mag_repeats, keep_mag_spikes,
                       "to a magnetometer calibration (CAL's cal_type is magnetometer)")
    with decisions_on_error(data):  # the decisions made before a refusal are printed with it
        applied = apply_to_file(cal, data, options, units_out=units_out)
    from optcal.cli.outputs import output_file

    fmt = write_table(applied, output_file(output))
    click.echo(f"calibration: {calibration}: {cal.describe()}")
    click.echo(f"DATA: {data} read as a {applied.kind} [{applied.kind_reason}], units {applied.units_in} "
               f"[{applied.units_reason}]")
    if applied.time_reason and "t" in cal.needs:
        click.echo(f"time: {applied.time_reason}")
    if applied.units_in != cal.units:
        click.echo(f"DATA converted from {applied.units_in} to {cal.units}")
    click.echo(f"wrote {applied.n_rows} rows to {output} ({fmt}), accelerations in {units_out}"
               + (f" (1 g = {applied.gravity_m_s2:g} m/s^2, the calibration's own)"
                  if units_out == "m/s^2" and cal.cal_type == "peer" else ""))
    click.echo("rows: " + ", ".join(f"{word} {n}" for word, n in applied.status_counts.items()))
    if applied.exclusions:
        click.echo("excluded (marked, not dropped): " + "; ".join(f"{k}: {v}" for k, v in applied.exclusions.items()))
    if applied.read_exclusions:
        click.echo("counted while reading (rows the log's reader left out are not in the output; an unhealthy gyro's "
                   "row is, its gyro columns empty): "
                   + "; ".join(f"{k}: {v}" for k, v in applied.read_exclusions.items()))
    for note in applied.range_notes:
        click.echo(f"warning: {note}")
