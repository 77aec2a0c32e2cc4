"""Progress of a diagnosis: stage messages and progress bars (tqdm, on stderr), silent by default."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TypeVar

Item = TypeVar("Item")

#: A loop wrapper: ``loop(iterable, description, total)`` yields the items (and may draw a bar).
Loop = Callable[[Iterable[Item], str, int], Iterable[Item]]


def plain_loop(iterable: Iterable[Item], description: str, total: int) -> Iterable[Item]:
    """No bar."""
    return iterable


@dataclass(frozen=True)
class Progress:
    """How a diagnosis reports its progress.

    Attributes
    ----------
    message : callable, optional
        Receives a short message at each stage.
    bars : bool
        Draw a tqdm bar on stderr for every loop and stage that takes more than a second.
    delay : float
        Seconds before a bar appears (a quicker loop draws nothing).
    """

    message: Callable[[str], None] | None = None
    bars: bool = False
    delay: float = 1.0

    @classmethod
    def for_terminal(cls, quiet: bool) -> "Progress":
        """Messages and bars on stderr, unless ``quiet`` or stderr is not a terminal (bars only then)."""
        if quiet:
            return cls()
        interactive = sys.stderr.isatty()
        return cls(message=None if interactive else (lambda text: print(f"... {text}", file=sys.stderr)),
                   bars=interactive)

    def say(self, text: str) -> None:
        if self.message is not None:
            self.message(text)

    def loop(self, iterable: Iterable[Item], description: str, total: int) -> Iterator[Item]:
        """``iterable``, with a bar when :attr:`bars` (shown only after a second)."""
        if not self.bars:
            yield from iterable
            return
        from tqdm import tqdm

        yield from tqdm(iterable, desc=description, total=total, file=sys.stderr, leave=False, delay=self.delay,
                        mininterval=0.5, dynamic_ncols=True)

    @contextmanager
    def stage(self, description: str) -> Iterator[None]:
        """A stage that is one call (e.g. the baseline fit): its message, and a bar with the elapsed time when slow."""
        self.say(description)
        if not self.bars:
            yield
            return
        from tqdm import tqdm

        with tqdm(total=1, desc=description, file=sys.stderr, leave=False, delay=self.delay,
                  bar_format="{desc}: {elapsed}", dynamic_ncols=True) as bar:
            yield
            bar.update(1)
