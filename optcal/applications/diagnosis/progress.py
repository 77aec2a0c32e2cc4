"""Progress of a diagnosis: stage messages and progress bars, silent by default.

The bars are :mod:`optcal.core.progress`'s (tqdm on standard error); whether a command draws
them, or says its stages in words, is the command line's one decision
(:func:`optcal.core.progress.decide`, read here by :meth:`Progress.from_command_line`).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TypeVar

from optcal.core import progress as core_progress

Item = TypeVar("Item")

#: A loop wrapper: ``loop(iterable, description, total)`` yields the items (and may draw a bar).
Loop = Callable[[Iterable[Item], str, int], Iterable[Item]]


def plain_loop(iterable: Iterable[Item], description: str, total: int) -> Iterable[Item]:
    """No bar."""
    return iterable


def _say_on_stderr(text: str) -> None:
    print(f"... {text}", file=sys.stderr)


@dataclass(frozen=True)
class Progress:
    """How a diagnosis reports its progress.

    Attributes
    ----------
    message : callable, optional
        Receives a short message at each stage.
    bars : bool
        Draw a tqdm bar on stderr for every loop and stage that takes more than a second.
    delay : float, optional
        Seconds before a bar appears (a quicker loop draws nothing); :data:`optcal.core.progress.DELAY_S` by default.
    """

    message: Callable[[str], None] | None = None
    bars: bool = False
    delay: float | None = None

    @classmethod
    def from_command_line(cls) -> "Progress":
        """The command line's decision (:mod:`optcal.core.progress`): bars in a terminal, stage
        messages on a standard error that is not one, nothing with ``--quiet`` or ``--json`` into a pipe."""
        return cls(message=_say_on_stderr if core_progress.stages() else None, bars=core_progress.enabled())

    def say(self, text: str) -> None:
        """Pass ``text`` to :attr:`message`, if any."""
        if self.message is not None:
            self.message(text)

    def loop(self, iterable: Iterable[Item], description: str, total: int) -> Iterator[Item]:
        """``iterable``, with a bar when :attr:`bars` (shown only after :attr:`delay`)."""
        return core_progress.progress(iterable, total=total, desc=description, enabled=self.bars, delay=self.delay)

    @contextmanager
    def stage(self, description: str) -> Iterator[None]:
        """A stage that is one call (e.g. the baseline fit): its message, and a bar with the elapsed time when slow."""
        self.say(description)
        with core_progress.stage(description, enabled=self.bars, delay=self.delay):
            yield
