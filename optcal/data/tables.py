"""Reading pose tables: one row per static pose, columns by header name."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from optcal.errors import InputError
from optcal.poses import PoseTable

ACC_COLUMNS = ("ax", "ay", "az")
GYRO_COLUMNS = ("gx", "gy", "gz")


def read_csv_frame(path: str | Path) -> pd.DataFrame:
    """Read a CSV file with a header row, with clear errors for unreadable files."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, expected a CSV file")
    try:
        frame = pd.read_csv(p, skipinitialspace=True)
    except pd.errors.EmptyDataError as exc:
        raise InputError(f"{p}: the file is empty; expected a CSV with a header row") from exc
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: not a readable CSV file ({str(exc).splitlines()[0]})") from exc
    frame.columns = [str(c).strip() for c in frame.columns]
    return frame


def numeric_column(frame: pd.DataFrame, name: str, source: str) -> np.ndarray:
    """Return a column as floats, naming the first non-numeric cell if there is one."""
    col = frame[name]
    values = pd.to_numeric(col, errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(np.isnan(values) & col.notna().to_numpy())
    if bad.size:
        r = int(bad[0])
        raise InputError(
            f"{source}: column {name!r} has a non-numeric value {str(col.iloc[r])!r} "
            f"on data row {r + 1}; every cell must be a number"
        )
    return values


def load_pose_table(path: str | Path, units: str | None = None) -> PoseTable:
    """Read a pose table CSV (``ax, ay, az`` required; ``t, temp, gx, gy, gz, sigma, n_samples`` optional).

    Parameters
    ----------
    path : str or Path
        CSV file with a header row and one row per static pose.
    units : {"g", "m/s^2", "counts"}, optional
        Units of the acceleration columns; guessed from the mean norm when omitted.
    """
    frame = read_csv_frame(path)
    src = str(path)
    missing = [c for c in ACC_COLUMNS if c not in frame.columns]
    if missing:
        raise InputError(
            f"{src}: missing column(s) {', '.join(missing)}; a pose table needs a header with "
            f"ax, ay, az (found: {', '.join(map(str, frame.columns)) or 'none'})"
        )
    if len(frame) == 0:
        raise InputError(f"{src}: no data rows")
    acc = np.column_stack([numeric_column(frame, c, src) for c in ACC_COLUMNS])
    opt = {c: numeric_column(frame, c, src) for c in ("t", "temp", "sigma", "n_samples") if c in frame.columns}
    gyro = None
    if all(c in frame.columns for c in GYRO_COLUMNS):
        gyro = np.column_stack([numeric_column(frame, c, src) for c in GYRO_COLUMNS])
    known = set(ACC_COLUMNS) | set(GYRO_COLUMNS) | set(opt)
    extra = {}
    for c in frame.columns:
        if c not in known:
            vals = pd.to_numeric(frame[c], errors="coerce")
            if vals.notna().all():
                extra[c] = vals.to_numpy(dtype=float)
    if units is None:
        units = guess_units(acc)
    table = PoseTable(
        acc=acc,
        sigma=opt.get("sigma"),
        n_samples=opt.get("n_samples"),
        t=opt.get("t"),
        temp=opt.get("temp"),
        gyro=gyro,
        rows=np.arange(1, len(frame) + 1),
        units=units,
        source="pose table",
        extra=extra,
        meta={"path": src},
    )
    return table


def guess_units(acc: np.ndarray) -> str:
    """Guess the units from the typical norm: ≈1 → g, ≈9.8 → m/s², large → counts."""
    finite = acc[np.all(np.isfinite(acc), axis=1)]
    if finite.size == 0:
        return "g"
    norm = float(np.median(np.linalg.norm(finite, axis=1)))
    if 0.3 < norm < 3.0:
        return "g"
    if 3.0 <= norm < 30.0:
        return "m/s^2"
    return "counts"
