"""``optcal diagnose DATA``: what the calibrated model gets wrong, the cause, the extended model, the gain."""

from __future__ import annotations

from typing import Any

import click

from optcal.families.accel.calibration import METHOD_CHOICES
from optcal.cli.data_options import DATA_PATH, data_options
from optcal.cli.peer_options import load_calibration, peer_options
from optcal.cli.report_option import command_line, report_options, write_report
from optcal.cli.solver_options import estimator_settings, pop_solver_options, solver_options
from optcal.cli.mag_options import mag_read_options, refuse_mag_options
from optcal.applications.diagnosis.effects import VOCABULARY

EFFECTS_HELP = (
    "Candidate effects, comma-separated, from: " + ", ".join(VOCABULARY)
    + " (default: every effect the data's columns support, session_bias with several DATA; none: the baseline "
    "and its simulation check only)."
)


def diagnosis_options(func: Any) -> Any:
    """The options shared by ``diagnose`` and ``demo``."""
    for option in reversed((
        click.option("--effects", default=None, metavar="LIST", help=EFFECTS_HELP),
        click.option("--folds", type=click.IntRange(min=2), default=10, show_default=True,
                     help="k of the k-fold held-out error (over poses)."),
        # at most 1e5: the Monte-Carlo p-value's resolution 1/(N+1) is then 2000x finer than the default alpha; more
        # only runs longer (a command never runs unbounded on a flag's value)
        click.option("--simulations", type=click.IntRange(0, 100_000), default=200, show_default=True,
                     help="Simulations of the fitted model in the simulation check (parametric bootstrap); with "
                          "--imu also of the gyro's model along the recorded moves (its band)."),
        click.option("--alpha", type=click.FloatRange(0, 1, min_open=True, max_open=True), default=0.02, show_default=True,
                     help="Family-wise false-finding level of each selection step."),
        click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True, help="Seed of the simulations."),
        click.option("--method", type=click.Choice(METHOD_CHOICES), default="mle", show_default=True,
                     help="Calibration method of the baseline (the start of the maximum-likelihood refit)."),
        click.option("--plot", "plot_dir", type=click.Path(), default=None, metavar="PATH",
                     help="Write the figures (residuals against temperature, time and each axis, before and after; "
                          "the simulation check) into the folder PATH (created when missing)."),
        click.option("--quiet", is_flag=True,
                     help="No progress on stderr (bars in a terminal, stage messages otherwise)."),
    )):
        func = option(func)
    return func


def settings_from(effects: str | None, folds: int, simulations: int, alpha: float, seed: int, method: str,
                  pose_correlation: str = "auto", calibration: dict[str, Any] | None = None,
                  drop_unneeded: bool = True, term_pairs: bool = True, pose_noise: str = "given",
                  heldout_se: float | None = None) -> Any:
    """The :class:`~optcal.applications.diagnosis.diagnoser.DiagnosisSettings` of the command's options."""
    from optcal.applications.diagnosis import DiagnosisSettings

    return DiagnosisSettings(effects=effects, folds=folds, simulations=simulations, alpha=alpha, seed=seed, method=method,
                             pose_correlation=pose_correlation, calibration=dict(calibration or {}),
                             drop_unneeded=drop_unneeded, term_pairs=term_pairs, pose_noise=pose_noise,
                             heldout_se=heldout_se)


def progress_printer() -> Any:
    """Progress bars on stderr in a terminal, stage messages otherwise; nothing with ``--quiet`` (``optcal -q`` too)
    or ``--json`` into a pipe: the command line's one decision (:func:`optcal.core.progress.decide`)."""
    from optcal.applications.diagnosis.progress import Progress

    return Progress.from_command_line()


@click.command()
@click.argument("data", type=DATA_PATH, nargs=-1, required=True)
@data_options
@diagnosis_options
@click.option("--baseline", "baseline_path", type=click.Path(dir_okay=False), default=None, metavar="CAL",
              help="Start from this saved calibration instead of calibrating with --method; imucal's JSON or imu_tk's "
                   ".calib is set next to optcal's own fit of DATA (what each misses).")
@click.option("--pose-correlation", type=click.Choice(["auto", "off", "on"]), default="auto", show_default=True,
              help="Pose noise correlated in time: used on evidence (auto), never (off: poses independent), or always (on).")
@click.option("--pose-noise", type=click.Choice(["given", "auto", "floor"]), default="given", show_default=True,
              help="The poses' weights: the per-pose σ as logged (given; a pose-to-pose noise beside it is still "
                   "tested and reported), σ widened by a fitted pose-to-pose noise when the residuals show one "
                   "(auto), or always (floor).")
@click.option("--keep-terms", is_flag=True,
              help="Keep every term the forward selection accepted: no term is dropped when later ones make it "
                   "unneeded (the backward check; each drop is reported under its step).")
@click.option("--no-term-pairs", is_flag=True,
              help="Test one term at a time only: no pair of terms (or one effect on every axis) searched together "
                   "when no single term passes (two effects that mask each other are then missed).")
@click.option("--heldout-se", type=click.FloatRange(0, 100), default=None, metavar="K",
              help="Enter an accelerometer term only when its paired gain on the held-out poses exceeds K of its "
                   "standard errors (default 0: any fall of the held-out rms); the gain, its SE and t are printed "
                   "for every candidate judged.")
@click.option("--sensor", type=click.Choice(["acc", "mag"]), default="acc", show_default=True,
              help="The sensor to diagnose: the accelerometer (static poses; --imu adds the gyroscope) or the "
                   "magnetometer (raw samples mx, my, mz: a local disturbance, a temperature or current column).")
@click.option("--mag-units", type=click.Choice(["uT", "nT", "gauss", "mgauss", "counts"]), default=None,
              help="--sensor mag: units of the magnetometer (default from the file or the data).")
@mag_read_options
@click.option("--imu", is_flag=True,
              help="Diagnose the gyroscope too (a raw recording with gyro columns): its gravity prediction across the "
                   "moves against its noise band, g_sensitivity, gyro_scale_nonlinearity, gyro_temperature_bias, "
                   "gyro_bias_drift and time_offset tested, the extended gyro model fitted, its held-out gain.")
@click.option("--gyro-heldout-se", type=click.FloatRange(0, 100), default=None, metavar="K",
              help="--imu: name a gyro finding only when its paired gain on the held-out moves exceeds K of its "
                   "standard errors (default: Student's one-sided 5 % quantile, about 1.7, for the terms; 1 for the "
                   "time offset, whose own t test is on the moves); 0 names one on any positive held-out gain.")
@click.option("--gyro-g-evidence", type=click.Choice(["response", "angles"]), default=None,
              help="--imu: what the held-out moves must show to confirm a g-sensitivity: response (the default), "
                   "their angle's paired gain or their response to it (1 when they carried what it removes, 0 when "
                   "none of it) beyond Student's 5 %% quantile; angles, the angle's gain alone, as every other term.")
@click.option("--no-gyro-frame-check", "no_frame_check", is_flag=True,
              help="--imu: skip refitting the accelerometer's frame jointly with the moves when they leave the band "
                   "unexplained (2k + 1 IMU fits, k the folds).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text report.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None, metavar="CAL",
              help="Save the final model as a calibration file (extended when effects were found, else lumped), "
                   "with the temperature, time and |a| ranges it was fitted on.")
@peer_options
@report_options
@solver_options
def diagnose(data: tuple[str, ...], effects: str | None, folds: int, simulations: int, alpha: float, seed: int, method: str,
             plot_dir: str | None, quiet: bool, baseline_path: str | None, pose_correlation: str, pose_noise: str,
             keep_terms: bool, no_term_pairs: bool, sensor: str,
             mag_units: str | None, accept_mag_fit: bool, keep_mag_repeats: bool, keep_mag_spikes: bool, imu: bool,
             gyro_heldout_se: float | None, gyro_g_evidence: str | None, heldout_se: float | None, as_json: bool,
             no_frame_check: bool, output: str | None, peer_gravity: float | None, gyro_calib: str | None, report_path: str | None,
             tolerance: float, **data_opts: Any) -> None:
    """Show where the calibrated model's simulation disagrees with DATA, name the cause, extend the model, measure the gain.

    DATA is a pose table or a raw recording (anything `optcal calibrate` reads); several DATA
    (`optcal diagnose A B C`) are sessions of one sensor, each read with its own data decisions,
    diagnosed together: one calibration for all, and "the bias changed between sessions"
    (session_bias, per-session offsets) as a candidate cause; time counts from each session's
    own start.  The paper's
    model is fitted (by --method, or taken from --baseline) and simulated many times on the same
    poses; the candidate effects (temperature_bias, temperature_scale, bias_drift,
    scale_nonlinearity, outliers) are tried per axis by forward selection (likelihood-ratio test,
    BIC and k-fold held-out error); the findings, the final model and its gain on held-out poses
    are reported.  A --baseline from imucal or imu_tk (recognised by content) is shown next to
    optcal's baseline fit of DATA: each one's error on DATA's poses (optcal's also held out), and
    what the peer's bias, scales and axis angles miss.

    With --imu (one raw recording with gyro columns) the gyroscope is diagnosed too: the IMU
    calibration's gravity prediction across each move against its noise band, the gyro's
    candidate effects by the same forward selection (on held-out moves), the extended gyro model
    refitted in CasADi; the findings of both sensors are listed (each says its "sensor"), and -o
    saves the IMU calibration with the g-sensitivity found (what an IMU calibration cannot hold is
    said).
    """
    from optcal.cli.data_options import data_line, data_summary, load_data_detailed
    from optcal.applications.diagnosis import Diagnoser
    from optcal.report.diagnosis_figures import save_figures
    from optcal.report.diagnosis_text import diagnosis_report

    from optcal.cli.outputs import echo_json, output_file, plot_folder
    from optcal.errors import InputError

    if sensor == "mag":
        if heldout_se is not None:
            raise InputError("--heldout-se applies to the accelerometer's diagnosis (--sensor acc)")
        if imu or baseline_path or len(data) != 1:
            raise InputError("--sensor mag diagnoses one magnetometer recording: one DATA, without --imu or --baseline")
        return _diagnose_mag(data[0], alpha, as_json, output, data_opts, mag_units, accept_mag_fit,
                             keep_mag_repeats, keep_mag_spikes)
    if mag_units is not None:
        raise InputError("--mag-units applies with --sensor mag")
    refuse_mag_options(accept_mag_fit, keep_mag_repeats, keep_mag_spikes, "with --sensor mag")
    if gyro_heldout_se is not None and not imu:
        raise InputError("--gyro-heldout-se applies with --imu (the gyroscope's diagnosis)")
    if gyro_g_evidence is not None and not imu:
        raise InputError("--gyro-g-evidence applies with --imu (the gyroscope's diagnosis)")
    if no_frame_check and not imu:
        raise InputError("--no-gyro-frame-check applies with --imu (the gyroscope's diagnosis)")
    fit_settings = estimator_settings(method, **pop_solver_options(data_opts))
    if fit_settings and baseline_path:
        raise InputError("--solver, --conic-solver, --fix and --bound set how the baseline is calibrated; "
                         "not with --baseline, which gives it")
    if imu and (len(data) != 1 or baseline_path):
        raise InputError("--imu diagnoses one raw recording with gyro columns: give one DATA, without --baseline")
    settings = settings_from(effects, folds, simulations, alpha, seed, method, pose_correlation, fit_settings,
                             not keep_terms, not no_term_pairs, pose_noise, heldout_se)
    figures_into = plot_folder(plot_dir) if plot_dir else None
    baseline = load_calibration(baseline_path, peer_gravity, gyro_calib) if baseline_path else None
    reporter = progress_printer()
    loaded = [load_data_detailed(path, **data_opts) for path in reporter.loop(data, "reading the sessions", len(data))]
    sessions = [item.poses for item in loaded]
    still_parts = [item.segmentation for item in loaded]  # the raw samples: the measured noise route
    if not as_json:
        for path, session in zip(data, sessions):
            click.echo(data_line(path, session))
    diagnoser = Diagnoser(settings, reporter)
    if len(sessions) == 1:
        poses, source = sessions[0], data[0]
        diag = diagnoser.run(poses, baseline, still_parts[0])
    else:
        diag = diagnoser.run_sessions(sessions, baseline, names=list(data), still_parts=still_parts)
        poses, source = diag.poses, " + ".join(data)
    if baseline is not None and baseline.cal_type == "peer":  # another tool's calibration next to optcal's own fit
        from optcal.applications.quality.peer import compare_with_peer
        from optcal.applications.quality.validation import convert_to_units

        diag.peer = compare_with_peer(baseline, convert_to_units(diag.poses, baseline.units), None,
                                      own=diag.baseline_model, own_label=f"the diagnosis's baseline: {diag.baseline_source} "
                                      f"refitted on these {diag.n} poses", own_heldout=diag.baseline_heldout, folds=folds)
    gyro = (_diagnose_gyro(loaded[0], method, alpha, folds, fit_settings, simulations, seed, gyro_heldout_se,
                           gyro_g_evidence or "response", not no_frame_check)
            if imu else None)
    paths = save_figures(diag, figures_into, gyro[0] if gyro is not None else None) if figures_into else []
    calibration = diag.calibration() if output and gyro is None else (gyro[1] if gyro is not None and output else None)
    if calibration is not None and output:
        calibration.save(output_file(output))
    if report_path:
        from optcal.report.document import diagnosis_document

        write_report(diagnosis_document(diag, poses, source, command_line(), tolerance,
                                        gyro[0] if gyro is not None else None), report_path)
    if as_json:
        out = diag.to_dict()
        summaries = [data_summary(path, session) for path, session in zip(data, sessions)]
        out["data"] = summaries[0] if len(summaries) == 1 else summaries  # one per session
        out["figures"] = paths
        out["saved"] = None if calibration is None else {"path": output, "cal_type": calibration.cal_type}
        if gyro is not None:
            gyro_out = gyro[0].to_dict()
            out["accelerometer_gain"] = out.get("gain")
            out["findings"] = [*out.get("findings", []), *gyro_out["findings"]]
            out["gain"] = gyro_out["gain"]
            out["gyroscope"] = {**gyro_out, "losses": gyro[2]}
        echo_json(out)
        return
    click.echo(diagnosis_report(diag))
    if gyro is not None:
        click.echo("\n".join(gyro[0].report_lines()))
        for loss in gyro[2] if output else []:
            click.echo(f"  saved without: {loss}")
    for path in paths:
        click.echo(f"figure: {path}")
    if calibration is not None:
        click.echo(f"saved: {output} ({calibration.describe()})")


def _diagnose_gyro(reading: Any, method: str, alpha: float, folds: int, fit_settings: dict[str, Any],
                   simulations: int = 200, seed: int = 0, heldout_se: float | None = None,
                   g_evidence: str = "response", check_frame: bool = True) -> Any:
    """The gyroscope's diagnosis of one recording: (diagnosis, the IMU calibration with its g-sensitivity, what the
    calibration cannot hold).  The gyro fit is kept whatever its fit check says (``accept_gyro_fit``): a fit the
    check refuses is what the diagnosis explains."""
    from dataclasses import replace

    import numpy as np

    from optcal.applications.diagnosis.gyro_diagnosis import GyroDiagnosisSettings, diagnose_gyro
    from optcal.core.gyro_model import BIAS_NAMES, G_NAMES, T_NAMES, GyroModel
    from optcal.families.gyro.estimator import GyroSettings, calibrate_imu_loaded
    from optcal.families.gyro.moves import moves_from_segmentation

    solver = fit_settings.get("solver")
    imu = calibrate_imu_loaded(reading, method=method, settings=GyroSettings(accept_gyro_fit=True, solver=solver))
    moves = moves_from_segmentation(reading.segmentation)
    result = diagnose_gyro(moves, imu.accelerometer, imu.gyro,
                           GyroDiagnosisSettings(alpha=alpha, folds=min(folds, 5), solver=solver,
                                                 simulations=simulations, seed=seed, heldout_se=heldout_se,
                                                 g_evidence=g_evidence, frame_check=check_frame))
    final = result.final
    rows = np.zeros((3, 3))
    losses = []
    for term, value in zip(final.terms, final.values):
        if term.effect == "g_sensitivity" and term.axis is not None:
            rows[term.axis] = value  # rad/s per g in the calibrated frame: ω = T (g − b) − K f
        else:
            losses.append(f"{term.label} (an IMU calibration holds a g-sensitivity only)")
    if result.time_offset.get("significant"):
        losses.append(f"time_offset {result.time_offset['dt_s'] * 1e3:.2f} ms (shift the gyro's stamps: an IMU "
                      "calibration holds no time offset)")
    g_raw = np.asarray(np.linalg.solve(final.T, rows), dtype=float) if np.any(rows) else None  # raw units per g: T⁻¹ K
    model = GyroModel(final.T, final.b, g_raw)
    params = np.concatenate([final.T.ravel(), final.b] + ([g_raw.ravel()] if g_raw is not None else []))
    names = list(T_NAMES) + list(BIAS_NAMES) + (list(G_NAMES) if g_raw is not None else [])
    covariance = np.full((len(names), len(names)), np.nan)
    calibration = replace(imu, gyro=model, params=params, param_names=names, covariance=covariance,
                          notes=[*imu.notes, "gyro extended by optcal diagnose --imu: "
                                 + ("; ".join(f.describe() for f in result.findings) or "nothing named")])
    return result, calibration, losses


def _diagnose_mag(data: str, alpha: float, as_json: bool, output: str | None, data_opts: dict[str, Any],
                  mag_units: str | None, accept_mag_fit: bool = False, keep_mag_repeats: bool = False, keep_mag_spikes: bool = False) -> None:
    """``optcal diagnose DATA --sensor mag`` (:mod:`optcal.applications.magnetic.diagnosis`): the plain calibration,
    then its diagnosis; ``-o`` saves the extended calibration (the disturbed stretches left out)."""
    import numpy as np

    from optcal.applications.magnetic.diagnosis import diagnose_mag
    from optcal.cli.outputs import echo_json, output_file
    from optcal.families.mag.calibration import MagCalibration, calibrate_mag
    from optcal.families.mag.samples import read_mag

    from optcal.families.mag.fit import MagSettings

    samples = read_mag(data, columns=data_opts.get("columns"), topic=data_opts.get("topic"), mag_units=mag_units,
                       keep_rail=accept_mag_fit, keep_repeats=keep_mag_repeats, keep_spikes=keep_mag_spikes)
    say = (lambda line: click.echo(line, err=True)) if as_json else click.echo
    say(f"data: {data}: {samples.n} magnetometer samples" + (", with an accelerometer" if samples.acc is not None else ""))
    for line in samples.decision_lines():
        say(line)
    plain = calibrate_mag(samples, MagSettings(accept_fit=accept_mag_fit))
    diag = diagnose_mag(samples, plain, alpha=alpha, gyro_units=data_opts.get("gyro_units"))
    ext = diag.extended
    T = np.asarray(ext["T"], dtype=float)
    info = {**plain.calibration.info, "diagnosis": {"findings": [f.to_dict() for f in diag.findings], "gain": diag.gain,
                                                    "excluded_samples": diag.excluded, "terms": ext["terms"]},
            "rms_norm_residual": ext["rms_norm_residual"], **({"dip_deg": ext["dip_deg"]} if "dip_deg" in ext else {})}
    R = np.asarray(ext["R_mag_to_acc"], dtype=float) if "R_mag_to_acc" in ext else plain.calibration.R_mag_to_acc
    calibration = MagCalibration(T, np.asarray(ext["o"], dtype=float), samples.units.units, ext["field_strength"],
                                 None, R, info)
    if output:
        calibration.save(output_file(output))
    if as_json:
        out = diag.to_dict()
        out.update(field_strength=ext["field_strength"], o=ext["o"], T=ext["T"],
                   rms_norm_residual=ext["rms_norm_residual"], data={"path": data, "decisions": samples.decision_lines()},
                   saved=None if not output else {"path": output, "cal_type": calibration.cal_type})
        echo_json(out)
        return
    click.echo("\n".join(diag.report_lines()))
    if output:
        lost = [f.effect for f in diag.findings if f.effect != "local_disturbance"]
        click.echo(f"saved: {output} (magnetometer calibration, the disturbed stretches left out"
                   + (f"; without {', '.join(lost)}: a calibration file holds no column terms" if lost else "") + ")")
