"""A time or sample-counter column that runs backwards: refused, or explained by the file's labelled sections.

Moved from :mod:`optcal.data.decisions` (the time base's decision calls both).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.data.evidence import Evidence
from optcal.data.readers import Source
from optcal.errors import InputError


def refuse_backwards(src: Source, ev: Evidence, t: NDArray[np.float64], what: str) -> None:
    """Refuse a time (or sample index) column that runs backwards among the usable rows."""
    rows = np.flatnonzero(ev.usable & np.isfinite(t))
    back = np.flatnonzero(np.diff(t[rows]) < 0)
    if back.size:
        i, j = rows[back[0]], rows[back[0] + 1]
        raise InputError(
            f"{src.path}: {what} runs backwards at data row {j + 1} ({t[j]:.6g} after "
            f"{t[i]:.6g} on row {i + 1}; {back.size} such step(s)); the file may be several "
            "logs joined together: split or sort it"
        )


def sections_explain_backwards(src: Source, ev: Evidence, counter: NDArray[np.float64]) -> str | None:
    """Why a sample counter that runs backwards is no reason to refuse the file, or ``None``.

    A file of labelled sections (imucal's annotated session: a ``part`` column names the section
    of each row, and the rows are grouped by section) keeps each section's sample numbers: the
    counter steps back where one section ends and the next begins.  When every step back falls on
    a change of the label, the counter is a sample number, not time; the time is the row number
    over the rate, and the sections are read by their label.
    """
    from optcal.data.sections import label_column_of, read_label_column

    rows = np.flatnonzero(ev.usable & np.isfinite(counter))
    back = np.flatnonzero(np.diff(counter[rows]) < 0)
    name = label_column_of(src.ignored_columns)
    if not back.size or name is None or src.file_type != "csv":
        return None
    labels = read_label_column(src.path, name)
    if labels.size != counter.size:
        return None
    before, after = rows[back], rows[back + 1]
    if not np.all(labels[before] != labels[after]):
        return None
    return (f"a sample counter; it steps back {back.size} time(s), each where the section in column {name!r} "
            "changes: sections stored by label, not time")
