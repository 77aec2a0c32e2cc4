"""Where commands write: ``--json``, ``-o FILE`` and ``--plot PATH``, the same in every command.

``--json`` prints exactly one JSON object on standard output (:func:`echo_json`: NumPy values
made plain, a number that is not finite written as ``null``).

``--plot PATH`` takes a folder in every command (created when missing); the figures are
written into it under their own names (``segments.png``, ``allan.png``, the diagnosis
figures).  Commands that draw one figure also take a file name with a figure suffix
(``--plot seg.png``).  ``-o FILE`` creates its folder when missing.  A path that cannot
be written (an existing folder given as a file, a file given as a folder) is one error line.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from optcal.errors import InputError

#: Suffixes that make ``--plot PATH`` a file name rather than a folder.
FIGURE_SUFFIXES: tuple[str, ...] = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def echo_json(obj: dict[str, Any]) -> None:
    """Print exactly one JSON object on standard output.

    Parameters
    ----------
    obj : dict
        The command's result; NumPy arrays and scalars are converted and a number that is not
        finite becomes ``null`` (:func:`optcal.core.jsonio.json_text`).
    """
    from optcal.core.jsonio import json_text

    click.echo(json_text(obj))


def plot_option(what: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The ``--plot PATH`` option (see the module docstring); ``what`` describes the figures."""
    return click.option(
        "--plot", "plot_path", type=click.Path(), default=None, metavar="PATH",
        help=f"Write {what} into the folder PATH (created when missing), or to PATH itself when it ends in "
             ".png, .pdf or .svg.",
    )


def output_file(path: str | Path, option: str = "-o") -> Path:
    """A file to write: its folder created when missing; an existing folder is refused."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{option} {p}: is a folder; give a file name (e.g. {p / 'out.json'})")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError) as exc:
        raise InputError(f"{option} {p}: cannot create its folder {p.parent} (a file of that name exists)") from exc
    except PermissionError as exc:
        raise InputError(f"{option} {p}: no permission to create the folder {p.parent}") from exc
    return p


def plot_file(plot_path: str | Path, name: str) -> Path:
    """The file one figure is written to: ``plot_path`` itself for a figure file name, else ``plot_path/name``."""
    p = Path(plot_path)
    if p.suffix.lower() in FIGURE_SUFFIXES and not p.is_dir():
        return output_file(p, "--plot")
    return output_file(p / name, "--plot")


def plot_folder(plot_path: str | Path) -> Path:
    """The folder several figures are written into (created when missing)."""
    p = Path(plot_path)
    if p.suffix.lower() in FIGURE_SUFFIXES and not p.is_dir():
        raise InputError(f"--plot {p}: this command writes several figures; give a folder")
    if p.exists() and not p.is_dir():
        raise InputError(f"--plot {p}: is a file; give a folder for the figures")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError) as exc:
        raise InputError(f"--plot {p}: cannot create the folder (a file is in the way)") from exc
    except PermissionError as exc:
        raise InputError(f"--plot {p}: no permission to create the folder") from exc
    return p
