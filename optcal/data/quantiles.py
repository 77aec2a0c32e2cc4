"""Medians and quantiles by one ``np.partition`` each: the values of ``np.median`` and ``np.quantile``.

``np.median`` partitions at two or three positions at once (the two middle values, and the
last one to look for NaN), which numpy does several times slower than one position (18 ms
against 5 ms for 10⁶ samples), and its NaN check imports ``numpy.ma`` (≈ 15 ms, once per
process).  The data layer takes medians and noise-floor quantiles of whole recordings
several times per file, always of finite values, so these helpers partition once at the
upper position and take the lower one as the maximum of the part below it.  The results
are bit for bit those of numpy's (``tests/data/test_data_speed.py`` checks it): the even-size
median is ``(a + b) / 2`` as ``np.mean`` of the two middle values computes it, and a
quantile is numpy's linear interpolation (``method="linear"``, Hyndman & Fan's type 7)
with numpy's own rounding (``_lerp``).  A median of many values (a 12-hour log's norms and steps) is selected
inside a bracket read from a subsample instead (:func:`median`): the same value, a fifth of the time.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray


#: Values from which :func:`median` selects its middle values inside a bracket read from a subsample (three passes
#: over the values, no partition of them all): below it one partition is as quick (a partition of 2¹⁶ values takes
#: about 0.5 ms, the bracket's subsample and passes about as long).  Speed only: the value is the same either way.
BRACKET_MIN_VALUES: int = 1 << 16
#: Values in the subsample the bracket is read from: its middle ranks then stand for the whole's to about
#: 1/(2√m) = 0.4 % of the values, so the bracket holds about 3 % of a large array (partitioned in its place).
BRACKET_SAMPLE: int = 1 << 14
#: The fractional part of the golden ratio: the subsample's k-th position is ``frac(k · φ)`` of the array's length.
GOLDEN_FRACTION: float = (5**0.5 - 1) / 2
#: The bracket's half-width about the subsample's middle, in standard deviations of a middle rank of the subsample
#: (binomial: √m/2): the whole's middle values fall outside it about once in 10⁴ arrays of independent values, and
#: then (or for any array) the whole is partitioned as before: the bracket changes the time, never the value.
BRACKET_SIGMAS: float = 4.0
#: Values compared at a time in the bracket's passes: their flags (64 KiB) stay in the processor's cache (twice as
#: fast as flags of the whole array's length on a 12-hour log; the same values).
BRACKET_PIECE: int = 1 << 16
#: Most of the values strictly inside the bracket, as a share of them all: about 3 % are, for values without many
#: ties at the middle; more (a subsample that missed) and the whole is partitioned instead, so the values taken
#: never hold more than an eighth of a copy of the array.
BRACKET_MAX_SHARE: float = 0.125


def _middle_in_bracket(a: NDArray[np.float64], lower: int, upper: int) -> tuple[float, float] | None:
    """The ``lower``-th and ``upper``-th smallest of ``a`` (1-D, ``upper`` is ``lower`` or ``lower + 1``, 0-based)
    by a bracket ``[lo, hi]`` read from a subsample (:data:`GOLDEN_FRACTION`): the values below ``lo``, equal to ``lo``
    and equal to ``hi`` are counted, those strictly between taken and partitioned; ``None`` (the caller partitions
    the whole) when a rank is outside the bracket, the bracket is not finite, more than
    :data:`BRACKET_MAX_SHARE` of the values are strictly inside it, or a selected value is a zero.

    The order is the partition's: a NaN is above every number, as it is above ``hi`` here, so the ranks of the
    values below and inside the bracket are the whole's.  Values equal in order are equal bit for bit, a zero's
    sign excepted (which of ``-0.0`` and ``0.0`` the whole's partition selects is its own: a zero is refused), so
    which of equal values is selected does not change the value.
    """
    n = a.size
    m = BRACKET_SAMPLE
    # positions at the fractional parts of k·φ (a Weyl sequence): spread evenly over the array in no period a
    # signal could share, the same on every run, and no import of numpy.random (7 MB and 10 ms of a process)
    at = np.arange(m, dtype=float)
    at *= GOLDEN_FRACTION
    np.mod(at, 1.0, out=at)
    at *= n
    sample = np.sort(a[at.astype(np.intp)])
    half = BRACKET_SIGMAS * 0.5 * np.sqrt(m)
    lo = float(sample[max(int(np.floor(lower / n * m - half)), 0)])
    hi = float(sample[min(int(np.ceil((upper + 1) / n * m + half)), m - 1)])
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return None
    below = at_lo = at_hi = 0
    kept: list[NDArray[np.float64]] = []
    most, held = int(BRACKET_MAX_SHARE * n), 0
    flags, more = np.empty(min(n, BRACKET_PIECE), dtype=bool), np.empty(min(n, BRACKET_PIECE), dtype=bool)
    for start in range(0, n, BRACKET_PIECE):
        piece = a[start:start + BRACKET_PIECE]
        f, g = flags[:piece.size], more[:piece.size]
        np.less(piece, lo, out=f)
        below += int(np.count_nonzero(f))
        np.equal(piece, lo, out=f)
        at_lo += int(np.count_nonzero(f))
        if hi > lo:
            np.equal(piece, hi, out=f)
            at_hi += int(np.count_nonzero(f))
            np.greater(piece, lo, out=f)
            np.less(piece, hi, out=g)
            f &= g
            kept.append(piece[f])
            held += kept[-1].size
            if held > most:
                return None
    inner = np.concatenate(kept) if kept else np.empty(0)
    del kept
    # each rank as (where, index): 0 the values equal to lo, 1 the values strictly inside, 2 those equal to hi
    places = []
    for rank in (lower, upper):
        r = rank - below
        if r < 0 or r >= at_lo + inner.size + at_hi:
            return None
        places.append((0, 0) if r < at_lo else (1, r - at_lo) if r < at_lo + inner.size else (2, 0))
    inside = [k for where, k in places if where == 1]
    if inside:
        top = max(inside)
        inner.partition(top)
    values = []
    for where, k in places:
        if where == 1:
            value = float(inner[k]) if k == top else float(inner[:top].max())  # k == top - 1: the largest below
        else:
            value = lo if where == 0 else hi
        if value == 0:
            return None
        values.append(value)
    return values[0], values[1]


def median(x: ArrayLike, overwrite_input: bool = False) -> float:
    """The median of finite values, as ``np.median`` gives it.

    Below :data:`BRACKET_MIN_VALUES` values a copy of ``x`` is partitioned, once; from it the middle values are
    selected inside a bracket read from a subsample (:func:`_middle_in_bracket`; the same value, in a fifth of the
    time on a 12-hour log's 4.3 million steps: 9 ms against 45 ms), the whole partitioned where the bracket misses them.

    Parameters
    ----------
    x : array_like
        Finite values (a NaN is not looked for); at least one.
    overwrite_input : bool
        Partition ``x`` itself (a 1-D float array the caller no longer needs) instead of a copy, where it is
        partitioned.
    """
    a = np.asarray(x, dtype=float).ravel()
    n = a.size
    if n == 0:
        return float("nan")
    mid = n // 2
    if n >= BRACKET_MIN_VALUES:
        middle = _middle_in_bracket(a, mid - 1 + n % 2, mid)
        if middle is not None:
            low, high = middle
            return float(high) if n % 2 else float((low + high) / 2)
    if overwrite_input and isinstance(x, np.ndarray) and np.shares_memory(a, x):
        a.partition(mid)
        part = a
    else:
        part = np.partition(a, mid)
    if n % 2:
        return float(part[mid])
    return float((part[:mid].max() + part[mid]) / 2)


def column_medians(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """The median of each column of a 2-D array of finite values (``np.median(x, axis=0)``), all columns by one
    partition at the upper middle position (as :func:`median`): the rest model asks for them once per still
    stretch, where a call per column costs more than the work.  From :data:`BRACKET_MIN_VALUES` rows each column's
    middle values are selected inside a bracket instead (:func:`_middle_in_bracket`; the same values: a 12-hour log's
    (172800, 3) bias track, 6.5 ms → 1 ms), all columns partitioned where a bracket misses."""
    a = np.asarray(x, dtype=float)
    n = a.shape[0]
    if n == 0:
        return np.full(a.shape[1], np.nan)
    mid = n // 2
    if n >= BRACKET_MIN_VALUES:  # each column's middle values selected inside a bracket, as :func:`median` does
        middles = []
        for j in range(a.shape[1]):  # a contiguous copy of the column: the bracket's passes on it take half the time
            middle = _middle_in_bracket(np.ascontiguousarray(a[:, j]), mid - 1 + n % 2, mid)
            if middle is None:  # missed, or a zero (whose sign is the whole partition's): all columns partitioned
                break
            middles.append(middle[1] if n % 2 else (middle[0] + middle[1]) / 2)
        else:
            return np.array(middles)
    part = np.partition(a, mid, axis=0)
    if n % 2:
        return np.asarray(part[mid]).copy()
    return np.asarray((part[:mid].max(axis=0) + part[mid]) / 2)


#: Mean rows per group from which :func:`grouped_column_medians` partitions each group on its own (a call of about
#: 10 µs each) rather than sorting every row: the 172,800 block variances of a 12-hour, 100 Hz log in 129 rests took
#: 0.15 s by sorts and take 0.01 s by partitions; the values are the same either way (speed only).
GROUP_PARTITION_ROWS: int = 64


def grouped_column_medians(x: NDArray[np.float64], sizes: NDArray[np.intp]) -> NDArray[np.float64]:
    """:func:`column_medians` of each group of consecutive rows of ``x`` (n, m) of finite values, the groups'
    ``sizes`` (g,) (each at least one, summing to n), all groups by one sort per column (g, m): the same values."""
    a = np.asarray(x, dtype=float)
    sizes = np.asarray(sizes, dtype=np.intp)
    offsets = np.r_[0, np.cumsum(sizes)[:-1]].astype(np.intp)
    group = np.repeat(np.arange(sizes.size), sizes)
    lower = offsets + (sizes - 1) // 2  # the lower and upper middle positions (equal for an odd size)
    upper = offsets + sizes // 2
    longest = int(sizes.max()) if sizes.size else 0
    if sizes.size * GROUP_PARTITION_ROWS <= a.shape[0]:  # few, long groups: one partition each (a 12-hour log's rests)
        return np.array([column_medians(a[o:o + k]) for o, k in zip(offsets.tolist(), sizes.tolist())]
                        ).reshape(sizes.size, a.shape[1])
    if sizes.size * longest <= 4 * max(a.shape[0], 1):  # groups of similar sizes: stacked, +inf below each, one sort
        at = np.arange(longest)
        inside = at[None, :] < sizes[:, None]
        stacked = np.where(inside[..., None], a[np.minimum(offsets[:, None] + at[None, :], a.shape[0] - 1)], np.inf)
        ordered = np.sort(stacked, axis=1)
        rows = np.arange(sizes.size)
        low, high = ordered[rows, (sizes - 1) // 2], ordered[rows, sizes // 2]
        return np.asarray(np.where((lower == upper)[:, None], high, (low + high) / 2))
    out = np.empty((sizes.size, a.shape[1]))
    for j in range(a.shape[1]):
        s = a[np.lexsort((a[:, j], group)), j]  # sorted within each group, the groups in order
        out[:, j] = np.where(lower == upper, s[upper], (s[lower] + s[upper]) / 2)
    return out


def np_median(x: ArrayLike) -> float:
    """``float(np.median(x))``, the same value, NaN and infinities included, without importing ``numpy.ma``.

    Finite values go to :func:`median`, any non-finite value to numpy's own (whose NaN check imports ``numpy.ma``,
    ≈ 15 ms of a process's start, the first time it runs).
    """
    a = np.asarray(x, dtype=float)
    if a.size and bool(np.isfinite(a).all()):
        return median(a)
    return float(np.median(a))


def np_column_medians(x: ArrayLike) -> NDArray[np.float64]:
    """``np.median(x, axis=0)`` of a 2-D array, the same values, NaN and infinities included, without importing
    ``numpy.ma`` where the values are finite (:func:`column_medians`; numpy's own otherwise)."""
    a = np.asarray(x, dtype=float)
    if a.size and bool(np.isfinite(a).all()):
        return column_medians(a)
    return np.asarray(np.median(a, axis=0))


def np_quantile(x: ArrayLike, probability: float) -> float:
    """``float(np.quantile(x, probability))`` of all of ``x``, the same value, NaN and infinities included, without
    importing ``numpy.ma`` where the values are finite (:func:`quantiles`; numpy's own otherwise)."""
    a = np.asarray(x, dtype=float)
    if a.size and bool(np.isfinite(a).all()):
        return quantiles(a, [probability])[0]
    return float(np.quantile(a, probability))


def column_quantile(x: NDArray[np.float64], probability: float) -> NDArray[np.float64]:
    """``np.quantile(x, probability, axis=0)`` of a 2-D array (the same values), by :func:`quantiles` per column
    (partitions, not a sort) where the values are finite."""
    a = np.asarray(x, dtype=float)
    if a.shape[0] == 0 or not bool(np.isfinite(a).all()):
        return np.asarray(np.quantile(a, probability, axis=0))
    return np.array([quantiles(a[:, j], [probability])[0] for j in range(a.shape[1])])


def quantiles(
    x: ArrayLike, probabilities: Sequence[float], scratch: NDArray[np.float64] | None = None
) -> list[float]:
    """Quantiles of finite values, as ``np.quantile(x, probabilities)`` gives them (linear interpolation).

    One partition per probability, each of the part of the data below the previous one (the
    probabilities in decreasing order), so two quantiles cost little more than one.

    Parameters
    ----------
    x : array_like
        Finite values; at least one.
    probabilities : sequence of float
        Each in [0, 1].
    scratch : ndarray, optional
        A float buffer of at least ``x``'s size that may be overwritten: the copy partitioned is
        made there (no allocation of another array of the data's size).
    """
    values_in = np.asarray(x, dtype=float).ravel()
    if values_in.size >= BRACKET_MIN_VALUES and len(set(probabilities)) == 1:
        # one quantile of many values (the noise colour's of a 12-hour log's 172,800 pairs per axis): its two order
        # statistics selected inside a bracket, as :func:`median` does (the same values; the whole partitioned where
        # the bracket misses them)
        value = _quantile_in_bracket(values_in, float(probabilities[0]))
        if value is not None:
            return [value] * len(probabilities)
    if scratch is not None and scratch.size >= values_in.size:
        a = scratch[: values_in.size]
        a[...] = values_in
    else:
        a = values_in.copy()  # partitioned in place below
    n = a.size
    if n == 0:
        return [float("nan")] * len(probabilities)
    out: dict[int, float] = {}
    end = n  # a[:end] holds the `end` smallest values
    values: dict[float, float] = {}
    for q in sorted(set(probabilities), reverse=True):
        virtual = (n - 1) * q  # numpy's 'linear' virtual index
        below = int(np.floor(virtual))
        if virtual >= n - 1:
            below = n - 1
        for k in (min(below + 1, n - 1), below):
            if k in out:
                continue
            if k == end - 1:  # the largest of the part below the previous position
                top = int(np.argmax(a[:end]))
                a[top], a[k] = a[k], a[top]
            else:
                a[:end].partition(k)
            out[k] = float(a[k])
            end = k
        above = min(below + 1, n - 1)
        values[q] = _lerp(out[below], out[above], virtual - below) if virtual < n - 1 else out[n - 1]
    return [values[q] for q in probabilities]


def _quantile_in_bracket(a: NDArray[np.float64], q: float) -> float | None:
    """:func:`quantiles`' value of one probability ``q`` of ``a`` (1-D, finite), its order statistics selected by
    :func:`_middle_in_bracket`; ``None`` where the bracket misses them (or selects a zero)."""
    n = a.size
    virtual = (n - 1) * q  # numpy's 'linear' virtual index, as in :func:`quantiles`
    below = int(np.floor(virtual))
    if virtual >= n - 1:
        below = n - 1
    middle = _middle_in_bracket(a, below, min(below + 1, n - 1))
    if middle is None:
        return None
    return _lerp(middle[0], middle[1], virtual - below) if virtual < n - 1 else middle[1]


def _lerp(a: float, b: float, t: float) -> float:
    """numpy's linear interpolation between two order statistics (``numpy.lib._function_base_impl._lerp``)."""
    diff = b - a
    return b - diff * (1 - t) if t >= 0.5 else a + diff * t


#: The median absolute deviation's factor to the standard deviation of a normal population (1/Φ⁻¹(3/4)).
MAD_TO_SIGMA: float = 1.4826


def column_mad_sigmas(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per column, the robust standard deviation ``1.4826 · median |x − median x|`` (:func:`column_medians` twice)."""
    a = np.asarray(x, dtype=float)
    return np.asarray(MAD_TO_SIGMA * column_medians(np.abs(a - column_medians(a))))
