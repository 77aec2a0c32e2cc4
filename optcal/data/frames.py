"""A pandas frame (a Parquet file's, or one made in memory) to a :class:`~optcal.data.source.Source`.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.data.source import Source
from optcal.data.source_columns import source_from_columns


def read_parquet(path: str | Path) -> Any:
    """Read a Parquet file (pyarrow) into a frame."""
    import pandas as pd

    try:
        frame = pd.read_parquet(path)
    except ImportError as exc:
        raise InputError("reading Parquet files needs pyarrow: pip install 'optcal[parquet]'") from exc
    except Exception as exc:  # pyarrow raises several types for damaged files
        raise InputError(f"{path}: not a readable Parquet file, truncated or corrupt ({exc.__class__.__name__}: {str(exc).splitlines()[0]})") from exc
    frame.columns = [str(c).strip() for c in frame.columns]
    if len(frame) == 0:
        raise InputError(f"{path}: no data rows")
    return frame


def source_from_frame(
    frame: Any,
    path: str,
    file_type: str,
    mapping: dict[str, str] | None = None,
    header: dict[str, str] | None = None,
) -> Source:
    """Map a pandas frame (Parquet, or made in memory) to canonical columns."""
    import pandas as pd

    names = [str(c) for c in frame.columns]
    columns: list[NDArray[np.float64]] = []
    non_numeric: dict[str, tuple[int, int, str]] = {}
    for name, col in zip(names, frame.columns):
        raw = frame[col]
        values = raw.astype(float) if pd.api.types.is_numeric_dtype(raw) else pd.to_numeric(raw, errors="coerce")
        bad = np.flatnonzero(values.isna().to_numpy() & raw.notna().to_numpy())
        if bad.size:
            non_numeric[name] = (int(bad.size), int(bad[0]) + 1, str(raw.iloc[bad[0]]))
        columns.append(values.to_numpy(dtype=float))
    return source_from_columns(names, columns, path, file_type, mapping, header, non_numeric)
