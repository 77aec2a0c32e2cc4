"""The results of a fleet run: the Parquet table, the JSON summary, the one-page report.

Table columns (one row per unit): ``unit``, ``path``, ``status``, ``reason``, the nine
parameters ``T_xx T_yx T_yy T_zx T_zy T_zz o_x o_y o_z`` and their standard errors
``<name>_stderr``, ``rms_g``, ``heldout_rms_g``, ``n_poses``, ``n_excluded`` and
``exclusions`` (JSON of the counts), ``units``, ``sigma_known``, ``flag`` (bool) and
``flag_reason``; then the refit with the population prior, ``<name>_with_prior``,
``<name>_with_prior_stderr`` and ``<name>_prior_weight`` (the share of the estimate that comes
from the prior), and the manifest's metadata as ``meta_<column>``.  For a
``calibrated_with_prior`` unit the main parameter columns hold the fit with the prior.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from optcal.applications.fleet.population import PopulationStats
from optcal.applications.fleet.prior import PopulationPrior
from optcal.applications.fleet.unit import STATUSES, UnitOutcome
from optcal.core.atomic import atomic_path
from optcal.core.model import PARAM_NAMES


def _vector_columns(values: Any, suffix: str) -> dict[str, float]:
    v = np.full(9, np.nan) if values is None else np.asarray(values, dtype=float)
    return {f"{name}{suffix}": float(x) for name, x in zip(PARAM_NAMES, v)}


def unit_row(o: UnitOutcome, meta_keys: list[str] | None = None) -> dict[str, Any]:
    """One row of the results table (``meta_keys``: every metadata column of the table, missing ones empty)."""
    row: dict[str, Any] = {"unit": o.unit, "path": o.path, "status": o.status, "reason": o.reason}
    row.update(_vector_columns(o.theta, ""))
    row.update(_vector_columns(o.stderr, "_stderr"))
    row.update({
        "rms_g": o.rms_g, "heldout_rms_g": o.heldout_rms_g, "n_poses": int(o.n_poses),
        "n_excluded": int(sum(o.exclusions.values())), "exclusions": json.dumps(o.exclusions, sort_keys=True),
        "units": o.units, "sigma_known": bool(o.sigma_known), "flag": bool(o.flag), "flag_reason": o.flag,
    })
    row.update(_vector_columns(o.theta_with_prior, "_with_prior"))
    row.update(_vector_columns(o.stderr_with_prior, "_with_prior_stderr"))
    row.update(_vector_columns(o.prior_weight, "_prior_weight"))
    row.update({f"meta_{k}": v for k, v in o.metadata.items()})
    row.update({f"meta_{k}": None for k in meta_keys or () if k not in o.metadata})
    return row


#: Rows per Parquet row group of the results table.
ROW_GROUP: int = 4096


def results_schema(meta_keys: list[str]) -> Any:
    """The :class:`pyarrow.Schema` of the results table (columns of :func:`unit_row`)."""
    import pyarrow as pa

    types = {"unit": pa.string(), "path": pa.string(), "status": pa.string(), "reason": pa.string(),
             "n_poses": pa.int64(), "n_excluded": pa.int64(), "exclusions": pa.string(), "units": pa.string(),
             "sigma_known": pa.bool_(), "flag": pa.bool_(), "flag_reason": pa.string()}
    columns = unit_row(UnitOutcome("", "", ""), meta_keys)
    return pa.schema([(name, types.get(name, pa.string() if name.startswith("meta_") else pa.float64()))
                      for name in columns])


class ResultsWriter:
    """The results table written as the units finish, in Parquet row groups of ``row_group`` rows.

    The client holds at most one row group of rows at a time instead of the whole table (a
    10⁶-unit table is ≈ 0.5 GB as Parquet, several GB as Python rows).  A context manager.

    Parameters
    ----------
    path : str or Path
    meta_keys : list of str
        Every manifest metadata column of the fleet (the schema is fixed before the first row).
    row_group : int
        Rows per row group (:data:`ROW_GROUP`): large enough for Parquet's column encodings.
    """

    def __init__(self, path: str | Path, meta_keys: list[str], row_group: int = 0) -> None:
        import pyarrow.parquet as pq

        self.meta_keys = list(meta_keys)
        self.schema = results_schema(self.meta_keys)
        self.row_group = int(row_group) or ROW_GROUP
        # written to a temporary file beside PATH and renamed when closed: a failed or interrupted run leaves no partial table
        self._atomic: Any = atomic_path(path)
        self._writer = pq.ParquetWriter(str(self._atomic.__enter__()), self.schema)
        self._pending: list[dict[str, Any]] = []
        self.rows = 0

    def write(self, outcomes: list[UnitOutcome]) -> None:
        """Append the rows of ``outcomes`` (written once a row group is full)."""
        self._pending += [unit_row(o, self.meta_keys) for o in outcomes]
        if len(self._pending) >= self.row_group:
            self._flush()

    def _flush(self) -> None:
        import pyarrow as pa

        if self._pending:
            self._writer.write_table(pa.Table.from_pylist(self._pending, schema=self.schema))
            self.rows += len(self._pending)
            self._pending = []

    def close(self) -> None:
        """Write the last rows and rename the table to its path."""
        self.__exit__(None, None, None)

    def __enter__(self) -> "ResultsWriter":
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._atomic is None:
            return
        atomic, self._atomic = self._atomic, None
        try:
            if exc[0] is None:
                self._flush()
            self._writer.close()
        except BaseException as error:
            atomic.__exit__(type(error), error, error.__traceback__)  # removes the temporary file
            raise
        atomic.__exit__(*exc)  # renamed when complete, removed after a failure


@dataclass
class FleetResult:
    """Every unit's outcome and what the population says.

    Attributes
    ----------
    outcomes : list of UnitOutcome
        In input order.
    stats : PopulationStats or None
        Robust bands (``None`` with fewer than five units calibrated by their own data).
    prior : PopulationPrior or None
        The population prior used for the refits.
    prior_note : str
        Why there is no prior, when there is none.
    engine : str
        The cluster it ran on.
    seconds : float
        Wall time of the run (cluster start not included).
    chunk : int
        Units per Dask task.
    """

    outcomes: list[UnitOutcome]
    stats: PopulationStats | None
    prior: PopulationPrior | None
    prior_note: str
    engine: str
    seconds: float
    chunk: int = 1

    def count(self, status: str) -> int:
        """Units with ``status``."""
        return sum(o.status == status for o in self.outcomes)

    @property
    def flagged(self) -> list[UnitOutcome]:
        return [o for o in self.outcomes if o.flag]

    @property
    def not_calibrated(self) -> list[UnitOutcome]:
        return [o for o in self.outcomes if not o.calibrated]

    def to_frame(self) -> Any:
        """The results table as a :class:`pandas.DataFrame`."""
        import pandas as pd

        return pd.DataFrame([unit_row(o) for o in self.outcomes])

    def write_parquet(self, path: str | Path) -> None:
        """Write the results table to a Parquet file (as :class:`ResultsWriter` does while a run streams it)."""
        meta_keys = sorted({k for o in self.outcomes for k in o.metadata})
        with ResultsWriter(path, meta_keys) as writer:
            writer.write(self.outcomes)

    def summary(self, results_path: str | None = None) -> dict[str, Any]:
        """The JSON summary (``engine``, ``n_units``, ``calibrated``, ``failed``, ``flagged``, ``results``, ...)."""
        out: dict[str, Any] = {
            "engine": self.engine,
            "n_units": len(self.outcomes),
            "calibrated": self.count("calibrated") + self.count("calibrated_with_prior"),
            "status_counts": {s: self.count(s) for s in STATUSES},
            "failed": [{"unit": o.unit, "error": o.reason, "status": o.status} for o in self.not_calibrated],
            "flagged": [{"unit": o.unit, "reason": o.flag} for o in self.flagged],
            "results": results_path,
            "flag_rule": self.stats.rule() if self.stats else "no population statistics (fewer than 5 units calibrated)",
            "prior": ({"n_units": self.prior.n_units, "units": self.prior.units,
                       "mean": dict(zip(PARAM_NAMES, self.prior.mean.tolist())),
                       "sd": dict(zip(PARAM_NAMES, np.sqrt(np.diag(self.prior.covariance)).tolist()))}
                      if self.prior else {"note": self.prior_note}),
            "seconds": self.seconds,
            "units_per_task": self.chunk,
        }
        if self.stats:
            out["population"] = {b.name: {"median": b.median, "robust_sd": b.spread} for b in self.stats.bands}
        return out

    def report(self) -> str:
        """The one-page text summary."""
        lines = [f"Fleet of {len(self.outcomes)} units on {self.engine} ({self.chunk} units per task), {self.seconds:.1f} s"]
        lines.append("  " + ", ".join(f"{s} {self.count(s)}" for s in STATUSES))
        if self.stats:
            lines += ["", f"Population ({self.stats.bands[0].n_units} units calibrated by their own data, {self.stats.units}):",
                      f"  {'statistic':<8s} {'median':>12s} {'robust SD':>11s} {'band':>27s}"]
            for b in self.stats.bands:
                lo = "-inf" if not np.isfinite(b.low) else f"{b.low:.6g}"
                lines.append(f"  {b.name:<8s} {b.median:12.6g} {b.spread:11.3g}   [{lo}, {b.high:.6g}]")
            lines.append(f"  rule: {self.stats.rule()}")
        if self.prior:
            sd = np.sqrt(np.diag(self.prior.covariance))
            lines += ["", f"Population prior from {self.prior.n_units} well-determined units (mean ± SD):",
                      "  " + ", ".join(f"{n} {m:.5g}±{s:.2g}" for n, m, s in zip(PARAM_NAMES, self.prior.mean, sd))]
            weak = [(o.unit, o.prior_weight) for o in self.outcomes  # the refit with the prior sets both
                    if o.status == "calibrated_with_prior" and o.prior_weight is not None]
            for unit, prior_weight in weak[:20]:
                share = ", ".join(f"{n} {w:.2f}" for n, w in zip(PARAM_NAMES, prior_weight) if w >= 0.1)
                lines.append(f"  {unit}: calibrated with the prior (share from the prior: {share or 'all < 0.1'})")
        else:
            lines += ["", f"Population prior: {self.prior_note}"]
        flagged = self.flagged
        lines += ["", f"Flagged: {len(flagged)}"] + [f"  {o.unit}: {o.flag}" for o in flagged[:30]]
        if len(flagged) > 30:
            lines.append(f"  ... {len(flagged) - 30} more in the results table")
        bad = self.not_calibrated
        lines += ["", f"Not calibrated: {len(bad)}"] + [f"  {o.unit} ({o.status}): {o.reason}" for o in bad[:30]]
        if len(bad) > 30:
            lines.append(f"  ... {len(bad) - 30} more in the results table")
        return "\n".join(lines)
