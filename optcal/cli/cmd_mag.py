"""``optcal calibrate DATA --sensor mag``: the magnetometer's calibration from its raw samples.

Called from :mod:`optcal.cli.cmd_calibrate`; the work is :mod:`optcal.families.mag`.  What was
read and decided (columns, units, the form) is printed before the result or the refusal (on
standard error with ``--json``, which prints one JSON object).
"""

from __future__ import annotations

from typing import Any

import click
import numpy as np


def mag_options_used(mag_form: str, mag_units: str | None, accept_mag_fit: bool, keep_mag_repeats: bool = False, keep_mag_spikes: bool = False) -> bool:
    """Whether a magnetometer option was given (refused without ``--sensor mag``)."""
    return mag_form != "auto" or mag_units is not None or accept_mag_fit or keep_mag_repeats or keep_mag_spikes


def calibrate_mag_command(data: str, method: str, as_json: bool, output: str | None, allow_degenerate: bool,
                          loss: str, mag_form: str, mag_units: str | None, accept_mag_fit: bool,
                          keep_mag_repeats: bool, keep_mag_spikes: bool,
                          solver_opts: dict[str, Any], data_opts: dict[str, Any], location: str | None = None,
                          session_date: str | None = None, report_path: str | None = None) -> None:
    """Read, fit and report (module docstring).

    Parameters
    ----------
    data : str
        The recording.
    method : str
        ``--method``: default (convex then ML), convex, mle, exact, gd or svd.
    as_json, output, allow_degenerate, loss
        As for the accelerometer.
    mag_form : str
        ``--mag-form``: auto, offsets, diagonal, full, planar, planar-circle or planar-ellipse.
    mag_units : str, optional
        ``--mag-units``.
    accept_mag_fit : bool
        Keep samples that do not lie on an ellipsoid (and those at the converter's rail).
    keep_mag_repeats : bool
        Keep every row where the logger repeats each magnetometer value until its next update.
    solver_opts, data_opts : dict
        The solver options and the DATA options (``--columns``, ``--topic``; the rest detection's do not apply).
    location, session_date : str, optional
        ``--location LAT,LON[,ALT]`` and ``--date YYYY-MM-DD``: the field and dip against the World Magnetic Model
        (:mod:`optcal.families.mag.wmm`).
    report_path : str, optional
        ``--report``: the HTML report (:mod:`optcal.report.mag_document`: the sphere's coverage before and after).
    """
    from optcal.cli.outputs import echo_json, output_file
    from optcal.cli.solver_options import estimator_settings
    from optcal.errors import InputError
    from optcal.families.mag.calibration import calibrate_mag
    from optcal.families.mag.fit import MagSettings, refuse_orientation_method
    from optcal.families.mag.samples import read_mag

    refuse_orientation_method(method)
    settings = estimator_settings(method, **solver_opts) if method != "default" or any(solver_opts.values()) else {}
    if loss != "squared":
        if method not in ("default", "mle"):
            raise InputError("--loss applies to the mle method only")
        settings["loss"] = loss
    from optcal.families.mag.wmm import Location, compare_with_wmm, parse_date, wmm_lines, wmm_reference

    if session_date is not None and location is None:
        raise InputError("--date applies with --location (the World Magnetic Model's place)")
    place = Location.parse(location) if location is not None else None
    reference = None
    if place is not None:  # before the fit: a missing extra or a bad date is said at once
        day, day_reason = parse_date(session_date)
        reference = wmm_reference(place, day)
    # a sample at the converter's rail lies off the ellipsoid as surely as one the fit rejects: the same flag keeps it
    samples = read_mag(data, columns=data_opts.get("columns"), topic=data_opts.get("topic"), mag_units=mag_units,
                       keep_rail=accept_mag_fit, keep_repeats=keep_mag_repeats, keep_spikes=keep_mag_spikes)
    if reference is not None:  # a unit decided from the data is checked against the field expected there
        from dataclasses import replace

        from optcal.families.mag.units import units_at_place

        samples = replace(samples, units=units_at_place(samples.units, samples.m, reference.total_nT / 1000.0))
    say = (lambda line: click.echo(line, err=True)) if as_json else click.echo
    say(f"data: {data}: {samples.n} magnetometer samples" + (", with an accelerometer" if samples.acc is not None else ""))
    for line in samples.decision_lines():
        say(line)
    result = calibrate_mag(samples, MagSettings(method=method, form=mag_form, allow_degenerate=allow_degenerate,
                                                accept_fit=accept_mag_fit, estimator=settings,
                                                gyro_units=data_opts.get("gyro_units")))
    if report_path:
        from optcal.cli.report_option import command_line, write_report
        from optcal.report.mag_document import mag_document

        write_report(mag_document(result, data, command_line()), report_path)
    if result.samples.units != samples.units:  # a planar fit's field in the plane decided the unit
        say(result.samples.units.line().replace("magnetometer units:", "magnetometer units, after the planar fit:", 1))
    cal = result.calibration
    comparison = None
    if reference is not None and cal.plane_normal is not None:
        from optcal.families.mag.calibration import state_vertical_field

        state_vertical_field(result, reference.inclination_deg)
        say("--location: the World Magnetic Model's field is not compared with a planar calibration's (its field in "
            "the plane depends on the plane's unknown tilt to the horizontal); its dip "
            f"{reference.inclination_deg:.2f}° gives the vertical field's share of the heading error")
    elif reference is not None:
        say(f"date: {day_reason}")
        comparison = compare_with_wmm(reference, cal.field_strength, cal.units, cal.info.get("dip_deg"),
                                      cal.info.get("dip_se_deg"))
        cal.info["wmm"] = comparison
    if output:
        cal.save(output_file(output))
    if as_json:
        echo_json(result.summary())
        return
    from optcal.report.mag_text import mag_report

    click.echo(mag_report(result))
    if comparison is not None:
        for line in wmm_lines(comparison):
            click.echo(line)
    if output:
        click.echo(f"saved to {output}")


def apply_mag(cal: Any, calibration: str, data: str, output: str, columns: str | None, topic: str | None,
              accept_mag_fit: bool = False, keep_mag_repeats: bool = False, keep_mag_spikes: bool = False) -> None:
    """``optcal apply mag.json DATA -o OUT``: the magnetometer's samples calibrated, in the calibration's units.

    Writes ``mx, my, mz`` (the field ``field_strength · T (m − o)``) and ``norm`` (``|T(m − o)|``, 1 in
    the calibration's field) for every finite row of DATA; rows with a non-finite value are counted, and so are
    those at the converter's rail (``--accept-mag-fit`` keeps them).  A planar calibration corrects the in-plane
    components and passes the normal one through (its ``norm`` the in-plane part's).
    """
    from optcal.cli.outputs import output_file
    from optcal.errors import InputError
    from optcal.families.mag.samples import read_mag

    samples = read_mag(data, columns=columns, topic=topic, keep_rail=accept_mag_fit, keep_repeats=keep_mag_repeats, keep_spikes=keep_mag_spikes)
    if cal.plane_normal is not None:  # a planar recording's unit from its field in the plane, as calibrate decides it
        from dataclasses import replace

        from optcal.families.mag.units import units_from_plane_field

        in_plane = float(np.median(cal.norm(samples.m))) * cal.field_strength  # data units, whatever their name
        samples = replace(samples, units=units_from_plane_field(samples.units, in_plane))
    if samples.units.units != cal.units:
        raise InputError(f"DATA's magnetometer is read as {samples.units.units} ({samples.units.reason}), the calibration "
                         f"is in {cal.units}: apply it to samples in {cal.units}")
    field = cal.field(samples.m)
    table = np.column_stack([field, cal.norm(samples.m)])
    path = output_file(output)
    np.savetxt(path, table, delimiter=",", header="mx,my,mz,norm", comments="", fmt="%.9g")
    click.echo(f"calibration: {calibration}: {cal.describe()}")
    for line in samples.decision_lines():
        click.echo(line)
    if cal.plane_normal is not None:
        click.echo(f"planar calibration: mx, my, mz hold the field in the plane calibrated plus the raw component along the "
                   f"normal [{', '.join(f'{v:+.3f}' for v in cal.plane_normal)}] unchanged (its hard iron undetermined); "
                   f"norm = the in-plane part's |T(m - o)|")
    click.echo(f"wrote {samples.n} rows to {output} (csv), the field in {cal.units}; norm = |T(m - o)|")
