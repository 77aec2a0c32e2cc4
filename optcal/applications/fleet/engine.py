"""Running a fleet on Dask: the cluster, the task graph, the population steps.

The same task code runs on a default :class:`distributed.LocalCluster` and on an existing
cluster given by its scheduler address.  Safe defaults: the local cluster listens on the
loopback address only, its dashboard is off unless asked for, and a remote scheduler can be
reached over TLS (:class:`ClusterSettings`; or a Dask configuration file with the
``distributed.comm.tls`` settings).  Tasks receive paths or URLs and return small typed
objects (:mod:`optcal.applications.fleet.unit`); the pose tables stay on the workers between the first
fit and the refit with the population prior.

Steps of :func:`run_fleet`:

1. read and calibrate every unit (``read_unit`` → ``fit_units``: the default calibrations of a task's
   units solved together in batched IPOPT problems), in tasks of a few dozen units
   (:func:`auto_chunk`: per-task overhead of the scheduler stays small, and the data of a chunk
   stay on its worker);
2. population statistics and flags from the units calibrated by their own data
   (:mod:`optcal.applications.fleet.population`);
3. the population prior from the well-determined units, and every unit with data refitted
   with it (:mod:`optcal.applications.fleet.prior`): units refused alone become ``calibrated_with_prior``,
   the others keep their own calibration and get the prior fit beside it;
4. flags again for the units calibrated with the prior (on their residual).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from optcal.errors import InputError
from optcal.applications.fleet.inputs import UnitInput
from optcal.applications.fleet.population import DEFAULT_FLAG_THRESHOLD, PopulationStats, flag_units, population_stats
from optcal.applications.fleet.prior import PopulationPrior, estimate_prior, fit_with_prior
from optcal.applications.fleet.results import FleetResult, ResultsWriter
from optcal.applications.fleet.unit import ReadFailure, UnitOutcome, fit_units, outcome_from_result, read_unit
from optcal.core.poses import PoseTable
from optcal.data.options import ReadOptions


@dataclass(frozen=True)
class ClusterSettings:
    """Where the fleet runs.

    Attributes
    ----------
    workers : int, optional
        Worker processes of the local cluster (one thread each); Dask's default when omitted.
    scheduler : str, optional
        Address of an existing scheduler (``tls://host:8786``); a local cluster when omitted.
    dashboard : bool
        Serve the local cluster's dashboard (on 127.0.0.1:8787); off by default.
    tls_ca_file, tls_cert, tls_key : str, optional
        TLS files for the connection to ``scheduler`` (:class:`distributed.security.Security`).
    dask_config : str, optional
        A Dask YAML configuration file merged into ``dask.config`` first (for example with
        ``distributed.comm.tls`` settings).
    """

    workers: int | None = None
    scheduler: str | None = None
    dashboard: bool = False
    tls_ca_file: str | None = None
    tls_cert: str | None = None
    tls_key: str | None = None
    dask_config: str | None = None

    def __post_init__(self) -> None:
        tls = (self.tls_ca_file, self.tls_cert, self.tls_key)
        if any(tls) and self.scheduler is None:
            raise InputError("the TLS files (tls_ca_file, tls_cert, tls_key) apply to a scheduler address; give scheduler too")
        if any(tls) and not all(tls):
            raise InputError("TLS needs all three of tls_ca_file, tls_cert and tls_key")
        if self.workers is not None and self.scheduler is not None:
            raise InputError("workers sets the size of the local cluster; an existing scheduler brings its own workers")
        if self.workers is not None and self.workers < 1:
            raise InputError(f"workers must be at least 1, got {self.workers}")


class FleetClient:
    """A Dask client on the cluster of :class:`ClusterSettings`; a context manager.

    Attributes
    ----------
    client : distributed.Client
    engine : str
        What it runs on, e.g. ``"dask.distributed LocalCluster, 2 workers"``.
    """

    def __init__(self, settings: ClusterSettings) -> None:
        import dask
        from distributed import Client, LocalCluster

        if settings.dask_config:
            import yaml

            with open(settings.dask_config, encoding="utf-8") as fh:
                dask.config.update(dask.config.config, yaml.safe_load(fh) or {}, priority="new")
        self.cluster = None
        self.dashboard = settings.dashboard and settings.scheduler is None
        if settings.scheduler is None:
            # the tasks report every failure in their outcome; worker logs are only shutdown noise
            self.cluster = LocalCluster(
                n_workers=settings.workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address="127.0.0.1:8787" if settings.dashboard else None, silence_logs=logging.CRITICAL,
            )
            self.client = Client(self.cluster)
            n = len(self.cluster.workers)
            self.engine = f"dask.distributed LocalCluster, {n} worker{'s' if n != 1 else ''}"
        else:
            security = None
            if settings.tls_ca_file:
                from distributed.security import Security

                security = Security(tls_ca_file=settings.tls_ca_file, tls_client_cert=settings.tls_cert,
                                    tls_client_key=settings.tls_key, require_encryption=True)
            self.client = Client(settings.scheduler, security=security)
            n = len(self.client.scheduler_info().get("workers", {}))
            self.engine = f"dask.distributed scheduler {settings.scheduler}, {n} worker{'s' if n != 1 else ''}"

    @property
    def dashboard_link(self) -> str | None:
        """The dashboard's address when one is served."""
        return self.client.dashboard_link if self.dashboard else None

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def __enter__(self) -> "FleetClient":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def refit_unit(outcome: UnitOutcome, data: PoseTable | ReadFailure, prior: PopulationPrior,
               solver: tuple[str | None, dict[str, Any]] = (None, {})) -> UnitOutcome:
    """Refit one unit with the population prior (a Dask task; never raises).

    A unit calibrated by its own data keeps that calibration and gets the prior fit in
    ``theta_with_prior``; a refused unit with usable data becomes ``calibrated_with_prior``.
    """
    if isinstance(data, ReadFailure) or not (outcome.status == "calibrated" or outcome.prior_candidate):
        return outcome
    try:
        fit = fit_with_prior(data, prior, start=outcome.theta, solver=solver[0], ipopt_options=solver[1])
    except Exception as exc:  # noqa: BLE001 - the unit keeps its first outcome, with the reason
        return replace(outcome, reason="; ".join(x for x in (outcome.reason, f"prior refit failed: {exc}") if x))
    se = np.sqrt(np.clip(np.diag(fit.result.covariance), 0.0, None))
    if outcome.status == "calibrated":
        return replace(outcome, theta_with_prior=fit.result.params[:9].copy(), stderr_with_prior=se, prior_weight=fit.prior_weight)
    unit = UnitInput(outcome.unit, outcome.path, outcome.metadata)
    new = outcome_from_result(unit, data, fit.result, status="calibrated_with_prior")
    new.reason = f"not identifiable from its own data ({outcome.reason})"
    new.theta_with_prior, new.stderr_with_prior, new.prior_weight = new.theta, new.stderr, fit.prior_weight
    return new


#: Most units per task: a task of tens of fits (≈ 0.1 s) keeps Dask's per-task overhead (≈ 1 ms
#: of scheduler time) small without starving the workers at the end of the run.
MAX_CHUNK: int = 64


def auto_chunk(n_units: int, n_workers: int) -> int:
    """Units per task: about eight tasks per worker, at most :data:`MAX_CHUNK` units each."""
    return int(min(MAX_CHUNK, max(1, n_units // (8 * max(n_workers, 1)))))


def read_chunk(units: list[UnitInput], load_options: ReadOptions) -> list[PoseTable | ReadFailure]:
    """:func:`~optcal.applications.fleet.unit.read_unit` for a chunk of units (one Dask task)."""
    return [read_unit(u, load_options) for u in units]


def fit_chunk(units: list[UnitInput], data: list[PoseTable | ReadFailure],
              settings: dict[str, Any] | None = None) -> list[UnitOutcome]:
    """The units of a chunk calibrated together (:func:`~optcal.applications.fleet.unit.fit_units`; one Dask task)."""
    return fit_units(units, data, settings)


def refit_chunk(outcomes: list[UnitOutcome], data: list[PoseTable | ReadFailure], prior: PopulationPrior,
                stats: PopulationStats | None = None, settings: dict[str, Any] | None = None) -> list[UnitOutcome]:
    """:func:`refit_unit` for a chunk of units, then their flags from ``stats`` (one Dask task)."""
    solver = ((settings or {}).get("solver"), dict((settings or {}).get("solver_options") or {}))
    refitted = [refit_unit(o, d, prior, solver) for o, d in zip(outcomes, data)]
    if stats is not None:
        flag_units(refitted, stats)
    return refitted


def _gather(futures: list[Any], sizes: list[int], desc: str, progress: bool,
            on_error: Callable[[int, BaseException], list[Any]],
            consume: Callable[[list[Any]], None] | None = None, release: bool = False) -> list[list[Any]]:
    """Results of the chunk ``futures`` in their order, with a progress bar (in units) on standard error.

    A task that raises anyway (a worker lost, out of memory) gives ``on_error(index, exception)``.
    ``consume``, if given, receives every chunk's results in input order as soon as the chunks
    before it are in (those that finish early wait in a buffer), while the others still run.
    ``release`` lets the cluster forget each result once it is here (the futures are then spent).
    """
    from distributed import as_completed

    from optcal.core.progress import progress as bar

    index = {f.key: i for i, f in enumerate(futures)}
    out: list[list[Any]] = [[] for _ in futures]
    done = [False] * len(futures)
    next_out = 0
    for future in bar(as_completed(futures), total=sum(sizes), desc=desc, enabled=progress, unit="unit",
                      size=lambda f: sizes[index[f.key]]):
        i = index[future.key]
        try:
            out[i] = future.result()
        except Exception as exc:  # noqa: BLE001 - one lost task never stops the run
            out[i] = on_error(i, exc)
        if release:
            future.release()
        done[i] = True
        while consume is not None and next_out < len(futures) and done[next_out]:
            consume(out[next_out])
            next_out += 1
    return out


def run_fleet(
    units: list[UnitInput],
    client: Any,
    *,
    engine: str = "dask.distributed",
    load_options: ReadOptions | dict[str, Any] | None = None,
    fit_settings: dict[str, Any] | None = None,
    flag_threshold: float = DEFAULT_FLAG_THRESHOLD,
    prior: str = "population",
    chunk: int | None = None,
    progress: bool = False,
    output: str | Path | None = None,
) -> FleetResult:
    """Calibrate every unit on the Dask ``client`` and analyse the population.

    Parameters
    ----------
    units : list of UnitInput
        From :func:`optcal.applications.fleet.inputs.expand_inputs`.
    client : distributed.Client
    engine : str
        Description of the cluster for the summary.
    load_options : ReadOptions or dict, optional
        How every unit's data is read (:class:`optcal.data.ReadOptions`, or its fields as a dict).
    fit_settings : dict, optional
        Settings of every unit's estimator (:func:`optcal.calibrate`'s: ``solver``,
        ``solver_options``, ``fix``, ``bounds``, ``conic_solver``); the solver and its options
        serve the prior refit too.  With fixed or bounded parameters the prior refit is not run
        (it would move what the user holds), and the summary says so.
    flag_threshold : float
        ``k`` of the flag rule (:mod:`optcal.applications.fleet.population`).
    prior : {"population", "none"}
        Refit with the population prior (default) or not.
    chunk : int, optional
        Units per Dask task (:func:`auto_chunk` when omitted).
    progress : bool
        Progress bars on standard error (:func:`optcal.core.progress.progress`; the command line passes its
        decision, :func:`optcal.core.progress.enabled`).
    output : str or Path, optional
        The Parquet results table, written while the last stage runs (:class:`ResultsWriter`:
        in input order, row group by row group) rather than from the whole table at the end.
    """
    from uuid import uuid4

    uuid = uuid4().hex[:8]
    if prior not in ("population", "none"):
        raise InputError(f"prior must be 'population' or 'none', got {prior!r}")
    if not units:
        raise InputError("no units to calibrate")
    t0 = time.perf_counter()
    opts = load_options if isinstance(load_options, ReadOptions) else ReadOptions.build(None, **(load_options or {}))
    n_workers = len(client.scheduler_info().get("workers", {}))
    size = auto_chunk(len(units), n_workers) if chunk is None else int(chunk)
    if size < 1:
        raise InputError(f"chunk must be at least 1, got {chunk}")
    chunks = [units[s:s + size] for s in range(0, len(units), size)]
    sizes = [len(c) for c in chunks]
    reads = [client.submit(read_chunk, c, opts, key=f"read-{j}-{uuid}") for j, c in enumerate(chunks)]
    settings = dict(fit_settings or {})
    fits = [client.submit(fit_chunk, c, r, settings, key=f"fit-{j}-{uuid}") for j, (c, r) in enumerate(zip(chunks, reads))]
    per_chunk = _gather(
        fits, sizes, "calibrating", progress,
        lambda j, exc: [UnitOutcome(u.unit, u.path, "failed", f"task lost: {type(exc).__name__}: {exc}") for u in chunks[j]],
    )
    outcomes: list[UnitOutcome] = [o for part in per_chunk for o in part]
    stats = population_stats(outcomes, flag_threshold)
    if stats is not None:
        flag_units(outcomes, stats)
    held = bool(settings.get("fix") or settings.get("bounds"))
    fitted_prior = estimate_prior(outcomes, stats.units if stats else None) if prior == "population" and not held else None
    prior_note = "not asked for" if prior == "none" else ""
    meta_keys = sorted({k for u in units for k in u.metadata})
    with contextlib.ExitStack() as stack:
        writer = stack.enter_context(ResultsWriter(output, meta_keys)) if output is not None else None
        if fitted_prior is not None:
            prior_future = client.scatter(fitted_prior, broadcast=True)
            # the first outcomes stay on the workers (the fit futures); flags are set where the refit runs
            refits = [client.submit(refit_chunk, fits[j], reads[j], prior_future, stats, settings, key=f"prior-{j}-{uuid}")
                      for j in range(len(chunks))]
            del reads, fits
            kept = _gather(refits, sizes, "refitting with the prior", progress, lambda j, exc: per_chunk[j],
                           consume=writer.write if writer is not None else None, release=True)
            outcomes = [o for part in kept for o in part]
        else:
            if prior == "population" and held:
                prior_note = "not estimated: --fix/--bound hold parameters that the population prior would move"
            elif prior == "population":
                n_good = sum(o.status == "calibrated" and not o.flag for o in outcomes)
                prior_note = f"not estimated: {n_good} well-determined unit(s), at least 20 needed"
            del reads, fits
            if writer is not None:
                for part in per_chunk:
                    writer.write(part)
    return FleetResult(outcomes=outcomes, stats=stats, prior=fitted_prior, prior_note=prior_note,
                       engine=engine, seconds=time.perf_counter() - t0, chunk=size)
