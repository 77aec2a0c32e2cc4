"""A time column written as ISO 8601 date-times: read as seconds from its first row.

Phone and logger apps stamp rows with the wall clock as text (jbrodovsky/research's Pixel 6a export,
``2023-08-04 17:47:58-04:00``; others ``2023-08-04T17:21:05.123Z`` or ``2023-08-04 17:21:05.123`` without a zone).
The numeric readers (:mod:`optcal.data.text`) leave such a column as no number in any row; only then, and only for
a delimited text file, :func:`date_time_column` reads that one column again as text and parses it as ISO 8601 (a
date, ``T`` or a space, the time of day with any fraction of a second, then ``Z``, ``±hh:mm`` or no zone).  A zone
is applied (stamps converted to UTC), so a change of offset inside the log (a daylight-saving change) is no step
of the clock; stamps without a zone are read as written.  Cells that do not parse are NaN, counted by the
reading's exclusions as non-finite.  A file of plain numbers never reaches this module.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from optcal.data.readers import Source

__all__ = ["ISO_DATE_TIME", "date_time_column", "text_time_column"]

#: An ISO 8601 date-time as loggers write it: the calendar date, ``T`` or a space, hh:mm:ss with any fraction, and
#: a zone (``Z``, ``±hh:mm``, ``±hhmm``, ``±hh``) or none.  A text that is not one (``Wed Dec 22 21:09:46 2021``)
#: leaves the column set aside, as before.
ISO_DATE_TIME = re.compile(
    r"^\s*\d{4}-\d{2}-\d{2}[T ]\d{1,2}:\d{2}:\d{2}(?:[.,]\d+)?\s*(Z|[+-]\d{2}(?::?\d{2})?)?\s*$")


def date_time_column(path: str | Path, name: str, n_rows: int, first: str) -> tuple[NDArray[np.float64], str] | None:
    """The column ``name`` of the delimited text file ``path`` as seconds from its first stamp, and how it was read.

    Parameters
    ----------
    path : str or Path
        A delimited text file whose column ``name`` held no number in any row.
    name : str
        The column's name as the layout gives it (a header name, or its 1-based position).
    n_rows : int
        The data rows the numeric reader read (the parsed column must have as many).
    first : str
        The column's first text (the sample the reader kept): the column is read only when it is an ISO 8601
        date-time (:data:`ISO_DATE_TIME`).

    Returns
    -------
    (ndarray, str) or None
        The seconds (NaN where a cell is no date-time) and the words saying how they were read; ``None`` when the
        column is not date-times or its rows do not align with the numeric reader's (comment lines among them).
    """
    zone = ISO_DATE_TIME.match(first)
    if zone is None:
        return None
    import pandas as pd

    from optcal.data.text import sniff_layout

    layout = sniff_layout(path)
    if name not in layout.names:
        return None
    raw = pd.read_csv(path, sep=r"\s+" if layout.delimiter == " " else layout.delimiter, header=None,
                      usecols=[layout.names.index(name)], skiprows=layout.first_data_line, dtype=str,
                      skip_blank_lines=True, encoding="utf-8-sig", encoding_errors="replace").iloc[:, 0]
    if len(raw) != n_rows:
        return None
    text = raw.str.strip().str.replace(",", ".", regex=False)
    stamps = pd.to_datetime(text, format="ISO8601", utc=True, errors="coerce")
    ns = stamps.to_numpy(dtype="datetime64[ns]").astype(np.int64)
    ok = stamps.notna().to_numpy()
    if not ok.any():
        return None
    # differences in integer nanoseconds before the float: seconds since 1970 in a float lose about 0.2 µs
    seconds = np.where(ok, (ns - ns[np.flatnonzero(ok)[0]]) / 1e9, np.nan)
    how = (f"ISO 8601 date-times such as {first.strip()!r}, "
           + (f"zone {zone.group(1)} applied" if zone.group(1) else "no zone (read as written)")
           + ", in seconds from the first row")
    return seconds.astype(float), how


def text_time_column(src: Source, file_type: str) -> None:
    """Read ``src``'s time column, which holds no number in any row, as date-times, or set it aside (said).

    A delimited text file's column of ISO 8601 date-times (:func:`date_time_column`) becomes the time in seconds
    from its first row, said in :attr:`~optcal.data.readers.Source.time_reason` (``--rate HZ`` times the rows
    instead; ``--columns t=NAME`` names another column).  Any other text (``Wed Dec 22 21:09:46 2021``) is no time
    base: the column is set aside and said (the rate is then needed: ``--rate``), instead of every row dropped as
    non-finite.
    """
    count, row, value = src.non_numeric["t"]
    name = src.column_map["t"]
    parsed = date_time_column(src.path, name, src.n_rows, value) if file_type == "csv" else None
    if parsed is not None:
        src.non_numeric.pop("t")
        src.data["t"], src.time_unit = parsed[0], "s"
        src.time_reason = f"column {name!r} read as {parsed[1]}; --rate HZ times the rows instead"
        return
    src.non_numeric.pop("t")
    src.column_map.pop("t")
    src.data.pop("t")
    src.ignored_columns.append(name)
    src.time_reason = (f"column {name!r} holds no number in any row (text such as {value!r} on data row "
                       f"{row}): not read as the time")
