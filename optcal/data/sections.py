"""Named sections of a recording: imucal's section list and a label column (``part``).

imucal (mad-lab-fau/imucal, ``imucal/ferraris_calibration.py``) marks the nine stretches of a
Ferraris session in two ways, both read here:

* a **section list**: for each section name its ``start`` and ``end`` sample, taken as
  ``data.iloc[start:end]`` (``_convert_data_from_section_list_to_df``), i.e. 0-based data rows,
  ``end`` exclusive.  imucal's example stores it as JSON, one object per section
  (``{"x_p": {"start": 540, "end": 1271}, ...}``, read by ``pd.read_json(...).T``); pandas'
  own ``to_json`` of the frame gives the transposed form (``{"start": {"x_p": 540}, ...}``) and
  ``to_csv`` a table ``,start,end``.  All three are read.
* a **label column** naming the section of every row (``ferraris_regions_from_df``: the frame's
  index level 0; imucal's ``annotated_session.csv`` calls it ``part``).

:data:`SECTION_NAMES` are imucal's ``FerrarisCalibration.FERRARIS_SECTIONS``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError

__all__ = ["FACE_NAMES", "LABEL_COLUMNS", "SECTION_NAMES", "TURN_NAMES", "label_column_of", "read_label_column",
           "read_section_list"]

#: The six static faces of a Ferraris session: ``x_p`` has +x up (the x accelerometer reads +1 g), ``x_a``
#: −x up (imucal, ``FerrarisCalibration`` docstring).
FACE_NAMES: tuple[str, ...] = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")
#: The three turns about the x, y and z axes (imucal: ``x_rot`` is done in the ``x_p`` position).
TURN_NAMES: tuple[str, ...] = ("x_rot", "y_rot", "z_rot")
#: imucal's ``FERRARIS_SECTIONS``.
SECTION_NAMES: tuple[str, ...] = FACE_NAMES + TURN_NAMES
#: Names of a column that labels each row with its section (imucal's annotated session: ``part``).
LABEL_COLUMNS: tuple[str, ...] = ("part", "section")


def _as_int(value: Any, where: str) -> int:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {value!r} is not a sample number") from None
    if not np.isfinite(number) or number != round(number) or number < 0:
        raise InputError(f"{where}: {value!r} is not a sample number (a whole number ≥ 0)")
    return int(number)


def _from_mapping(d: dict[str, Any], path: str) -> dict[str, tuple[int, int]]:
    if set(d) >= {"start", "end"} and isinstance(d["start"], dict):  # pandas' to_json of the frame: by column
        d = {name: {"start": d["start"][name], "end": d["end"].get(name)} for name in d["start"]}
    out: dict[str, tuple[int, int]] = {}
    for name, entry in d.items():
        if not isinstance(entry, dict) or "start" not in entry or "end" not in entry:
            raise InputError(f"{path}: section {name!r} needs a start and an end sample (imucal's section list)")
        out[str(name)] = (_as_int(entry["start"], f"{path}: {name}.start"), _as_int(entry["end"], f"{path}: {name}.end"))
    return out


def read_section_list(path: str | Path) -> dict[str, tuple[int, int]]:
    """imucal's section list: section name → (start, end) data rows, 0-based, end exclusive.

    Parameters
    ----------
    path : str or Path
        JSON (either orientation pandas writes) or CSV (``name,start,end``).

    Raises
    ------
    InputError
        Unreadable, a section without start/end, an end not after its start, a name outside
        :data:`SECTION_NAMES`.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"{p}: cannot read the section list ({exc.strerror})") from exc
    sections: dict[str, tuple[int, int]]
    if text.lstrip().startswith("{"):
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"{p}: not valid JSON ({exc.msg} at line {exc.lineno})") from exc
        sections = _from_mapping(d, str(p))
    else:  # imucal: section_list.to_csv(...), read back with index_col=0
        lines = [ln.split(",") for ln in text.splitlines() if ln.strip()]
        if not lines or [c.strip() for c in lines[0][1:3]] != ["start", "end"]:
            raise InputError(f"{p}: a section list is JSON or a CSV with the columns ,start,end (imucal's section_list)")
        sections = {}
        for k, cells in enumerate(lines[1:], start=2):
            if len(cells) < 3:
                raise InputError(f"{p}: line {k} has fewer than three fields (name,start,end)")
            sections[cells[0].strip()] = (_as_int(cells[1], f"{p}: line {k}"), _as_int(cells[2], f"{p}: line {k}"))
    unknown = sorted(set(sections) - set(SECTION_NAMES))
    if unknown:
        raise InputError(f"{p}: unknown section(s) {', '.join(unknown)}; imucal's sections are {', '.join(SECTION_NAMES)}")
    for name, (start, end) in sections.items():
        if end <= start:
            raise InputError(f"{p}: section {name} ends (sample {end}) before it starts (sample {start})")
    return sections


def label_column_of(ignored_columns: list[str]) -> str | None:
    """The column among a file's non-numeric ones that labels the sections (:data:`LABEL_COLUMNS`), if any."""
    for name in ignored_columns:
        if name.strip().lower() in LABEL_COLUMNS:
            return name
    return None


def read_label_column(path: str | Path, name: str) -> NDArray[np.str_]:
    """The text of column ``name`` on every data row of a delimited text file (empty cells: ``""``).

    The numeric columns are read by :mod:`optcal.data.readers`; a label column is text, so it is
    read here, on its own, when a section label is needed.
    """
    from optcal.data.text import read_frame

    frame, _ = read_frame(path)
    if name not in frame.columns:
        raise InputError(f"{path}: no column {name!r}")
    return np.asarray(frame[name].fillna("").astype(str).str.strip().to_numpy(), dtype=str)
