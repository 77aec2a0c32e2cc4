"""``optcal calibrate DATA --method ferraris``: Ferraris' six faces and three turns on a raw recording.

Kept apart from :mod:`optcal.cli.cmd_calibrate`, which only dispatches here.  The sections are
imucal's section list (``--sections``), else a ``part`` column of DATA, else found in the
recording (:mod:`optcal.families.ferraris.regions`); the report says which stretch was taken for what.
"""

from __future__ import annotations

from typing import Any

import click

from optcal.cli.data_options import data_line, data_summary, load_data_detailed
from optcal.cli.outputs import echo_json, output_file
from optcal.errors import InputError


def calibrate_ferraris(data: str, sections: str | None, turn_angle: float | None, gyro_units: str | None,
                       as_json: bool, output: str | None, data_opts: dict[str, Any]) -> None:
    """Run Ferraris' calibration on DATA and print (or save) it.

    Parameters
    ----------
    data : str
        The raw recording, with gyro columns.
    sections : str, optional
        imucal's section list (JSON or CSV).
    turn_angle : float, optional
        The angle of each turn, degrees (default: the whole turns nearest the reading; one for counts).
    gyro_units : str, optional
        Units of the gyro columns.
    as_json : bool
    output : str, optional
        Where to save the calibration (cal_type ``imu``).
    data_opts : dict
        The DATA reading options.
    """
    from optcal.families.ferraris import ferraris_fit, regions_for
    from optcal.report.ferraris_text import ferraris_report, ferraris_summary

    loaded = load_data_detailed(data, **data_opts)
    seg = loaded.segmentation
    if seg is None:
        raise InputError(f"DATA was read as a pose table ({loaded.kind.reason}); the Ferraris method needs the raw "
                         "recording (its turns calibrate the gyroscope); pass --format raw if it is one")
    rec = seg.recording
    fit = ferraris_fit(seg, regions_for(seg, sections), turn_angle_deg=turn_angle, gyro_units=gyro_units)
    if output:
        fit.calibration(rec).save(output_file(output))
    if as_json:
        out = ferraris_summary(fit, rec)
        out["data"] = data_summary(data, loaded.poses)
        echo_json(out)
        return
    click.echo(data_line(data, loaded.poses))
    click.echo(ferraris_report(fit, rec))
    if output:
        click.echo(f"saved to {output} (cal_type imu: accelerometer W, V and gyroscope T_g, b_g, G_g)")
