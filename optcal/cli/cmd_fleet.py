"""``optcal fleet INPUT... -o results.parquet``: calibrate many units on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from optcal.cli.data_options import data_options
from optcal.cli.outputs import echo_json
from optcal.cli.report_option import command_line, report_options, write_report
from optcal.cli.solver_options import estimator_settings, pop_solver_options, solver_options
from optcal.cli.quiet import quiet_option


@click.command()
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="Results table, one row per unit (Parquet).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON summary object on standard output.")
@click.option("--workers", type=click.IntRange(1), default=None,
              help="Worker processes of the local Dask cluster (one thread each) [Dask's default].")
@click.option("--scheduler", metavar="ADDRESS", default=None,
              help="Use an existing Dask cluster (e.g. tls://host:8786) instead of a local one; the same tasks run there.")
@click.option("--tls-ca-file", type=click.Path(exists=True, dir_okay=False), default=None,
              help="With --scheduler: CA certificate for TLS (Dask's tls_ca_file).")
@click.option("--tls-cert", type=click.Path(exists=True, dir_okay=False), default=None,
              help="With --scheduler: client certificate for TLS.")
@click.option("--tls-key", type=click.Path(exists=True, dir_okay=False), default=None,
              help="With --scheduler: client private key for TLS.")
@click.option("--dask-config", type=click.Path(exists=True, dir_okay=False), default=None,
              help="A Dask YAML configuration file (e.g. distributed.comm.tls settings) read before connecting.")
@click.option("--dashboard", is_flag=True,
              help="Serve the local cluster's dashboard on 127.0.0.1:8787 (off by default).")
@click.option("--prior", type=click.Choice(["population", "none"]), default="population", show_default=True,
              help="Refit every unit with the population prior (empirical Bayes); units not identifiable alone "
                   "become calibrated_with_prior.")
@click.option("--flag-threshold", type=click.FloatRange(min=0, min_open=True), default=None, metavar="K",
              help="Flag a unit when a parameter lies outside median ± K·1.4826·MAD of the population [3.5].")
@click.option("--plot", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Write a figure per parameter and a one-page summary figure (PNG) into DIR.")
@click.option("--chunk", type=click.IntRange(1), default=None, metavar="N",
              help="Units per Dask task [about eight tasks per worker, at most 64 units].")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bars on standard error when it is a terminal (--no-progress: as --quiet).")
@report_options
@solver_options
@data_options
@quiet_option
def fleet(inputs: tuple[str, ...], output: str, as_json: bool, workers: int | None, scheduler: str | None,
          tls_ca_file: str | None, tls_cert: str | None, tls_key: str | None, dask_config: str | None,
          dashboard: bool, prior: str, flag_threshold: float | None, plot: str | None, chunk: int | None, progress: bool,
          report_path: str | None, tolerance: float, **data_opts: Any) -> None:
    """Calibrate every unit of a fleet on Dask, flag the odd ones, borrow strength from the population.

    INPUT is a folder (every data file in it), a glob, a manifest CSV (columns unit, path and
    optional metadata) or a data file; paths may be fsspec URLs, which the workers open.  Each
    unit is calibrated exactly as `optcal calibrate` does.  By default a local Dask cluster
    runs on 127.0.0.1 with the dashboard off; --scheduler uses an existing cluster, over TLS
    with --tls-ca-file/--tls-cert/--tls-key or a --dask-config file.  Unreadable or degenerate
    files never stop the run: they are listed with their reason.
    """
    from optcal.cli.data_options import build_read_options
    from optcal.applications.fleet.engine import ClusterSettings, FleetClient, run_fleet
    from optcal.applications.fleet.inputs import expand_inputs
    from optcal.applications.fleet.population import DEFAULT_FLAG_THRESHOLD
    from optcal.core.progress import enabled as progress_enabled

    from optcal.errors import InputError

    if not Path(output).resolve().parent.is_dir():
        raise InputError(f"{output}: its folder does not exist; create it or give another -o path")
    fit_settings = estimator_settings("default", **pop_solver_options(data_opts))
    units = expand_inputs(list(inputs))
    settings = ClusterSettings(workers=workers, scheduler=scheduler, dashboard=dashboard, tls_ca_file=tls_ca_file,
                               tls_cert=tls_cert, tls_key=tls_key, dask_config=dask_config)
    threshold = DEFAULT_FLAG_THRESHOLD if flag_threshold is None else flag_threshold
    with FleetClient(settings) as fc:
        where = "listening on 127.0.0.1" if scheduler is None else "existing cluster"
        board = f"dashboard {fc.dashboard_link}" if fc.dashboard_link else "dashboard off"
        click.echo(f"engine: {fc.engine} ({where}, {board}); {len(units)} units", err=True)
        result = run_fleet(units, fc.client, engine=fc.engine, load_options=build_read_options(data_opts),
                           fit_settings=fit_settings,
                           flag_threshold=threshold, prior=prior, chunk=chunk, progress=progress and progress_enabled(), output=output)
    if plot:
        _write_figures(result, Path(plot))
    if report_path:
        from optcal.report.fleet_report import fleet_document

        write_report(fleet_document(result, output, command_line(), tolerance), report_path)
    if as_json:
        echo_json(result.summary(output))
    else:
        click.echo(result.report())
        click.echo(f"results: {output}" + (f"; figures in {plot}" if plot else ""))
    calibrated = result.count("calibrated") + result.count("calibrated_with_prior")
    if calibrated == 0:  # the results say why each unit failed; the run did not do its job
        raise InputError(f"no unit of {len(result.outcomes)} was calibrated (the reasons are in {output} and above)")


def _write_figures(result: Any, folder: Path) -> None:
    from optcal.applications.fleet.population import STATISTICS, parameter_figure, summary_figure

    if result.stats is None:
        click.echo("no figures: fewer than 5 units calibrated by their own data", err=True)
        return
    from optcal.cli.outputs import plot_folder, writing

    folder = plot_folder(folder)
    for name in STATISTICS:
        with writing(folder / f"{name}.png", "--plot") as tmp:  # whole or not at all
            parameter_figure(result.outcomes, result.stats, name).savefig(tmp, dpi=110)
    with writing(folder / "summary.png", "--plot") as tmp:
        summary_figure(result.outcomes, result.stats).savefig(tmp, dpi=90)
