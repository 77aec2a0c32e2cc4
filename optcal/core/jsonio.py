"""The one JSON writer and reader of optcal: files, ``--json`` objects, the file format version.

Every JSON that optcal writes goes through :func:`jsonable` (NumPy arrays and scalars made plain,
a number that is not finite written as ``null``) and :func:`json.dumps` with ``allow_nan=False``,
so that what is written is strict JSON (RFC 8259 has no NaN or Infinity):

* :func:`write_json` writes a file: indented by 2, one trailing newline (calibration files,
  saved results);
* :func:`json_text` is the one-line form that ``--json`` prints on standard output.

:func:`read_json` reads a file back, with one clear :class:`~optcal.errors.InputError` for a
missing file, a file that is not JSON and JSON that is not an object.

Calibration files carry a semantic ``format_version`` (``MAJOR.MINOR``): a reader accepts every
minor version of its major version (minor versions only add optional fields) and refuses a newer
major version (:func:`check_version`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from optcal.errors import InputError

#: Major version of the calibration file format written by this optcal.
FORMAT_MAJOR: int = 2
#: Version string written into every calibration file.
FORMAT_VERSION: str = f"{FORMAT_MAJOR}.0"


def jsonable(x: Any) -> Any:
    """``x`` with NumPy values made plain and non-finite floats made ``None``, for :func:`json.dumps`.

    Parameters
    ----------
    x : Any
        Dictionaries (keys become strings), lists, tuples (become lists), NumPy arrays (become
        nested lists), NumPy and Python scalars; anything else is returned as it is.

    Returns
    -------
    Any
        The same structure, made of ``dict``, ``list``, ``str``, ``int``, ``float``, ``bool`` and ``None``.
    """
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def json_text(obj: Any) -> str:
    """``obj`` as one line of strict JSON (what ``--json`` prints).

    Parameters
    ----------
    obj : Any
        Anything :func:`jsonable` converts.

    Returns
    -------
    str
        The JSON text, without a trailing newline.
    """
    return json.dumps(jsonable(obj), allow_nan=False)


def write_json(path: str | Path, obj: Any) -> None:
    """Write ``obj`` to ``path`` as strict JSON, indented by 2, with one trailing newline.

    Parameters
    ----------
    path : str or Path
        The file to write (replaced when it exists).
    obj : Any
        Anything :func:`jsonable` converts.
    """
    from optcal.core.atomic import write_text_atomic

    write_text_atomic(path, json.dumps(jsonable(obj), indent=2, allow_nan=False) + "\n")  # whole or not at all


def read_json(path: str | Path, what: str = "calibration file", hint: str = "") -> dict[str, Any]:
    """The JSON object of a file, with one clear error for a missing or broken file.

    Parameters
    ----------
    path : str or Path
        The file to read.
    what : str
        What the file should be, for the messages (``"calibration file"``, ``"Allan result file"``).
    hint : str
        How to make a good file, added to the message for a file that is not JSON.

    Returns
    -------
    dict
        The file's JSON object.

    Raises
    ------
    InputError
        ``"<path>: no such <what>"``, ``"<path>: not a JSON <what> (<parser message>)"`` or
        ``"<path>: not an optcal <what> (not a JSON object)"``.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such {what}")
    try:
        d = json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: not a JSON {what} ({exc})" + (f"; {hint}" if hint else "")) from exc
    if not isinstance(d, dict):
        raise InputError(f"{p}: not an optcal {what} (not a JSON object)")
    return d


def parse_version(version: Any) -> tuple[int, int]:
    """``"2.0"`` → ``(2, 0)``; a bare integer (format 1 files wrote ``1``) → ``(1, 0)``.

    Raises
    ------
    InputError
        ``version`` is not a version number.
    """
    if isinstance(version, bool):
        raise InputError(f"format_version {version!r} is not a version number like \"2.0\"")
    if isinstance(version, int):
        return version, 0
    parts = str(version).split(".")
    try:
        major = int(parts[0])
        minor = int(parts[1]) if len(parts) > 1 else 0
    except ValueError as exc:
        raise InputError(f"format_version {version!r} is not a version number like \"2.0\"") from exc
    return major, minor


def check_version(version: Any) -> tuple[int, int]:
    """Parse ``version`` (:func:`parse_version`) and refuse a major version newer than :data:`FORMAT_MAJOR`.

    Raises
    ------
    InputError
        A newer major version, a version below 1, or not a version number.
    """
    major, minor = parse_version(version)
    if major > FORMAT_MAJOR:
        raise InputError(
            f"the calibration file has format version {version}, newer than this optcal reads "
            f"({FORMAT_MAJOR}.x and older); upgrade optcal to read it"
        )
    if major < 1:
        raise InputError(f"the calibration file has format version {version}; optcal files start at version 1")
    return major, minor


__all__ = ["FORMAT_MAJOR", "FORMAT_VERSION", "check_version", "json_text", "jsonable", "parse_version", "read_json",
           "write_json"]
