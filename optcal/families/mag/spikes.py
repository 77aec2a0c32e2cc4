"""A magnetometer's isolated spikes: samples no turning field could read between their neighbours.

A bus glitch, a torn register read or a motor's pulse gives a magnetometer a sample far from the field
(AlexMinhao/MagnetometerCali's ``M1.csv``: two rows of |m| ≈ 152 µT in a 30–50 µT log, one axis each, which set the
fit's rms at 15.5 % against 7.4 % without them).  The field the sensor reads is the Earth's, turned by the sensor's
attitude and shifted by its hard iron: between two samples it moves along the sphere (ellipsoid) of the field, by
at most the chord a turn at the sensor's largest rate sweeps in the time between them.  A spike is a run of one to
:data:`MAX_SPIKE_ROWS` rows that

1. **leaves both neighbours by more than a turning field can move** between them: each of its rows is farther from
   the row before the run and from the row after it than the chord ``D sin(min(ω Δt, π)/2)`` of a field of diameter
   ``D`` turning at :data:`HAND_TURN_RATE` over the time ``Δt`` between those two neighbours (:func:`turn_reach`).
   ``D`` is the larger of twice the median |m| (the field and its hard iron: no true sample lies farther than that
   from another on a sphere about an offset at most as long as the field, and a larger offset only makes it
   larger) and the largest axis's range over the central 99 % of the samples (the ellipsoid's extent where soft
   iron stretches one axis).  Without a time column ``Δt`` is unknown and the chord is the whole diameter ``D``:
   then only samples that no attitude at all could read between their neighbours are spikes.
2. **is not the noise's or the turns' second difference**: its rows' distance from the midpoint of the neighbours,
   ``m_i − (m_{i−1} + m_{i+k})/2`` (for one row, half the second difference ``m_{i−1} − 2 m_i + m_{i+1}``), exceeds on
   some axis the robust scale of that statistic over the log (1.4826 · MAD of the second differences, which the
   coloured noise and the turns set, no smaller than a rounding's ``q/√2``) by the two-sided normal quantile at the
   Bonferroni share of :data:`SPIKE_ALPHA` over every row, axis and run length tested.

Both must hold: the first is the physics (a turn, however fast, is never a spike; the field's diameter bounds a
still sensor's wander far above its noise), the second keeps a slow log's noise from being read as a departure
where a turn's chord is small.  Runs longer than :data:`MAX_SPIKE_ROWS` rows are not sought (a longer departure is
a disturbance, named by the magnetometer's diagnosis, not a glitch).  A run of rows that read the same glitch value
is found as one run (each row leaves both outer neighbours); the first and last rows of the log, which have one
neighbour, are not judged.

:func:`find_spikes` returns the rows; :func:`drop_spikes` (called by
:func:`optcal.families.mag.samples.read_mag`) leaves them out of every
command's samples and says so, and ``--keep-mag-spikes`` (``keep_spikes``) keeps them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.core.quantiles import norm_isf
from optcal.data.quantiles import column_mad_sigmas, median, quantiles
from optcal.data.quantisation import smallest_step

if TYPE_CHECKING:
    from optcal.families.mag.samples import MagSamples

__all__ = ["HAND_TURN_RATE", "MAX_SPIKE_ROWS", "SPIKE_ALPHA", "SPIKE_ROWS", "MagSpikes", "drop_spikes", "find_spikes",
           "turn_reach"]

#: The largest rate at which a hand turns a logger, rad/s (a wrist's fastest flick is about 2 turns a second, 12 rad/s;
#: a calibration's figure-eight stays under 5): the chord a field can sweep between two samples is bounded by this
#: rate over the time between them.  A faster turn (a spinning vehicle) only raises the bar a spike must clear.
HAND_TURN_RATE: float = 10.0
#: The family-wise false-alarm level of the spike test over every sample, axis and run length of a log: a log of
#: true samples loses a row to it once in a hundred logs (and then only where the row also leaves both neighbours by
#: more than a turn can move).
SPIKE_ALPHA: float = 0.01
#: The longest run of glitched rows sought: a bus glitch or a motor's pulse lasts a sample or a few; a longer
#: departure is a disturbance of the field (a magnet, a motor's steady current), not a read fault.
MAX_SPIKE_ROWS: int = 3
#: The central share of the samples whose per-axis range bounds the field's ellipsoid (its soft-iron extent): 99 %
#: leaves out a half-percent tail each side, where up to a few spikes per thousand samples would otherwise sit.
CENTRAL_SHARE: float = 0.99

def turn_reach(diameter: float, dt: NDArray[np.float64] | float | None,
               rate: float = HAND_TURN_RATE) -> NDArray[np.float64] | float:
    """The farthest a field of ``diameter`` turning at ``rate`` moves in ``dt`` seconds: the chord
    ``D sin(min(ω Δt, π)/2)`` (the whole diameter where ``dt`` is ``None``, unknown)."""
    if dt is None:
        return diameter
    return diameter * np.sin(np.minimum(rate * np.asarray(dt, dtype=float), math.pi) / 2)


@dataclass(frozen=True)
class MagSpikes:
    """A magnetometer's spikes (module docstring).

    Attributes
    ----------
    rows : ndarray of int
        The rows of the spikes, ascending.
    run_counts : tuple of int
        The spikes' runs of 1, 2, … :data:`MAX_SPIKE_ROWS` rows.
    n_rows : int
        The rows judged.
    diameter : float
        The field's diameter ``D`` (the samples' units).
    reach : float
        The chord a turn sweeps between the neighbours of a one-row spike at the log's median sample period (``D``
        without a time column).
    z_bound : float
        The second-difference bound, in robust standard deviations.
    timed : bool
        Whether the log's time was used.
    """

    rows: NDArray[np.intp]
    run_counts: tuple[int, ...]
    n_rows: int
    diameter: float
    reach: float
    z_bound: float
    timed: bool

    @property
    def n(self) -> int:
        """Rows found."""
        return int(self.rows.size)

    def describe(self, units: str, flag: str, kept: bool = False) -> str:
        """The spikes in words: the rule's two bars, the runs, and what was done (a note of the reading)."""
        runs = ", ".join(f"{c} {'single rows' if k == 1 else f'runs of {k} rows'}" for k, c in enumerate(self.run_counts, 1)
                         if c)
        turn = (f"more than a field of diameter {self.diameter:.3g} {units} turning at {HAND_TURN_RATE:g} rad/s "
                f"moves between them ({self.reach:.3g} {units} at the median sample period)" if self.timed else
                f"more than the field's diameter, {self.diameter:.3g} {units} (no time column: any turn)")
        head = (f"{self.n} magnetometer samples are spikes ({runs}): each leaves both neighbours by {turn}, and its "
                f"second difference exceeds {self.z_bound:.2f} robust SD (family-wise {SPIKE_ALPHA:g} over "
                f"{self.n_rows} rows)")
        return f"{head}: kept ({flag})" if kept else f"{head}: left out ({flag} keeps them)"


def _runs(rows: NDArray[np.intp]) -> list[int]:
    """The lengths of the runs of consecutive rows."""
    if rows.size == 0:
        return []
    starts = np.flatnonzero(np.diff(rows) != 1) + 1
    return [int(x) for x in np.diff(np.concatenate(([0], starts, [rows.size])))]


def _beyond(d: NDArray[np.float64], bar: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Rows of ``d`` with an axis beyond ``±bar`` (column by column: numpy reduces a row of three slowly)."""
    return (np.abs(d[:, 0]) > bar[0]) | (np.abs(d[:, 1]) > bar[1]) | (np.abs(d[:, 2]) > bar[2])


def find_spikes(m: NDArray[np.float64], t: NDArray[np.float64] | None = None) -> MagSpikes:
    """A magnetometer's spikes (module docstring).

    Parameters
    ----------
    m : ndarray, shape (n, 3)
        The samples in the log's order (finite rows, one per update).
    t : ndarray, shape (n,), optional
        Their times, seconds; without them a turn may take the field anywhere on its sphere between two samples.

    Returns
    -------
    MagSpikes
    """
    n = int(m.shape[0])
    timed = t is not None and n > 1 and bool(np.all(np.diff(t) >= 0))
    empty = MagSpikes(np.empty(0, dtype=np.intp), (0,) * MAX_SPIKE_ROWS, n, 0.0, 0.0, math.inf, timed)
    if n < 2 * MAX_SPIKE_ROWS + 1:
        return empty
    norms = np.sqrt(np.einsum("ij,ij->i", m, m))
    tail = (1 - CENTRAL_SHARE) / 2
    extent = max(hi - lo for lo, hi in (quantiles(m[:, k], (tail, 1 - tail)) for k in range(3)))
    diameter = max(2 * median(norms), extent)
    d2 = m[:-2] - 2 * m[1:-1] + m[2:]
    # a rounding of step q adds q²/12 to each sample's variance, 6 q²/12 to a second difference's
    floor = np.array([0.0 if not math.isfinite(q := smallest_step(m[:, k])) else q / math.sqrt(2) for k in range(3)])
    sigma = np.maximum(column_mad_sigmas(d2), floor)
    if not np.all(sigma > 0):
        return empty
    z_bound = norm_isf(SPIKE_ALPHA / (2 * 3 * (n - 2) * MAX_SPIKE_ROWS))
    dt_one = float(median(t[2:] - t[:-2])) if timed and t is not None else None
    bar = z_bound * sigma
    flagged = np.zeros(n, dtype=bool)
    for k in range(1, MAX_SPIKE_ROWS + 1):
        # runs of k rows starting at 1 … n − k − 1 whose first row passes the statistic (one row: |d2| / σ(d2)) …
        start = np.flatnonzero(_beyond(2 * m[1: n - k] - m[: n - k - 1] - m[k + 1:], bar)) + 1
        for j in range(1, k):  # … and its other rows
            start = start[_beyond(2 * m[start + j] - m[start - 1] - m[start + k], bar)]
        # … each of whose rows leaves both neighbours by more than the turn's chord between them
        reach = turn_reach(diameter, t[start + k] - t[start - 1] if timed and t is not None else None)
        for j in range(k):
            row = m[start + j]
            away = np.minimum(np.linalg.norm(row - m[start - 1], axis=1), np.linalg.norm(row - m[start + k], axis=1))
            keep = away > reach
            start = start[keep]
            reach = reach[keep] if isinstance(reach, np.ndarray) else reach
        for j in range(k):
            flagged[start + j] = True
    rows = np.flatnonzero(flagged)
    counts = [0] * MAX_SPIKE_ROWS
    for length in _runs(rows):
        counts[min(length, MAX_SPIKE_ROWS) - 1] += 1
    return MagSpikes(rows, tuple(counts), n, float(diameter),
                     float(turn_reach(diameter, dt_one)), float(z_bound), timed)


#: Exclusion reason of a magnetometer's spikes.
SPIKE_ROWS = "magnetometer samples that are spikes (leave both neighbours by more than a turning field moves)"


def drop_spikes(samples: MagSamples, keep: bool = False) -> MagSamples:
    """``samples`` without its spikes (:func:`find_spikes`), counted and said; with ``keep`` (``--keep-mag-spikes``)
    every sample, said."""
    spikes = find_spikes(samples.m, samples.t)
    if not spikes.n:
        return samples
    note = spikes.describe(samples.units.units, "--keep-mag-spikes", kept=keep)
    if keep:
        return replace(samples, notes=[*samples.notes, note])
    rows = np.delete(np.arange(samples.n), spikes.rows)
    pick = (lambda a: None if a is None else a[rows])
    return replace(samples, m=np.ascontiguousarray(samples.m[rows]), acc=pick(samples.acc), gyro=pick(samples.gyro),
                   t=pick(samples.t), temp=pick(samples.temp), current=pick(samples.current),
                   throttle=pick(samples.throttle), exclusions={**samples.exclusions, SPIKE_ROWS: spikes.n},
                   notes=[*samples.notes, note])
