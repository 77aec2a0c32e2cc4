"""Where commands write: ``--json``, ``-o FILE`` and ``--plot PATH``, the same in every command.

``--json`` prints exactly one JSON object on standard output (:func:`echo_json`: NumPy values
made plain, a number that is not finite written as ``null``).

``--plot PATH`` takes a folder in every command (created when missing); the figures are
written into it under their own names (``segments.png``, ``allan.png``, the diagnosis
figures).  Commands that draw one figure also take a file name with a figure suffix
(``--plot seg.png``).  ``-o FILE`` creates its folder when missing.  A path that cannot
be written (an existing folder given as a file, a file given as a folder) is one error line.

Every output is written whole or not at all (:func:`writing`, :mod:`optcal.core.atomic`): a
temporary file beside it, renamed when complete; a read-only folder or a full disk is one
``error:`` line naming the path and the reason (exit 2) and leaves no file behind.  An output
that is one of the command's input files is refused before the command does any work
(:func:`refuse_outputs_over_inputs`, run by the ``optcal`` group on every command's parsed
arguments) and again where the file is written.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from optcal.errors import InputError

#: The parameters of a command that name what it writes; every other parameter naming an existing
#: file is an input, which an output must not overwrite.
OUTPUT_PARAMS: frozenset[str] = frozenset({"output", "report_path", "plot_path", "plot", "plot_dir"})

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
    refuse_input(p, option)
    return p


def _inputs() -> list[str]:
    """The files the running command reads: its parameters' values other than :data:`OUTPUT_PARAMS`."""
    context = click.get_current_context(silent=True)
    if context is None:
        return []
    found: list[str] = []
    for name, value in context.params.items():
        values = value if isinstance(value, (tuple, list)) else (value,)
        if name not in OUTPUT_PARAMS:
            found += [str(v) for v in values if isinstance(v, (str, Path)) and str(v)]
    return found


def _same_file(a: str | Path, b: str | Path) -> bool:
    """Whether ``a`` and ``b`` are one existing file: the same device and inode, which follows
    symbolic links and sees hard links and other spellings of the path (``./x``, ``d/../x``).

    An output that does not exist yet is no input, whatever its spelling."""
    try:
        return os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b)
    except OSError:
        return False


def refuse_outputs_over_inputs(context: click.Context) -> None:
    """Refuse, before any work, a command whose output path is one of its inputs.

    Every parameter in :data:`OUTPUT_PARAMS` with a value is compared with every other
    parameter naming an existing file (:func:`_same_file`); the ``optcal`` group calls this on
    the command's parsed arguments, before the command reads or fits anything.

    Parameters
    ----------
    context : click.Context
        The command's context (its ``params`` parsed).

    Raises
    ------
    InputError
        One line naming the flag, the output and the input it would have replaced.
    """
    flags = {p.name: (p.opts[0] if p.opts else p.name) for p in context.command.params}
    inputs: list[str] = []
    for name, value in context.params.items():
        if name not in OUTPUT_PARAMS:
            values = value if isinstance(value, (tuple, list)) else (value,)
            inputs += [str(v) for v in values if isinstance(v, (str, Path)) and str(v) and os.path.isfile(v)]
    for name in OUTPUT_PARAMS:
        value = context.params.get(name)
        if not isinstance(value, (str, Path)) or not str(value):
            continue
        for given in inputs:
            if _same_file(given, value):
                raise InputError(f"{flags.get(name, name)} {value}: is the input {given}; writing it would destroy "
                                 "the input: give another output file")


def refuse_input(path: Path, option: str = "-o") -> None:
    """Refuse to write ``path`` when it is one of the command's inputs (the same file, by device and inode).

    Raises
    ------
    InputError
        Naming the input and the option that would have replaced it.
    """
    if not path.exists():
        return
    for given in _inputs():
        if _same_file(given, path):
            raise InputError(f"{option} {path}: is the input {given}; writing it would destroy the input: "
                             "give another output file")


@contextmanager
def writing(path: str | Path, option: str = "-o") -> Iterator[Path]:
    """The temporary file to write an output to; it becomes ``path`` when the block completes.

    ``path``'s folder is created when missing (:func:`output_file`), an input of the command
    is refused, and a write that fails (read-only folder, full disk) is one
    :class:`~optcal.errors.InputError` naming the path and the reason, with nothing left behind.

    Parameters
    ----------
    path : str or Path
    option : str
        The flag that named the path (``-o``, ``--report``, ``--plot``), for the messages.
    """
    from optcal.core.atomic import atomic_path

    target = output_file(path, option)
    try:
        with atomic_path(target) as tmp:
            yield tmp
    except OSError as exc:
        raise InputError(f"{option} {target}: cannot write: {exc.strerror or exc}") from None


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
