"""``optcal export CAL --format FORMAT``: a calibration in another tool's format (the formats: :data:`EXPORTERS`)."""

from __future__ import annotations

from pathlib import Path

import click

from optcal.applications.export import EXPORTERS
from optcal.applications.export.base import DEFAULT_GYRO_RATE_DEG_S
from optcal.cli.data_options import DATA_PATH
from optcal.cli.quiet import quiet_option


@click.command()
@click.argument("calibration", type=click.Path(dir_okay=False), metavar="CAL")
@click.option("--format", "fmt", required=True, type=click.Choice(list(EXPORTERS)),
              help="ardupilot (param file), px4 (QGroundControl parameter file), px4-shell (param set lines), "
                   "kalibr (imu.yaml), ros (Imu covariance), c (C99 header), imucal (imucal's calibration JSON); "
                   "IMU intrinsics: kalibr-imu (Kalibr scale-misalignment), openvins (kalibr_imu_chain.yaml), basalt "
                   "(calibration.json IMU keys), imutk (.calib pair); noise: vins, orbslam3, okvis.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Write the file here (default: standard output, with the report on standard error).")
@click.option("--counts-per-g", type=click.FloatRange(min=0, min_open=True), default=None,
              help="ardupilot/px4 with a calibration in counts: the driver's sensitivity (counts per g, from the datasheet).")
@click.option("--counts-zero", type=click.FloatRange(min=0), default=None, metavar="COUNTS",
              help="ardupilot/px4 with a calibration in counts: the reading the driver subtracts before scaling "
                   "(e.g. 32768 for unsigned 16-bit; default: 32768 when the poses are unsigned around mid-scale, else 0).")
@click.option("--max-loss", type=click.FloatRange(min=0), default=5.0, show_default=True, metavar="MG",
              help="ardupilot/px4: refuse when the per-axis model's rms |a|-1 exceeds the full model's by more (mg).")
@click.option("--poses", type=DATA_PATH, default=None,
              help="The data the calibration was fitted on, when CAL holds no fitted poses (for the loss figures); "
                   "ardupilot/px4 with an imu calibration: a raw recording's moves also measure the gyro's loss.")
@click.option("--poses-rate", type=click.FloatRange(min=0, min_open=True), default=None, metavar="HZ",
              help="The sample rate of the --poses recording when it has no time column.")
@click.option("--allan", type=click.Path(dir_okay=False), default=None,
              help="kalibr (required), ros (the sensor noise; without it the calibration residual): an `optcal allan --json` result.")
@click.option("--gyro-allan", type=click.Path(dir_okay=False), default=None,
              help="kalibr: an `optcal allan --sensor gyro --json` result (gyroscope_noise_density, gyroscope_random_walk).")
@click.option("--random-walk-bound", is_flag=True,
              help="kalibr: when the Allan log shows no rate random walk, write its upper bound (labelled) instead of refusing.")
@click.option("--rate", type=click.FloatRange(min=0, min_open=True), default=None, metavar="HZ",
              help="kalibr/ros: the IMU topic's rate (default: the Allan log's).")
@click.option("--rostopic", default="/imu0", show_default=True, help="kalibr: the IMU topic.")
@click.option("--device-id", type=click.IntRange(1, 2**32 - 1), default=None, metavar="N",
              help="ardupilot/px4: the accelerometer's device id (INS_ACC_ID, CAL_ACC0_ID, TC_A0_ID); without it the "
                   "firmware does not apply the calibration until the id is set.")
@click.option("--gyro-device-id", type=click.IntRange(1, 2**32 - 1), default=None, metavar="N",
              help="ardupilot/px4, imu calibrations: the gyroscope's device id (INS_GYR_ID, CAL_GYRO0_ID).")
@click.option("--instance", type=click.IntRange(0, 2), default=0, show_default=True, metavar="K",
              help="ardupilot/px4: the IMU (0, 1, 2) the parameters are for (INS_ACC2OFFS_*, CAL_ACC1_*, ...).")
@click.option("--counts-per-dps", type=click.FloatRange(min=0, min_open=True), default=None,
              help="ardupilot/px4, a gyroscope in counts: the driver's sensitivity (counts per deg/s, from the datasheet).")
@click.option("--gyro-rate", type=click.FloatRange(min=0, min_open=True), default=DEFAULT_GYRO_RATE_DEG_S, show_default=True,
              metavar="DEG_S", help="ardupilot/px4: the rate at which the gyro error the firmware cannot correct is stated.")
@click.option("--vehicle-id", type=click.IntRange(1, 255), default=1, show_default=True,
              help="px4: the vehicle's MAV_SYS_ID written in each line (QGroundControl refuses another).")
@click.option("--gyro-counts-per-rad-s", type=click.FloatRange(min=0, min_open=True), default=None, metavar="N",
              help="kalibr-imu/openvins/basalt with a gyroscope in counts: the driver's sensitivity (counts per rad/s).")
@click.option("--gyro-counts-zero", type=click.FloatRange(min=0), default=None, metavar="COUNTS",
              help="kalibr-imu/openvins/basalt: the raw gyro reading the driver subtracts (default: 32768 when the bias "
                   "lies around the unsigned 16-bit mid-scale, else 0).")
@click.option("--gravity", type=click.FloatRange(min=0, min_open=True), default=None, metavar="M_S2",
              help="m/s^2 per g of the calibration (its local gravity) for the intrinsics and noise formats "
                   "(default: standard gravity 9.80665).")
@click.option("--inflate", default="1,1", show_default=True, metavar="WHITE,WALK",
              help="vins/orbslam3/okvis/kalibr-imu/openvins/basalt: multiply the white-noise densities by WHITE and the "
                   "random walks by WALK (written into the file's comments).")
@click.option("--accept-planar", is_flag=True,
              help="ardupilot/px4/px4-shell: write a planar (heading) magnetometer calibration, its hard iron along the "
                   "plane's normal undetermined (taken as 0), instead of refusing it.")
@quiet_option
def export(calibration: str, fmt: str, output: str | None, counts_per_g: float | None, counts_zero: float | None,
           max_loss: float, poses: str | None, allan: str | None, gyro_allan: str | None, random_walk_bound: bool,
           rate: float | None, rostopic: str, device_id: int | None, gyro_device_id: int | None, instance: int,
           counts_per_dps: float | None, gyro_rate: float, vehicle_id: int, poses_rate: float | None,
           gyro_counts_per_rad_s: float | None, gyro_counts_zero: float | None, gravity: float | None,
           inflate: str, accept_planar: bool) -> None:
    """Write the calibration CAL (any cal_type) in the format another tool reads.

    ArduPilot and PX4 keep per-axis offsets and scales only (and a thermal offset polynomial):
    the loss of that model on the calibration's own poses is reported next to the full model's
    and the export is refused above --max-loss.  Their parameters are in m/s² of the driver's
    output, so a calibration in counts needs --counts-per-g (and --counts-zero when the driver
    subtracts a zero reading that optcal cannot see in the poses).  Of an imu calibration's
    gyroscope they keep the bias offsets (rad/s; --counts-per-dps for counts); its scale,
    misalignment and g-sensitivity are reported with the rate error they leave.
    """
    import optcal.families.calibration_files as calibration_files
    from optcal.cli.messages import cli_message
    from optcal.families.caltypes.apply import convert_samples
    from optcal.applications.export import export as run_export, read_allan
    from optcal.applications.export.base import ExportOptions

    cal = calibration_files.load(calibration)
    fit_poses = recording = None
    if poses is not None:
        from optcal.families.caltypes import FitPoses
        from optcal.cli.data_options import load_data_detailed

        loaded = load_data_detailed(poses, rate=poses_rate)
        table = loaded.poses
        fit_poses = FitPoses(convert_samples(table.acc, table.units, cal.units), table.temp, table.t)
        if cal.cal_type == "imu" and loaded.segmentation is not None and loaded.segmentation.recording.gyro is not None:
            recording = loaded.segmentation  # the gyro's loss across its moves
    options = ExportOptions(
        counts_per_g=counts_per_g,
        counts_zero=counts_zero,
        max_loss_g=max_loss * 1e-3,
        poses=fit_poses,
        allan=read_allan(allan) if allan else None,
        random_walk_bound=random_walk_bound,
        gyro_allan=read_allan(gyro_allan) if gyro_allan else None,
        rate_hz=rate,
        rostopic=rostopic,
        source=Path(calibration).name,
        device_id=device_id,
        gyro_device_id=gyro_device_id,
        instance=instance,
        counts_per_dps=counts_per_dps,
        gyro_rate_deg_s=gyro_rate,
        vehicle_id=vehicle_id,
        recording=recording,
        gyro_counts_per_rad_s=gyro_counts_per_rad_s,
        gyro_counts_zero=gyro_counts_zero,
        **({"gravity_m_s2": gravity} if gravity is not None else {}),
        inflate=parse_inflate(inflate),
        accept_planar=accept_planar,
    )
    result = run_export(cal, fmt, options)
    report = [f"calibration: {calibration}: {cal.describe()}"]
    if result.loss is not None:
        report.append(result.loss.describe())
    report += [f"exported: {m}" for m in result.mapped]
    report += [f"not exported: {d}" for d in result.dropped]
    report += [f"note: {cli_message(n, 'export')}" for n in result.notes]
    if output is None:
        if result.files:
            from optcal.errors import InputError

            raise InputError(f"the {fmt} format writes {1 + len(result.files)} files: give -o FILE (the others are "
                             f"written beside it, {', '.join(result.files)} added to its name)")
        click.echo(result.text, nl=False)
        for line in report:
            click.echo(line, err=True)
        return
    from optcal.cli.outputs import writing

    with writing(output) as tmp:  # whole or not at all
        tmp.write_text(result.text)
    for line in report:
        click.echo(line)
    click.echo(f"wrote {fmt} file {output}")
    for suffix, text in result.files.items():
        extra = Path(output).with_name(f"{Path(output).stem}{suffix}{Path(output).suffix}")
        with writing(extra) as tmp:
            tmp.write_text(text)
        click.echo(f"wrote {fmt} file {extra}")


def parse_inflate(text: str) -> tuple[float, float]:
    """``--inflate WHITE,WALK`` as two positive factors."""
    from optcal.errors import InputError

    try:
        white, walk = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--inflate {text!r}: give two factors WHITE,WALK (e.g. 10,10; 1,1 for none)") from None
    if not (white > 0 and walk > 0):
        raise InputError(f"--inflate {text!r}: the factors must be positive")
    return white, walk
