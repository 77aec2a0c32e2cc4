"""``optcal plan``: which orientations to take (``--poses K``), or which one next (``--next DATA``)."""

from __future__ import annotations

from typing import Any

import click

from optcal.cli.data_options import DATA_PATH, data_line, data_options, data_summary, load_data
from optcal.cli.outputs import echo_json
from optcal.cli.report_option import check_report_path, command_line, write_report
from optcal.cli.quiet import quiet_option
from optcal.cli.mag_options import mag_read_options, refuse_mag_options



#: Most poses a plan takes: the rounding is linear in K, and 10,000 held poses (at 1 s each, about three hours
#: of dwell alone) is past any calibration session; a larger K would only run long (issue 40: never unbounded).
MAX_PLAN_POSES = 10_000
#: Largest pose noise: the expected standard errors are σ² M⁻¹, and σ² of a larger σ is not a finite double.
MAX_SIGMA = 1e150

@click.command()
@click.option("--sensor", type=click.Choice(["acc", "mag"]), default="acc", show_default=True,
              help="mag: the orientations a magnetometer session still needs (the field directions its samples have not "
                   "reached, --next DATA; all 26 with --poses K).")
@click.option("--poses", "n_poses", type=click.IntRange(max=MAX_PLAN_POSES), default=None, metavar="K", help="Plan K orientations.")
@click.option("--next", "next_data", type=DATA_PATH, default=None, metavar="DATA",
              help="Recommend the one orientation that adds the most to the poses in DATA (pose table or raw recording).")
@click.option("--criterion", type=click.Choice(["D", "A", "E"], case_sensitive=False), default="D", show_default=True,
              help="D: maximise det of the Fisher information; A: minimise the sum of parameter variances; "
                   "E: maximise the information of the worst-determined combination.")
@click.option("--prior", default=None, metavar="CAL.json|nominal",
              help="Plan for this saved calibration; 'nominal' for T = I, o = 0. Default: nominal, or with "
                   "--given/--next the convex fit of that DATA when it determines one.")
@click.option("--sigma", type=click.FloatRange(min=0, min_open=True, max=MAX_SIGMA), default=None,
              help="Pose noise per axis, in the prior's units, for the expected standard errors [1 mg].")
@click.option("--turntable", is_flag=True, help="Only orientations of a three-axis turntable (Sun 2011) with gimbal steps of --turntable-step.")
@click.option("--turntable-step", type=float, default=45.0, show_default=True, metavar="DEG", help="Gimbal step of --turntable.")
@click.option("--within", type=float, default=None, metavar="DEG", help="Only orientations within DEG of --axis up (a device that cannot be turned over).")
@click.option("--axis", default="+z", show_default=True, help="Axis of --within: +x, -x, +y, -y, +z, -z.")
@click.option("--candidates", "candidates_file", type=click.Path(dir_okay=False), default=None,
              help="Choose only from the orientations in this CSV (dx,dy,dz or qw,qx,qy,qz or roll_deg,pitch_deg).")
@click.option("--given", "given_data", type=DATA_PATH, default=None, metavar="DATA",
              help="Poses already taken (pose table or raw recording): plan K more.")
@click.option("--target-stderr", type=click.FloatRange(min=0, min_open=True), default=None,
              help="With --next: say 'stop' once every standard error is below this (T relative to 1, o in g).")
@click.option("--grid", type=click.IntRange(100, 100_000), default=2000, show_default=True,
              help="Candidate directions on the sphere (or in the cap) for the relaxation.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True, help="Seed of the random rounding start.")
@click.option("--solver", default=None, metavar="NAME",
              help="NLP solver of the refinement on the sphere (a CasADi nlpsol plugin; ipopt by default); one that "
                   "does not run here is refused, naming those that do.")
@click.option("--solver-option", multiple=True, metavar="KEY=VALUE", help="An option of --solver (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the text report.")
@click.option("--plot", type=click.Path(), default=None, metavar="PATH",
              help="Save the orientation sphere into the folder PATH (plan.png; created when missing), or to PATH "
                   "itself when it ends in .png, .pdf or .svg.")
@click.option("--report", "report_path", type=click.Path(dir_okay=False), default=None, metavar="FILE.html",
              callback=check_report_path,
              help="Write the plan as a self-contained HTML page: the poses as a sphere map and a table to follow, "
                   "the criterion, the expected standard errors.")
@mag_read_options
@data_options
@quiet_option
def plan(sensor: str, n_poses: int | None, next_data: str | None, criterion: str, prior: str | None, sigma: float | None,
         turntable: bool, turntable_step: float, within: float | None, axis: str, candidates_file: str | None,
         given_data: str | None, target_stderr: float | None, grid: int, seed: int, solver: str | None,
         solver_option: tuple[str, ...], as_json: bool, plot: str | None, report_path: str | None,
         accept_mag_fit: bool, keep_mag_repeats: bool, keep_mag_spikes: bool, **data_opts: Any) -> None:
    """Plan calibration poses before taking them (optimal experiment design for the lumped model).

    --poses K: the K orientations that determine the nine parameters best (convex relaxation
    in cvxpy over a grid of gravity directions, rounding, refinement on the sphere in IPOPT),
    with the efficiency against the relaxation's bound and the expected standard errors.
    --next DATA: the next best orientation after the poses in DATA.
    """
    from optcal.errors import InputError
    from optcal.applications.plan import Cap, Prior, given_candidates, sphere_candidates, turntable_candidates
    from optcal.applications.plan.candidates import read_orientations

    if (n_poses is None) == (next_data is None):
        raise InputError("give either --poses K (plan K poses) or --next DATA (the next pose after DATA)")
    if sensor == "mag":
        used = [flag for flag, value in (("--criterion", criterion.upper() != "D"), ("--prior", prior), ("--sigma", sigma),
                                         ("--turntable", turntable), ("--within", within), ("--candidates", candidates_file),
                                         ("--given", given_data), ("--target-stderr", target_stderr), ("--plot", plot),
                                         ("--report", report_path), ("--solver", solver)) if value]
        if used:
            raise InputError(f"{', '.join(used)} plan the accelerometer's poses; --sensor mag plans the field directions "
                             "a magnetometer session still needs: drop them")
        _plan_mag(n_poses, next_data, as_json, data_opts, accept_mag_fit, keep_mag_repeats, keep_mag_spikes)
        return
    refuse_mag_options(accept_mag_fit, keep_mag_repeats, keep_mag_spikes, "with --sensor mag")
    if next_data is not None and given_data is not None:
        raise InputError("--next DATA already gives the poses taken; drop --given")
    if turntable and candidates_file:
        raise InputError("--turntable and --candidates both fix the orientations; give one")
    if target_stderr is not None and next_data is None:
        raise InputError("--target-stderr goes with --next DATA")
    if next_data is not None and criterion.upper() != "D":
        raise InputError("--next always uses the D criterion (the largest gain in log det); drop --criterion")

    from optcal.cli.solver_options import nlp_settings

    nlp = nlp_settings(solver=solver, solver_option=solver_option)  # a solver that cannot run: refused before reading
    data_path = next_data or given_data or ""
    poses = load_data(data_path, **data_opts) if data_path else None
    if poses is not None and not as_json:
        click.echo(data_line(data_path, poses))
    if prior is None or prior == "nominal":
        prior_model = (Prior.of_poses(poses, data_path) if prior is None and poses is not None
                       else Prior.nominal(poses.units if poses is not None else "g"))
    else:
        prior_model = Prior.load(prior)

    cap = Cap(axis, within) if within is not None else None
    if turntable:
        candidates = turntable_candidates(turntable_step, cap)
    elif candidates_file:
        candidates = given_candidates(read_orientations(candidates_file), cap, candidates_file)
    else:
        candidates = sphere_candidates(grid, cap)

    if n_poses is None:  # --next DATA: exactly one of --poses and --next was given (checked above)
        from optcal.applications.plan import next_pose

        if poses is None:
            raise InputError("--next DATA needs the path of the poses taken, not an empty string")
        result: Any = next_pose(poses, prior=prior_model, sigma=sigma, candidates=candidates,
                                target_stderr=target_stderr, **nlp)
        planned, given_dirs = result.direction[None, :], result.given_directions
    else:
        from optcal.applications.plan import plan_poses

        result = plan_poses(n_poses, criterion, prior=prior_model, sigma=sigma, candidates=candidates,
                            given=poses, seed=seed, **nlp)
        planned, given_dirs = result.directions, result.given_directions
    shown = None if candidates.continuous else candidates.directions
    if plot:
        from optcal.report.plan_figure import sphere_figure
        from optcal.cli.outputs import plot_file, writing

        plot = str(plot_file(plot, "plan.png"))
        with writing(plot, "--plot") as tmp:  # whole or not at all
            sphere_figure(planned, given_dirs, shown, cap).savefig(tmp, dpi=120)
    if report_path:
        from optcal.report.plan_report import plan_document

        write_report(plan_document(result, prior_model, command_line(), shown, cap, data_path), report_path)
    if as_json:
        out = result.to_dict()
        if poses is not None:
            out["data"] = data_summary(data_path, poses)
        echo_json(out)
        return
    click.echo(result.report())
    if poses is not None and poses.exclusions:
        click.echo("excluded from DATA: " + "; ".join(f"{k}: {v}" for k, v in poses.exclusions.items()))
    if plot:
        click.echo(f"figure: {plot}")


def _plan_mag(n_poses: int | None, next_data: str | None, as_json: bool, data_opts: dict[str, Any],
              accept_mag_fit: bool = False, keep_mag_repeats: bool = False, keep_mag_spikes: bool = False) -> None:
    """``plan --sensor mag``: the missing field directions of DATA's calibrated samples, or the first K of the 26."""
    from optcal.errors import InputError
    from optcal.families.mag.calibration import calibrate_mag
    from optcal.families.mag.coverage_plan import plan_coverage, plan_lines
    from optcal.families.mag.fit import COVERAGE_NAMES, MagSettings, coverage
    from optcal.families.mag.samples import read_mag

    cov = None
    if next_data is not None:
        samples = read_mag(next_data, columns=data_opts.get("columns"), topic=data_opts.get("topic"),
                           keep_rail=accept_mag_fit, keep_repeats=keep_mag_repeats, keep_spikes=keep_mag_spikes)
        if not as_json:
            click.echo(f"data: {next_data}: {samples.n} magnetometer samples")
            for line in samples.decision_lines():
                click.echo(line)
        # the hard iron only: a session that misses part of the sphere (what is planned for) does not determine the
        # soft iron, and the directions from the field's centre are what coverage asks
        cal = calibrate_mag(samples, MagSettings(form="offsets", allow_degenerate=True,
                                                 accept_fit=accept_mag_fit)).calibration
        cov = coverage(cal.correct(samples.m))
        planned = plan_coverage(cov)
    else:
        assert n_poses is not None
        if not 1 <= n_poses <= len(COVERAGE_NAMES):
            raise InputError(f"--sensor mag --poses K: K from 1 to {len(COVERAGE_NAMES)} (the coverage directions)")
        planned = plan_coverage(None)[:n_poses]
    if as_json:
        echo_json({"sensor": "magnetometer", "covered": list(cov.covered) if cov else [],
                   "missing": list(cov.missing) if cov else list(COVERAGE_NAMES),
                   "plan": [p.to_dict() for p in planned]})
        return
    for line in plan_lines(planned, cov):
        click.echo(line)
