"""``--quiet``, the option of every command that does long work, and the one decision on progress.

The option only records the wish; :func:`decide_progress`, called on every command's parsed
arguments (:func:`optcal.cli.main._before_command`), makes the decision from it, the global
``optcal -q`` and ``--json`` (:func:`optcal.core.progress.decide`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

__all__ = ["decide_progress", "quiet_option"]

HELP = "No progress on standard error (bars in a terminal, stage messages otherwise); the same as 'optcal -q COMMAND'."


def _remember(context: click.Context, _param: click.Parameter, value: bool) -> None:
    root = context.find_root().obj
    if value and isinstance(root, dict):
        root["quiet"] = True  # where the global -q is kept (optcal.cli.main.cli)


def quiet_option(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding ``-q/--quiet`` to a command (not passed to its function).

    Parameters
    ----------
    func : callable
        The command's function.

    Returns
    -------
    callable
    """
    return click.option("-q", "--quiet", is_flag=True, expose_value=False, callback=_remember, help=HELP)(func)


def decide_progress(context: click.Context) -> None:
    """The one decision on progress, from a command's parsed arguments: bars when standard error is a
    terminal, stage messages when it is not, neither with ``--quiet`` (the command's or ``optcal -q``)
    or with ``--json`` into a pipe (:func:`optcal.core.progress.decide`, :func:`~optcal.core.progress.decide_stages`)."""
    from optcal.core import progress

    root = context.find_root().obj
    quiet = bool(context.params.get("quiet")) or bool(isinstance(root, dict) and root.get("quiet"))
    as_json = bool(context.params.get("as_json"))
    progress.set_enabled(progress.decide(quiet, as_json), progress.decide_stages(quiet, as_json))
