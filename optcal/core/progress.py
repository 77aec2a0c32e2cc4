"""Progress bars for long work: one helper, silent unless the command line turned it on.

Library calls draw nothing by default.  The ``optcal`` command decides once, from its
arguments, whether bars are wanted (:func:`decide`: standard error is a terminal, no
``--quiet``, and not ``--json`` into a pipe) and sets it with :func:`set_enabled`; every long
loop then goes through :func:`progress`, which draws a tqdm bar on standard error only when
the loop outlasts :data:`DELAY_S`.  The bar never touches standard output, so the outputs are
the same with and without it.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator
from typing import TypeVar

__all__ = ["DELAY_S", "decide", "enabled", "progress", "set_enabled"]

Item = TypeVar("Item")

#: Seconds before a bar appears: a loop quicker than this draws nothing (no flicker on small files).
DELAY_S: float = 1.0

_ENABLED: bool = False


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
    stderr_tty = bool(getattr(sys.stderr, "isatty", lambda: False)())
    stdout_tty = bool(getattr(sys.stdout, "isatty", lambda: False)())
    return stderr_tty and not quiet and not (as_json and not stdout_tty)


def set_enabled(flag: bool) -> None:
    """Turn the bars of :func:`progress` on or off for the process (the command line's decision).

    Parameters
    ----------
    flag : bool
    """
    global _ENABLED
    _ENABLED = bool(flag)


def enabled() -> bool:
    """Whether :func:`progress` draws bars when not told otherwise.

    Returns
    -------
    bool
    """
    return _ENABLED


def progress(iterable: Iterable[Item], total: float | None = None, desc: str = "", enabled: bool | None = None,
             unit: str = "it", scale: bool = False, size: Callable[[Item], float] | None = None) -> Iterator[Item]:
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

    Yields
    ------
    object
        The items of ``iterable``, unchanged.
    """
    if not (_ENABLED if enabled is None else enabled):
        yield from iterable
        return
    from tqdm import tqdm

    options = dict(total=total, desc=desc, file=sys.stderr, leave=False, delay=DELAY_S, mininterval=0.5,
                   dynamic_ncols=True, unit=unit, unit_scale=scale)
    if size is None:
        yield from tqdm(iterable, **options)
        return
    with tqdm(**options) as bar:
        for item in iterable:
            yield item
            bar.update(size(item))
