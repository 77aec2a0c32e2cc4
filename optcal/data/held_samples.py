"""Samples a logger repeats until the sensor's next update: a slower sensor in a faster log.

A logger that writes a row at its fastest sensor's rate repeats a slower sensor's last value until that sensor
updates (AlexMinhao/MagnetometerCali's ``M1.csv``: an AK8963 at about 22 Hz in a 111-Hz log, each magnetometer
triple written on 5 rows, 4 or 6 where the two clocks slip).  Its triples then stay identical over runs whose
lengths follow the rate ratio.  A sensor read afresh on every row repeats its whole triple only where the quantised
noise of all three axes lands on the same codes again; whether a row repeats the last is then independent of how
long the last value has lasted, so the runs' lengths fall off geometrically, ``P(L) = (1 − p) p^(L−1)`` with ``p``
the chance of a repeat, and runs of one row are at least as many as runs of any other length, however coarse the
converter or still the sensor (a still sensor's slow wander only lengthens the runs, it does not make a length
between favoured).  A logger's hold is the opposite: most runs at the ratio, few of one row.  The rule
(:func:`held_runs`) takes the most common run length ``L* ≥ 2`` and asks whether its runs outnumber those of one row
by more than :data:`HOLD_Z` binomial standard deviations (under the geometric model, a run of length 1 or ``L*`` is
of length ``L*`` with a chance of at most one half), and whether more than :data:`RATIO_SHARE` of the runs lie
within one row of ``L*`` (a filtered, oversampled sensor with noise under one code repeats its codes in runs that
are not geometric, but spread over many lengths; a hold's sit at the rate ratio).

A logger that copies the axes of a new update one at a time can write a row between two updates that holds some
axes of the one and some of the other (``M1.csv``'s 16 runs of one row among 1625 of five: ``(31.8, -18.6, 24.0)``,
``(31.8, -20.4, 24.0)``, ``(28.2, -20.4, 25.2)``, y already new, x and z still old).  Such a torn triple is no
sample of the field: a run much shorter than an update (at most half the modal length, where the clocks' slip gives
the modal length ±1) whose every axis reads the previous run's or the next run's value is left out and counted
apart (:attr:`HeldRuns.torn`); a short run with an axis of its own is a sample and is kept.

Counting every row of a held sample weighs it ``L*`` times: a fit's standard errors are then too small by about
``√L*`` (41 % at ``L* = 2``) and its noise model sees steps of zero between rows the sensor never sampled, so a hold
once found is always relevant; the readers keep the first row of each update (the row nearest the time it was
measured) and count the rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["HOLD_Z", "MIN_HELD_RUNS", "RATIO_SHARE", "HeldRuns", "held_rows", "held_runs"]

#: The modal run's excess over the runs of one row, in binomial standard deviations, beyond which the runs are a
#: logger's hold and not a sensor's repeated codes: a one-sided false alarm of about 1e-3 for a sensor read afresh
#: every row (the excess of the most common length among several is taken, so the alarm is somewhat larger; a still,
#: coarse sensor's runs stay geometric and far from it).
HOLD_Z: float = 3.0

#: The share of the runs a hold puts within one row of its modal length, at or below which the runs are a sensor's
#: own repeated codes and not a hold.  A logger writing a sensor that updates at a fixed ratio of its rate repeats
#: each value the ratio's floor or ceiling rows (``circle.txt``: all 148 runs at 5 ± 1); a sensor read afresh on
#: every row spreads its runs over many lengths: geometrically (:func:`held_runs`), or, an accelerometer whose
#: filter's band is a hundredth of the log's rate and whose noise is under one code, so widely that :data:`HOLD_Z`
#: alone is exceeded in about 4 % of simulated still logs, their runs within one row of the mode 8 %.  Half keeps
#: a hold whose clocks slip often and refuses those.  Part of :func:`held_runs`, so the accelerometer's rule
#: (:func:`held_rows`, whose repeats are dropped from every command's samples, an Allan analysis of a still log
#: included) and the magnetometer's (``optcal.families.mag.held.drop_held``) both have it: a still magnetometer
#: so filtered (cut-off 0.005-0.02 of the rate, noise 0.2-0.5 of a 0.15- or 0.3-µT step) passed :data:`HOLD_Z` in
#: 31 of 2400 simulated logs (12 of 200 at worst), within one row of the mode in none.
RATIO_SHARE: float = 0.5


@dataclass(frozen=True)
class HeldRuns:
    """A sensor's values held over several rows of a faster log.

    Attributes
    ----------
    first : ndarray of int
        The first row of each update (indices into the rows given to :func:`held_runs`), torn rows not among them.
    torn : ndarray of int
        The rows of the torn triples (module docstring).
    n_rows : int
        The rows given.
    modal_length : int
        The most common run length (the rate ratio, rounded).
    z : float
        The modal runs' excess over the runs of one row, in binomial standard deviations.
    """

    first: NDArray[np.intp]
    torn: NDArray[np.intp]
    n_rows: int
    modal_length: int
    z: float

    @property
    def n_repeats(self) -> int:
        """Rows that repeat their update's first row."""
        return self.n_rows - int(self.first.size) - int(self.torn.size)

    @property
    def mean_length(self) -> float:
        """Rows per update on average (the log's rate over the sensor's)."""
        return (self.n_rows - int(self.torn.size)) / max(1, int(self.first.size))

    def describe(self, what: str, flag: str, kept: bool = False) -> str:
        """The hold in words: the runs, the rate ratio and what was done (a note of the reading)."""
        head = (f"the {what} repeats each value until its next update (runs of identical triples, most of "
                f"{self.modal_length} rows, {self.mean_length:.3g} on average: a slower sensor in a faster log; a "
                f"sensor read every row would give more runs of one row, {self.z:.1f} binomial SD fewer here)")
        if kept:
            return f"{head}: every row kept ({flag}), so each update weighs about {self.mean_length:.2g} samples"
        torn = (f", and {self.torn.size} rows between two updates holding axes of both (a torn copy, no sample of "
                f"the field)" if self.torn.size else "")
        return (f"{head}: the first row of each update kept, {self.n_repeats} repeated rows left out{torn} "
                f"({flag} keeps them)")


def held_runs(x: NDArray[np.float64]) -> HeldRuns | None:
    """The runs of identical rows of ``x`` when they are a logger's hold (module docstring), else ``None``.

    Parameters
    ----------
    x : ndarray, shape (n, k)
        A sensor's samples, one row each, in the log's order (finite rows only).

    Returns
    -------
    HeldRuns or None
    """
    n = int(x.shape[0])
    if n < 3:
        return None
    change = np.any(x[1:] != x[:-1], axis=1)
    first = np.concatenate(([0], np.flatnonzero(change) + 1))
    lengths = np.diff(np.append(first, n))
    inner = lengths[1:-1]  # the first and last runs may be cut by the log's start and end
    if inner.size == 0:
        return None
    counts = np.bincount(inner)
    mode = int(np.argmax(counts[1:])) + 1
    if mode < 2:
        return None
    n_one, n_mode = int(counts[1]), int(counts[mode])
    z = (n_mode - n_one) / math.sqrt(n_mode + n_one)
    if z <= HOLD_Z:
        return None
    # torn copies: short inner runs each of whose axes reads the previous run's or the next run's value
    short = np.flatnonzero(lengths <= mode // 2)
    short = short[(short > 0) & (short < lengths.size - 1)]
    torn_runs = np.zeros(lengths.size, dtype=bool)
    if short.size:
        here, before, after = x[first[short]], x[first[short - 1]], x[first[short + 1]]
        torn_runs[short] = np.all((here == before) | (here == after), axis=1)
    kept = first[~torn_runs]
    between = np.diff(kept)[1:]  # the runs between updates (a torn copy's rows in the run before it)
    if between.size == 0 or np.mean(np.abs(between - mode) <= 1) <= RATIO_SHARE:
        return None  # the runs spread over many lengths: a sensor's own codes, not a fixed rate ratio (RATIO_SHARE)
    torn = np.concatenate([np.arange(first[k], first[k] + lengths[k]) for k in np.flatnonzero(torn_runs)]
                          or [np.empty(0, dtype=np.intp)])
    return HeldRuns(kept.astype(np.intp), torn.astype(np.intp), n, mode, float(z))


#: The fewest runs of the modal length :data:`HOLD_Z` can call a hold (no run of one row: ``n / √n > 3`` needs
#: ``n ≥ 10``); each such run repeats its whole triple at least once, so a recording whose first axis, and then whose
#: whole triple, repeats its last value on fewer rows holds no sensor's value, and is not searched further (one pass
#: over one axis and a look at the few rows it flags, instead of the triples' runs: a still log of 4.3 M rows written
#: to 1e-6 g repeats its first axis on about a thousand rows by chance, and the runs cost 0.05 s).
MIN_HELD_RUNS: int = 10


def held_rows(x: NDArray[np.float64], usable: NDArray[np.bool_]) -> tuple[NDArray[np.bool_], HeldRuns] | None:
    """The rows of a recording to keep where its sensor ``x`` is held (:func:`held_runs` over its usable rows).

    Parameters
    ----------
    x : ndarray, shape (n, 3)
        A recording's accelerometer (or gyro) samples, one row each, in the log's order.
    usable : ndarray of bool, shape (n,)
        The rows read as samples (finite, ...); the others are kept as they are (counted by the reading).

    Returns
    -------
    (ndarray of bool, HeldRuns) or None
        The rows kept (every unusable row and the first usable row of each update) and the runs; ``None`` when
        the sensor is read afresh on every row.
    """
    every = bool(usable.all())  # the common case: no index of every row to build
    idx = None if every else np.flatnonzero(usable)
    first_axis = x[:, 0] if idx is None else x[idx, 0]
    pairs = np.flatnonzero(first_axis[1:] == first_axis[:-1])  # rows whose first axis repeats the last
    if pairs.size < MIN_HELD_RUNS:
        return None
    before, after = (pairs, pairs + 1) if idx is None else (idx[pairs], idx[pairs + 1])
    if int(np.count_nonzero(np.all(x[after] == x[before], axis=1))) < MIN_HELD_RUNS:
        return None  # whole triples repeated on too few rows for a hold (MIN_HELD_RUNS)
    held = held_runs(x if idx is None else x[idx])
    if held is None:
        return None
    keep = ~usable
    keep[held.first if idx is None else idx[held.first]] = True
    return keep, held
