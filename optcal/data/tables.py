"""Pose tables: one row per static pose, columns by header name.

A pose table has the accelerometer columns (``ax, ay, az`` or any name
:mod:`optcal.data.readers` recognises, or ``--columns``) and optionally ``t``, ``temp``,
``gx, gy, gz``, ``sigma`` (standard deviation of each pose mean) and ``n_samples``.  Any
other all-numeric column is kept as a per-pose extra column.
"""

from __future__ import annotations

from pathlib import Path

from typing import Any

import numpy as np

from optcal.data.decisions import DataDecisions, decide
from optcal.data.evidence import gather_evidence
from optcal.data.readers import ACC, GYRO, Source, source_from_frame
from optcal.data.units import decide_units
from optcal.errors import InputError
from optcal.core.poses import PoseTable

ACC_COLUMNS = ACC
GYRO_COLUMNS = GYRO


def read_csv_frame(path: str | Path) -> Any:
    """Read a delimited text file (any layout :mod:`optcal.data.text` recognises) as a pandas frame."""
    from optcal.data.text import read_frame

    return read_frame(path)[0]


def pose_table_from_source(src: Source, decisions: DataDecisions | str | None = None) -> PoseTable:
    """Build a :class:`PoseTable` from a tabular :class:`Source` read as a pose table (conversion step).

    Parameters
    ----------
    src : Source
    decisions : DataDecisions or str, optional
        The decisions (:func:`optcal.data.decisions.decide`), or just the user's units (then
        the decisions are made here, as a pose table).

    Raises
    ------
    InputError
        For a cell that is not a number (naming the column and row).
    """
    for canon, (count, row, value) in src.non_numeric.items():
        raise InputError(
            f"{src.path}: column {src.column_map.get(canon, canon)!r} has a non-numeric value "
            f"{value!r} on data row {row} ({count} such cell(s)); every cell must be a number"
        )
    if not isinstance(decisions, DataDecisions):
        decisions = decide(src, gather_evidence(src), kind="poses", units=decisions)
    # the rows the reader excluded (non-finite, all-zero, absurd: decisions.exclusions, printed as "excluded while
    # reading") are left out of the poses and counted in their exclusions, as a recording's samples are
    usable = decisions.evidence.usable if decisions.evidence is not None else None
    keep = None if usable is None or bool(np.all(usable)) else np.asarray(usable, dtype=bool)

    def column(name: str) -> np.ndarray:
        values = src.column(name)
        return values if keep is None else values[keep]

    acc = np.column_stack([column(c) for c in ACC])
    gyro = np.column_stack([column(c) for c in GYRO]) if src.has(*GYRO) else None
    opt = {c: column(c) for c in ("t", "temp", "sigma", "n_samples") if src.has(c)}
    rows = np.arange(1, src.n_rows + 1)
    meta = {
        "path": src.path,
        "file_type": src.file_type,
        "columns": src.describe_columns(),
        "units_reason": decisions.units.reason,
        "kind_reason": decisions.kind.reason,
        "decisions": decisions.to_dict(),
    }
    if src.ignored_columns:
        meta["ignored_columns"] = list(src.ignored_columns)
    return PoseTable(
        acc=acc,
        sigma=opt.get("sigma"),
        n_samples=opt.get("n_samples"),
        t=opt.get("t"),
        temp=opt.get("temp"),
        gyro=gyro,
        rows=rows if keep is None else rows[keep],
        units=str(decisions.units.value),
        source="pose table",
        exclusions=dict(decisions.exclusions) if keep is not None else {},
        extra={k: (v if keep is None else np.asarray(v)[keep]) for k, v in src.extra.items()},
        meta=meta,
        decisions=decisions,
    )


def guess_units(acc: np.ndarray) -> str:
    """Guess the units from the typical norm (see :func:`optcal.data.units.decide_units`)."""
    return decide_units(acc).units


__all__ = ["pose_table_from_source", "read_csv_frame", "guess_units", "source_from_frame"]
