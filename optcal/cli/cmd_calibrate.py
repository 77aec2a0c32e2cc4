"""``optcal calibrate DATA``: fit the lumped model to static poses."""

from __future__ import annotations

from typing import Any

import click

from optcal.families.accel.calibration import METHOD_CHOICES
from optcal.cli.data_options import DATA_PATH, data_line, data_options, data_summary, load_data, load_data_detailed
from optcal.cli.outputs import echo_json, output_file
from optcal.cli.report_option import command_line, report_options, write_report
from optcal.cli.solver_options import estimator_settings, pop_solver_options, solver_options
from optcal.cli.quiet import quiet_option
from optcal.cli.mag_options import mag_read_options


@click.command()
@click.argument("data", type=DATA_PATH)
@click.option("--method", type=click.Choice((*METHOD_CHOICES, "ferraris")), default="default", show_default=True,
              help="Estimator: convex+mle (default), svd, convex, mle, exact, gd, sixpos, nominal (known orientations, "
                   "tilts estimated), ferraris (six faces and three turns of a raw recording, both sensors).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text report.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Save the calibration as JSON.")
@click.option("--allow-degenerate", is_flag=True, help="Proceed (with a warning) when the poses do not identify every parameter.")
@click.option("--loss", type=click.Choice(["squared", "huber", "cauchy"]), default="squared", show_default=True,
              help="Loss of the mle fit; huber/cauchy down-weight corrupt poses.")
@click.option("--scale-range", nargs=2, type=click.FloatRange(min=0, min_open=True), default=None, metavar="LOW HIGH",
              help="Known range of the scale factors (raw units per g), a bound in the mle fit.")
@click.option("--imu", is_flag=True, help="Calibrate the gyroscope too, from the moves between the poses (Tedaldi 2014): cal_type imu.")
@click.option("--joint", is_flag=True, help="--imu: re-estimate the accelerometer jointly with the gyro.")
@click.option("--g-sensitivity", is_flag=True, help="--imu: model the gyro's g-sensitivity.")
@click.option("--accept-gyro-fit", is_flag=True,
              help="--imu: keep a gyro calibration that cannot be right (it leaves more than 20 % of the moves' turn "
                   "unexplained, or has the axes or scale of a column mapping, unit or time base), with a warning.")
@click.option("--sections", type=click.Path(exists=True, dir_okay=False), default=None,
              help="--method ferraris: imucal's section list (JSON or CSV of start/end rows per section).")
@click.option("--turn-angle", type=float, default=None, metavar="DEG",
              help="--method ferraris: the angle of each turn (default: the whole turns the gyro reads; 360 for counts).")
@click.option("--sensor", type=click.Choice(["acc", "mag"]), default="acc", show_default=True,
              help="The sensor to calibrate: the accelerometer (static poses) or the magnetometer (raw samples, mx, my, mz).")
@click.option("--mag-form", type=click.Choice(["auto", "offsets", "diagonal", "full", "planar", "planar-circle", "planar-ellipse"]),
              default="auto", show_default=True,
              help="--sensor mag: the model (hard iron only, with axis scales, or full soft iron; planar: a heading "
                   "calibration of a turn in one plane, circle or ellipse held out, or forced); auto by evidence.")
@click.option("--mag-units", default=None, metavar="UNIT",
              help="--sensor mag: units of the magnetometer (uT, nT, gauss, mgauss, counts); default from the file or the data.")
@mag_read_options
@click.option("--location", default=None, metavar="LAT,LON[,ALT]",
              help="--sensor mag: where the session was recorded (degrees, degrees, metres above the WGS-84 ellipsoid): "
                   "the field strength and dip are compared with the World Magnetic Model (extra 'mag', pygeomag).")
@click.option("--date", "session_date", default=None, metavar="YYYY-MM-DD",
              help="--sensor mag with --location: the session's date [today].")
@report_options
@solver_options
@data_options
@quiet_option
def calibrate(data: str, method: str, as_json: bool, output: str | None, allow_degenerate: bool,
              loss: str, scale_range: tuple[float, float] | None, imu: bool,
              joint: bool, g_sensitivity: bool, accept_gyro_fit: bool, sections: str | None, turn_angle: float | None,
              sensor: str, mag_form: str, mag_units: str | None, accept_mag_fit: bool, keep_mag_repeats: bool, keep_mag_spikes: bool,
              location: str | None,
              session_date: str | None,
              report_path: str | None, tolerance: float, **data_opts: Any) -> None:
    """Calibrate the accelerometer from DATA: a pose table (ax, ay, az per static pose) or a raw recording.

    With --imu, DATA is a raw recording with gyro columns and the gyroscope is calibrated too.
    """
    from optcal.families.accel.calibration import calibrate as run_calibration
    from optcal.errors import IdentifiabilityError, InputError

    solver_opts = pop_solver_options(data_opts)
    gyro_units: str | None = data_opts.get("gyro_units")
    from optcal.cli.cmd_mag import calibrate_mag_command, mag_options_used

    if sensor == "mag":
        if imu or scale_range or sections or turn_angle is not None:
            raise InputError("--imu, --scale-range, --sections and --turn-angle apply to the accelerometer, "
                             "not to --sensor mag")
        calibrate_mag_command(data, method, as_json, output, allow_degenerate, loss, mag_form, mag_units,
                              accept_mag_fit, keep_mag_repeats, keep_mag_spikes, solver_opts, data_opts, location, session_date, report_path)
        return
    if mag_options_used(mag_form, mag_units, accept_mag_fit, keep_mag_repeats, keep_mag_spikes) or location is not None or session_date is not None:
        raise InputError("--mag-form, --mag-units, --accept-mag-fit, --keep-mag-repeats, --keep-mag-spikes, --location and --date apply "
                         "with --sensor mag")
    if method == "ferraris" or sections or turn_angle is not None:
        if method != "ferraris" or imu or report_path or joint or g_sensitivity or accept_gyro_fit:
            raise InputError("--sections and --turn-angle apply with --method ferraris, which calibrates both sensors "
                             "itself (no --imu, --joint, --g-sensitivity, --accept-gyro-fit; --report not yet)")
        from optcal.cli.cmd_ferraris import calibrate_ferraris

        if any(v not in (None, (), {}) for v in solver_opts.values()):
            raise InputError("--method ferraris solves no optimisation problem (its means are Ferraris' closed form): "
                             "drop --solver, --solver-option, --conic-solver, --fix and --bound")
        calibrate_ferraris(data, sections, turn_angle, gyro_units, as_json, output, data_opts)
        return
    fit_settings = estimator_settings(method, **solver_opts)
    if not imu and (joint or g_sensitivity):
        raise InputError("--joint and --g-sensitivity apply with --imu only")
    if not imu and accept_gyro_fit:
        raise InputError("--accept-gyro-fit applies with --imu only")
    if imu:
        if report_path:
            raise InputError("--report covers the accelerometer calibration; it is not available with --imu yet")

        calibrate_imu(data, method, as_json, output, allow_degenerate, gyro_units, joint, g_sensitivity, data_opts,
                      accept_gyro_fit, fit_settings)
        return
    poses = load_data(data, **data_opts)
    settings: dict = {"allow_degenerate": allow_degenerate}
    if method in ("default", "mle"):
        settings["loss"] = loss
        settings["keep_physical"] = True  # the refinement only inside the accelerometer's physical set (families/accel/physical.py)
        if scale_range:
            settings["scale_range"] = tuple(scale_range)
    elif loss != "squared" or scale_range:
        raise InputError("--loss and --scale-range apply to the mle method only")
    settings.update(fit_settings)
    try:
        result = run_calibration(poses, method=method, **settings)
    except IdentifiabilityError as exc:
        if not as_json:  # what was read, so that the refusal can be judged against it
            click.echo(data_line(data, poses))
        if report_path:  # the report says what is missing and which poses would fix it; the error still ends the command
            from optcal.report.document import calibration_document

            forced = {**settings, "allow_degenerate": True}
            refused = run_calibration(poses, method=method, **forced)
            write_report(calibration_document(refused, poses, data, command_line(), method, forced, tolerance), report_path)
        raise _with_known_orientation_hint(exc, poses, method) from exc
    except InputError as exc:  # too few poses for a self-calibration
        raise _with_known_orientation_hint(exc, poses, method) from exc
    if output:
        result.save(output_file(output))
    if report_path:
        from optcal.report.document import calibration_document

        write_report(calibration_document(result, poses, data, command_line(), method, settings, tolerance), report_path)
    if as_json:
        summary = result.summary()
        summary["data"] = data_summary(data, poses)
        echo_json(summary)
        return
    from optcal.report.calibration_text import calibration_report

    click.echo(data_line(data, poses))
    click.echo(calibration_report(result))
    if output:
        click.echo(f"saved to {output}")


def calibrate_imu(
    data: str, method: str, as_json: bool, output: str | None, allow_degenerate: bool,
    gyro_units: str | None, joint: bool, g_sensitivity: bool, data_opts: dict[str, Any], accept_gyro_fit: bool = False,
    fit_settings: dict[str, Any] | None = None,
) -> None:
    """``optcal calibrate DATA --imu``: both sensors from one raw recording (cal_type imu).

    Parameters
    ----------
    data : str
        The raw recording, with gyro columns.
    method : str
        The accelerometer's estimator (``--method``).
    as_json : bool
        Print one JSON object instead of the text report.
    output : str, optional
        Where to save the calibration (``-o``).
    allow_degenerate : bool
        Proceed when the poses or the moves do not identify every parameter.
    gyro_units : str, optional
        Units of the gyro columns (``--gyro-units``; default: decided from the file and the data).
    joint : bool
        Re-estimate the accelerometer jointly with the gyro.
    g_sensitivity : bool
        Model the gyro's g-sensitivity.
    data_opts : dict
        The DATA reading options (:func:`optcal.cli.data_options.data_options`).
    accept_gyro_fit : bool
        Keep a gyro calibration the moves do not support, with a warning (``--accept-gyro-fit``).
    fit_settings : dict, optional
        The accelerometer estimator's settings from :func:`optcal.cli.solver_options.estimator_settings`;
        its ``solver`` and ``solver_options`` serve the gyroscope's problem too.
    """
    from optcal.cli.messages import cli_message
    from optcal.families.gyro.estimator import GyroSettings, calibrate_imu_loaded

    loaded = load_data_detailed(data, **data_opts)
    fit_settings = dict(fit_settings or {})
    settings = GyroSettings.from_flags(joint=joint, g_sensitivity=g_sensitivity, allow_degenerate=allow_degenerate,
                                       accept_gyro_fit=accept_gyro_fit, solver=fit_settings.get("solver"),
                                       solver_options=fit_settings.get("solver_options"))
    cal = calibrate_imu_loaded(loaded, gyro_units=gyro_units, method=method, settings=settings,
                               acc_settings={"allow_degenerate": allow_degenerate, **fit_settings})
    if cal.fit_warning:
        click.echo(f"warning: {cli_message(cal.fit_warning, 'calibrate')}", err=True)
    if output:
        cal.save(output_file(output))
    if as_json:
        out = cal.to_dict()
        out.pop("fitted_on", None)
        out["data"] = data_summary(data, loaded.poses)
        echo_json(out)
        return
    from optcal.report.imu_text import imu_report

    click.echo(data_line(data, loaded.poses))
    click.echo(imu_report(cal))
    if output:
        click.echo(f"saved to {output}")


def _with_known_orientation_hint(exc: Exception, poses: Any, method: str) -> Exception:
    """``exc`` with the known-orientation methods named when a self-calibration refuses the six faces of a cube."""
    from optcal.errors import IdentifiabilityError, InputError
    from optcal.families.accel.nominal import known_orientation_hint

    if method in ("sixpos", "nominal") or not isinstance(exc, InputError):
        return exc
    hint = known_orientation_hint(poses, raw_with_gyro=poses.source == "raw recording" and poses.gyro is not None)
    if hint is None:
        return exc
    if isinstance(exc, IdentifiabilityError):
        return IdentifiabilityError(f"{exc}. {hint}", exc.report)
    return InputError(f"{exc}. {hint}")
