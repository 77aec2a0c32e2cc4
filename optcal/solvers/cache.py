"""One factory for the caches of built optimisation problems: bounded, least recently used, thread-safe.

Building a CasADi NLP (an SX graph and its derivatives) or a cvxpy problem costs far more than
solving it, so each estimator builds its problem once per shape and options and re-solves it with
new data.  Every such cache is made by :func:`problem_cache`: at most ``maxsize`` problems, the
least recently used dropped first, one lock around look-up and build (two threads asking for the
same problem build it once).  The problems themselves hold no data between solves and guard
each solve with their own lock (a CasADi ``nlpsol`` keeps the statistics of its last call, a
cvxpy problem its parameter values and solution: solving and reading the outcome are one step),
so two threads calibrating at once never see each other's data.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Mapping
from typing import Any, Generic, TypeVar

from optcal.errors import InputError

Problem = TypeVar("Problem")
#: An options mapping frozen into a hashable, order-independent key.
FrozenOptions = tuple[tuple[str, Any], ...]


def freeze_options(options: Mapping[str, Any] | None) -> FrozenOptions:
    """``{"ipopt.tol": 1e-9}`` → ``(("ipopt.tol", 1e-9),)``, sorted, for a cache key."""
    frozen = tuple(sorted((options or {}).items()))
    try:
        hash(frozen)
    except TypeError as exc:
        raise InputError(f"solver options must have hashable values (numbers, strings, tuples): {exc}") from exc
    return frozen


class ProblemCache(Generic[Problem]):
    """Built problems keyed by their shape and options (see :func:`problem_cache`)."""

    def __init__(self, build: Callable[..., Problem], maxsize: int) -> None:
        if maxsize < 1:
            raise ValueError("maxsize must be at least 1")
        self._build = build
        self.maxsize = int(maxsize)
        self._items: OrderedDict[tuple[Hashable, ...], Problem] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, *key: Hashable) -> Problem:
        """The problem ``build(*key)``, built on first use; the least recently used is evicted beyond ``maxsize``."""
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
            problem = self._build(*key)
            self._items[key] = problem
            while len(self._items) > self.maxsize:
                self._items.popitem(last=False)
            return problem

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def clear(self) -> None:
        """Drop every built problem."""
        with self._lock:
            self._items.clear()


def problem_cache(build: Callable[..., Problem], maxsize: int) -> ProblemCache[Problem]:
    """A bounded, thread-safe LRU cache of problems made by ``build(*key)``.

    Parameters
    ----------
    build : callable
        Builds the problem from the key's parts (e.g. ``(n, loss, frozen_options)``); options
        go in frozen by :func:`freeze_options`.
    maxsize : int
        How many built problems to keep.
    """
    return ProblemCache(build, maxsize)


__all__ = ["FrozenOptions", "ProblemCache", "freeze_options", "problem_cache"]
