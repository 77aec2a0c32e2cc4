"""``optcal diagnose DATA``: what the calibrated model gets wrong, the cause, the extended model, the gain."""

from __future__ import annotations

from typing import Any

import click

from optcal.families.accel.calibration import METHOD_CHOICES
from optcal.cli.data_options import DATA_PATH, data_options
from optcal.cli.peer_options import load_calibration, peer_options
from optcal.cli.report_option import command_line, report_options, write_report
from optcal.cli.solver_options import estimator_settings, pop_solver_options, solver_options
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
                     help="Simulations of the fitted model in the simulation check (parametric bootstrap)."),
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
                  pose_correlation: str = "auto", calibration: dict[str, Any] | None = None) -> Any:
    """The :class:`~optcal.applications.diagnosis.diagnoser.DiagnosisSettings` of the command's options."""
    from optcal.applications.diagnosis import DiagnosisSettings

    return DiagnosisSettings(effects=effects, folds=folds, simulations=simulations, alpha=alpha, seed=seed, method=method,
                             pose_correlation=pose_correlation, calibration=dict(calibration or {}))


def progress_printer(quiet: bool) -> Any:
    """Progress bars on stderr in a terminal, stage messages otherwise; nothing with ``--quiet`` (``optcal -q`` too)."""
    from optcal.applications.diagnosis.progress import Progress

    context = click.get_current_context(silent=True)
    root = context.find_root().obj if context is not None else None
    return Progress.for_terminal(quiet or bool(isinstance(root, dict) and root.get("quiet")))


@click.command()
@click.argument("data", type=DATA_PATH, nargs=-1, required=True)
@data_options
@diagnosis_options
@click.option("--baseline", "baseline_path", type=click.Path(dir_okay=False), default=None, metavar="CAL",
              help="Start from this saved calibration instead of calibrating with --method; imucal's JSON or imu_tk's "
                   ".calib is set next to optcal's own fit of DATA (what each misses).")
@click.option("--pose-correlation", type=click.Choice(["auto", "off", "on"]), default="auto", show_default=True,
              help="Pose noise correlated in time: used on evidence (auto), never (off: poses independent), or always (on).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text report.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None, metavar="CAL",
              help="Save the final model as a calibration file (extended when effects were found, else lumped), "
                   "with the temperature, time and |a| ranges it was fitted on.")
@peer_options
@report_options
@solver_options
def diagnose(data: tuple[str, ...], effects: str | None, folds: int, simulations: int, alpha: float, seed: int, method: str,
             plot_dir: str | None, quiet: bool, baseline_path: str | None, pose_correlation: str, as_json: bool,
             output: str | None, peer_gravity: float | None, gyro_calib: str | None, report_path: str | None,
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
    """
    from optcal.cli.data_options import data_line, data_summary, load_data_detailed
    from optcal.applications.diagnosis import Diagnoser
    from optcal.report.diagnosis_figures import save_figures
    from optcal.report.diagnosis_text import diagnosis_report

    from optcal.cli.outputs import echo_json, output_file, plot_folder
    from optcal.errors import InputError

    fit_settings = estimator_settings(method, **pop_solver_options(data_opts))
    if fit_settings and baseline_path:
        raise InputError("--solver, --conic-solver, --fix and --bound set how the baseline is calibrated; "
                         "not with --baseline, which gives it")
    settings = settings_from(effects, folds, simulations, alpha, seed, method, pose_correlation, fit_settings)
    figures_into = plot_folder(plot_dir) if plot_dir else None
    baseline = load_calibration(baseline_path, peer_gravity, gyro_calib) if baseline_path else None
    reporter = progress_printer(quiet)
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
    paths = save_figures(diag, figures_into) if figures_into else []
    calibration = diag.calibration() if output else None
    if calibration is not None and output:
        calibration.save(output_file(output))
    if report_path:
        from optcal.report.document import diagnosis_document

        write_report(diagnosis_document(diag, poses, source, command_line(), tolerance), report_path)
    if as_json:
        out = diag.to_dict()
        summaries = [data_summary(path, session) for path, session in zip(data, sessions)]
        out["data"] = summaries[0] if len(summaries) == 1 else summaries  # one per session
        out["figures"] = paths
        out["saved"] = None if calibration is None else {"path": output, "cal_type": calibration.cal_type}
        echo_json(out)
        return
    click.echo(diagnosis_report(diag))
    for path in paths:
        click.echo(f"figure: {path}")
    if calibration is not None:
        click.echo(f"saved: {output} ({calibration.describe()})")
