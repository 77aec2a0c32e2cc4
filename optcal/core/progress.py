"""Progress bars for long work: one helper, silent unless the command line turned it on.

Library calls draw nothing by default.  The ``optcal`` command decides once, from its
arguments, whether bars are wanted (:func:`decide`: standard error is a terminal, no
``--quiet``, and not ``--json`` into a pipe) and sets it with :func:`set_enabled`; every long
loop then goes through :func:`progress`, and every long single call through :func:`stage`,
which draw a tqdm bar on standard error only when the work outlasts :data:`DELAY_S`.  Where
standard error is not a terminal (a log file) a bar would be one long line of carriage
returns, so long work may say its stages in words instead (:func:`decide_stages`, read with
:func:`stages`), under the same ``--quiet`` and ``--json`` rules.  Nothing here touches
standard output, so the outputs are the same with and without progress.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

__all__ = ["DELAY_S", "decide", "decide_stages", "enabled", "progress", "set_enabled", "stage", "stages"]

Item = TypeVar("Item")

#: Seconds before a bar appears: a loop quicker than this draws nothing (no flicker on small files).
DELAY_S: float = 1.0

_ENABLED: bool = False
_STAGES: bool = False


def decide(quiet: bool, as_json: bool) -> bool:
    """Whether the command line draws bars: standard error is a terminal, not ``--quiet``, and
    not ``--json`` with standard output a pipe (a script reading the JSON wants a quiet stderr).

    Parameters
    ----------
    quiet : bool
        ``--quiet`` given (globally or to the command).
    as_json : bool
        ``--json`` given.

    Returns
    -------
    bool
    """
    return _isatty(sys.stderr) and _wanted(quiet, as_json)


def decide_stages(quiet: bool, as_json: bool) -> bool:
    """Whether long work says its stages in words on standard error: it is not a terminal (where
    :func:`decide` draws bars instead), not ``--quiet``, and not ``--json`` into a pipe.

    Parameters
    ----------
    quiet : bool
        ``--quiet`` given (globally or to the command).
    as_json : bool
        ``--json`` given.

    Returns
    -------
    bool
    """
    return not _isatty(sys.stderr) and _wanted(quiet, as_json)


#: Columns and rows assumed of a terminal that states no size (a pseudo-terminal opened without one,
#: as ``script`` or ``docker exec -t`` give): tqdm follows its 0 × 0 and draws nothing (0 columns, and a
#: bar at row 0 of 0 rows is "hidden").
FALLBACK_SIZE: tuple[int, int] = (80, 24)


def _width() -> dict[str, Any]:
    """tqdm's size options: follow the terminal's width, or :data:`FALLBACK_SIZE` where it states none."""
    try:
        size = os.get_terminal_size(sys.stderr.fileno())
    except (AttributeError, OSError, ValueError):  # not a real file (a test's capture): tqdm's own defaults
        return {"dynamic_ncols": True}
    options: dict[str, Any] = {"ncols": FALLBACK_SIZE[0]} if size.columns == 0 else {"dynamic_ncols": True}
    if size.lines == 0:
        options["nrows"] = FALLBACK_SIZE[1]
    return options


def _isatty(stream: Any) -> bool:
    return bool(getattr(stream, "isatty", lambda: False)())


def _wanted(quiet: bool, as_json: bool) -> bool:
    """Progress of any kind is wanted: not ``--quiet``, and not ``--json`` read by a program (standard output not a terminal)."""
    return not quiet and not (as_json and not _isatty(sys.stdout))


def set_enabled(flag: bool, stages: bool = False) -> None:
    """Turn the bars of :func:`progress` and :func:`stage` (and the stages said in words) on or off
    for the process (the command line's decision, :func:`decide` and :func:`decide_stages`).

    Parameters
    ----------
    flag : bool
        Draw bars.
    stages : bool
        Say the stages of long work in words (where no bar is drawn).
    """
    global _ENABLED, _STAGES
    _ENABLED = bool(flag)
    _STAGES = bool(stages)


def stages() -> bool:
    """Whether long work says its stages in words (the command line's :func:`decide_stages`).

    Returns
    -------
    bool
    """
    return _STAGES


def enabled() -> bool:
    """Whether :func:`progress` draws bars when not told otherwise.

    Returns
    -------
    bool
    """
    return _ENABLED


def progress(iterable: Iterable[Item], total: float | None = None, desc: str = "", enabled: bool | None = None,
             unit: str = "it", scale: bool = False, size: Callable[[Item], float] | None = None,
             delay: float | None = None) -> Iterator[Item]:
    """``iterable``'s items, with a tqdm bar on standard error when enabled.

    Parameters
    ----------
    iterable : iterable
        The work.
    total : float, optional
        Number of items (or of ``unit`` when the caller updates by amounts), for the bar's length.
    desc : str
        What is being done, shown before the bar.
    enabled : bool, optional
        Draw the bar; by default the command line's decision (:func:`set_enabled`), off in a library call.
    unit : str
        What one step counts (``"it"``, ``"B"`` for bytes).
    scale : bool
        Show the counts with SI prefixes (bytes, rows).
    size : callable, optional
        How many ``unit`` an item is (the rows of a block read); one each by default.
    delay : float, optional
        Seconds before the bar appears; :data:`DELAY_S` by default.

    Yields
    ------
    object
        The items of ``iterable``, unchanged.
    """
    if not (_ENABLED if enabled is None else enabled):
        yield from iterable
        return
    from tqdm import tqdm

    options = dict(total=total, desc=desc, file=sys.stderr, leave=False, delay=DELAY_S if delay is None else delay,
                   mininterval=0.5, unit=unit, unit_scale=scale, **_width())
    if size is None:
        yield from tqdm(iterable, **options)
        return
    with tqdm(**options) as bar:
        for item in iterable:
            yield item
            bar.update(size(item))


@contextmanager
def stage(desc: str, enabled: bool | None = None, delay: float | None = None) -> Iterator[None]:
    """A long piece of work that is one call (a fit): a bar with its elapsed time on standard
    error when enabled and slower than the delay.

    Parameters
    ----------
    desc : str
        What is being done.
    enabled : bool, optional
        Draw the bar; by default the command line's decision (:func:`set_enabled`).
    delay : float, optional
        Seconds before the bar appears; :data:`DELAY_S` by default.

    Yields
    ------
    None
    """
    if not (_ENABLED if enabled is None else enabled):
        yield
        return
    from tqdm import tqdm

    with tqdm(total=1, desc=desc, file=sys.stderr, leave=False, delay=DELAY_S if delay is None else delay,
              bar_format="{desc}: {elapsed}", **_width()) as bar:
        yield
        bar.update(1)
