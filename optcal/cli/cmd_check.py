"""``optcal check CAL.json DATA``: evaluate a saved calibration (any ``cal_type``) on other data."""

from __future__ import annotations

from typing import Any

import click
import numpy as np

from optcal.cli.data_options import DATA_PATH, data_line, data_options, data_summary, load_data, load_data_detailed
from optcal.cli.outputs import echo_json
from optcal.cli.peer_options import load_calibration, peer_options
from optcal.cli.report_option import command_line, report_options, write_report
from optcal.cli.quiet import quiet_option
from optcal.cli.mag_options import mag_read_options, refuse_mag_options


@click.command()
@click.argument("calibration", type=click.Path(dir_okay=False), metavar="CAL.json")
@click.argument("data", type=DATA_PATH)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text report.")
@click.option("--method", type=click.Choice(["default", "mle", "convex", "svd", "exact", "gd"]), default="default",
              show_default=True,
              help="CAL from imucal or imu_tk: optcal's own calibration of DATA, shown next to it, by this method.")
@mag_read_options
@peer_options
@report_options
@data_options
@quiet_option
def check(calibration: str, data: str, as_json: bool, method: str, accept_mag_fit: bool, keep_mag_repeats: bool, keep_mag_spikes: bool,
          peer_gravity: float | None,
          gyro_calib: str | None, report_path: str | None, tolerance: float, **data_opts: Any) -> None:
    """Apply the calibration in CAL.json (any cal_type) to the static poses of DATA; report |a|−1 before and after.

    DATA is a pose table or a raw recording (its static intervals are found as by
    ``optcal segment``).  "Before" is the nominal conversion to g (exact unit factors for g
    and m/s²; for counts, mid-scale offset if unsigned and one sensitivity from the median norm).

    CAL may be another tool's calibration (imucal's JSON, imu_tk's .calib pair; recognised by
    content): its errors on DATA are then shown next to optcal's own calibration of DATA (fitted
    by --method, in sample and held out), with what the peer's bias, scales and axis angles miss.
    """
    from optcal.applications.quality.validation import check_calibration, convert_to_units

    cal = load_calibration(calibration, peer_gravity, gyro_calib)
    if cal.cal_type == "magnetometer":
        return _check_mag(cal, calibration, data, as_json, data_opts, accept_mag_fit, keep_mag_repeats, keep_mag_spikes)
    refuse_mag_options(accept_mag_fit, keep_mag_repeats, keep_mag_spikes,
                       "to a magnetometer calibration (CAL's cal_type is magnetometer)")
    fitted = cal.fitted_on.n if cal.fitted_on is not None else None
    # an imu (or a peer's gyro) calibration also needs DATA's segmentation (its moves): the file is read once, with it
    with_gyro = cal.cal_type == "imu" or bool(getattr(cal, "has_gyro", False))
    loaded = load_data_detailed(data, **data_opts) if with_gyro else None
    poses = loaded.poses if loaded is not None else load_data(data, **data_opts)
    result = check_calibration(cal, poses)
    comparison = None
    in_units = convert_to_units(poses, cal.units) if cal.cal_type == "peer" or report_path else None
    if cal.cal_type == "peer":  # another tool's calibration: next to optcal's own fit of DATA
        from optcal.applications.quality.peer import compare_with_peer

        assert in_units is not None
        comparison = compare_with_peer(cal, in_units, result.noise, method=method)
    if report_path:
        from optcal.report.document import check_document

        assert in_units is not None
        write_report(check_document(cal, calibration, in_units, result, data, command_line(), tolerance, comparison),
                     report_path)
    gyro_lines: list[str] = []
    gyro_out: dict[str, Any] = {}
    if loaded is not None:  # the gyro: gravity predicted across the moves, before and after
        gyro_lines, gyro_out = gravity_check_lines(cal, loaded)
    if as_json:
        out = {
            "calibration": {"path": calibration, "cal_type": cal.cal_type, "units": cal.units, "n_poses": fitted},
            "data": data_summary(data, poses),
            **result.summary(),
            **gyro_out,
        }
        if comparison is not None:
            out["calibration"]["peer"] = {"tool": cal.tool, "cal_type": cal.peer_type, "read_as": cal.read_as,
                                          "gravity_m_s2": cal.gravity_m_s2, "gravity_reason": cal.gravity_reason,
                                          "notes": cal.notes}
            out["peer_comparison"] = comparison.to_dict()
        echo_json(out)
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
    for note in getattr(cal, "notes", []) if comparison is not None else []:
        click.echo(f"note: {note}")
    if comparison is not None:
        for line in comparison.lines():
            click.echo(line)
    own = comparison.own_after if comparison is not None else None
    heldout = comparison.own_heldout if comparison is not None else None
    click.echo("")
    after_name = "after (mg)" if comparison is None else f"{cal.tool} (mg)"
    click.echo(f"{'pose':>5} {'t (s)':>9} {'n':>7} {'before (mg)':>12} {after_name:>11} {'noise (mg)':>11}"
               + (f" {'optcal (mg)':>11}" if own is not None else "") + (f" {'held out':>9}" if heldout is not None else ""))
    for k in range(result.rows.size):
        t = f"{result.t[k]:9.2f}" if result.t is not None else f"{'':>9}"
        n = f"{int(result.n_samples[k]):7d}" if result.n_samples is not None else f"{'':>7}"
        noise = f"{result.noise[k] * 1e3:11.4f}" if result.noise is not None else f"{'':>11}"
        extra = (f" {own[k] * 1e3:11.4f}" if own is not None else "") + (f" {heldout[k] * 1e3:9.4f}" if heldout is not None else "")
        click.echo(f"{int(result.rows[k]):>5} {t} {n} {result.before[k] * 1e3:12.4f} {result.after[k] * 1e3:11.4f} {noise}"
                   + extra)
    if poses.exclusions:
        click.echo("excluded: " + "; ".join(f"{k}: {v}" for k, v in poses.exclusions.items()))


def gravity_check_lines(cal: Any, loaded: Any) -> tuple[list[str], dict[str, Any]]:
    """``optcal check`` on an IMU calibration: the gravity-prediction residual of DATA's moves, before and after.

    Parameters
    ----------
    cal : ImuCalibration or PeerCalibration
        The saved calibration (cal_type imu, or a peer's with a gyroscope).
    loaded : optcal.data.LoadedData
        The recording checked, with its segmentation (a raw recording with gyro columns; a pose
        table gives one line saying so).

    Returns
    -------
    lines : list of str
        The text report's lines.
    out : dict
        The ``--json`` entries (``gravity_prediction``; empty without raw gyro samples).
    """
    from optcal.families.gyro.check import gravity_prediction_check

    if loaded.segmentation is None or loaded.segmentation.recording.gyro is None:
        return ["gyro: DATA has no raw gyro samples; the gravity-prediction check needs a raw recording with gx, gy, gz"], {}
    result = gravity_prediction_check(cal, loaded.segmentation)
    lines = [f"gyro: gravity predicted across {result.angles_after_deg.size} moves, rms angle to the next pose: "
             f"before {result.rms_before_deg:.3f}° ({result.before}), after {result.rms_after_deg:.3f}°"]
    verdict = result.verdict()  # "after" against DATA's noise model (flagged beyond its bound)
    if verdict is not None:
        lines.append(verdict)
    return lines, {"gravity_prediction": {"n_moves": int(result.angles_after_deg.size), **result.to_dict(),
                                          "rms_deg_before": result.rms_before_deg, "rms_deg_after": result.rms_after_deg,
                                          "before": result.before, "exclusions": result.exclusions,
                                          "angles_deg_before": np.round(result.angles_before_deg, 6).tolist(),
                                          "angles_deg_after": np.round(result.angles_after_deg, 6).tolist()}}


def _check_mag(cal: Any, calibration: str, data: str, as_json: bool, data_opts: dict[str, Any],
               accept_mag_fit: bool = False, keep_mag_repeats: bool = False, keep_mag_spikes: bool = False) -> None:
    """A magnetometer calibration on DATA's magnetometer samples: the norm residual ``|T(m − o)| − 1`` (rms, and the
    field's strength the data read through it against the calibration's)."""
    import numpy as np

    from optcal.cli.outputs import echo_json
    from optcal.families.mag.samples import read_mag

    samples = read_mag(data, columns=data_opts.get("columns"), topic=data_opts.get("topic"), mag_units=cal.units,
                       keep_rail=accept_mag_fit, keep_repeats=keep_mag_repeats, keep_spikes=keep_mag_spikes)
    norm = cal.norm(samples.m)  # a planar calibration's: the in-plane part's
    rms = float(np.sqrt(np.mean((norm - 1.0) ** 2)))
    out = {"sensor": "magnetometer", "calibration": {"path": calibration, "cal_type": cal.cal_type, "units": cal.units},
           "data": {"path": data, "n_samples": samples.n, "decisions": samples.decision_lines()},
           "rms_norm_residual": rms, "median_norm": float(np.median(norm)),
           "field_strength": cal.field_strength, "field_strength_in_data": float(np.median(norm)) * cal.field_strength}
    plane_line = None
    if cal.plane_normal is not None:  # a planar calibration holds in its plane only: is DATA turned in it?
        from optcal.families.mag.fit import PLANAR_SPREAD
        from optcal.families.mag.planar import plane_departure

        share, deg = plane_departure(samples.m, cal.plane_normal)
        inside = share < PLANAR_SPREAD  # the planar test's bound (a tilt of 8° rms): the calibration's own decision
        out["plane"] = {"normal": [float(v) for v in cal.plane_normal], "tilt_share": share, "tilt_deg": deg,
                        "in_plane": inside}
        n = ", ".join(f"{v:+.3f}" for v in cal.plane_normal)
        plane_line = (f"plane: DATA turns in the calibration's plane (normal [{n}]): its spread along the normal, less "
                      f"the noise, is {100 * share:.2g} % of the whole, a tilt of {deg:.2g}° (below "
                      f"{100 * PLANAR_SPREAD:g} %)" if inside else
                      f"plane: DATA is not turned in the calibration's plane (normal [{n}]): {100 * share:.2g} % of its "
                      f"spread lies along the normal, as in a plane at {deg:.2g}° to it (a turn in the plane: below "
                      f"{100 * PLANAR_SPREAD:g} %), so the in-plane norm holds part of the field's normal component and "
                      f"the residual below measures the plane, not the calibration; check it on a recording turned in "
                      f"that plane")
    if as_json:
        echo_json(out)
        return
    for line in samples.decision_lines():
        click.echo(line)
    if plane_line is not None:
        click.echo(plane_line)
    click.echo(f"{calibration} on {data}: {samples.n} magnetometer samples; rms of |T(m − o)| − 1 {rms:.4%} of the field; "
               f"the field read {out['field_strength_in_data']:.6g} {cal.units} (the calibration's "
               f"{cal.field_strength:.6g}: {out['median_norm'] - 1.0:+.2%})")
