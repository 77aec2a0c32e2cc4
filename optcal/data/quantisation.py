"""The converter step of quantised data (:func:`quantum`).

The rest model (:mod:`optcal.data.rest_tests`) adds the step's ``q²/12`` to every block's variance, and keeps it
in a block mean where the signal is quieter than the step (:func:`optcal.data.rest_model.rounding_floor`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

#: Steps per chunk of :func:`_abs_step_chunks` (temporaries of 2 MB, whatever the recording's length).
STEP_CHUNK: int = 2**18


def _abs_step_chunks(col: NDArray[np.float64], ends: list[float] | None = None) -> Iterator[NDArray[np.float64]]:
    """``|diff(col)|`` in consecutive chunks of at most :data:`STEP_CHUNK` steps; ``ends``, if given, gets each
    chunk's largest and smallest value (read while the chunk is in the processor's cache, not in a pass of its own).
    Each chunk is written into one buffer, which the next chunk overwrites: a caller keeps copies, not the chunks."""
    buffer = np.empty(min(STEP_CHUNK, max(0, col.size - 1)))
    for start in range(0, max(0, col.size - 1), STEP_CHUNK):
        chunk = col[start:start + STEP_CHUNK + 1]
        d = buffer[: chunk.size - 1]
        np.subtract(chunk[1:], chunk[:-1], out=d)  # np.diff's subtraction, without a fresh array per chunk
        if ends is not None:
            ends += (chunk.max(), chunk.min())
        yield np.abs(d, out=d)


def smallest_step(col: NDArray[np.float64]) -> float:
    """The smallest non-zero ``|diff|`` of a column (its converter's or its printing's step; ``inf`` when it never
    changes), chunk by chunk (:func:`_abs_step_chunks`)."""
    q = np.inf
    for d in _abs_step_chunks(col):
        d = d[d > 0]  # NaN steps compare False: left out
        if d.size:
            q = min(q, float(d.min()))
    return q


#: Steps on which :func:`quantum` checks that the steps are multiples of the smallest.
QUANTUM_CHECK_STEPS: int = 100_000


def quantum(x: NDArray[np.float64]) -> float | None:
    """The converter step of quantised data, else ``None``.

    Data are quantised when their steps are multiples of one step and their range spans at
    most 2¹⁶ steps (a 16-bit converter); values printed with a fixed number of decimals
    have a common step too, but span far more of them, or (a signal of small range) step by
    exactly 10⁻ᵏ, which no converter in physical units does.  The multiples are checked on at most
    :data:`QUANTUM_CHECK_STEPS` evenly strided non-zero steps (the smallest step over all of
    them), column by column and chunk by chunk (:func:`_abs_step_chunks`): no temporary of the
    data's length.
    """
    columns = x.reshape(x.shape[0], -1)
    k = columns.shape[1]
    stride = max(1, (columns.shape[0] - 1) * k // QUANTUM_CHECK_STEPS)
    q, span, n_steps, sample = np.inf, 0.0, 0, []
    for j in range(k):
        col = columns[:, j]
        column_steps = 0  # every stride-th non-zero step of the column, counted across its chunks
        ends: list[float] = []
        for d in _abs_step_chunks(col, ends):
            steps, chunk_q, chunk_sample = _non_zero_steps(d, (-column_steps) % stride, stride)
            if steps:
                q = min(q, chunk_q)
                sample.append(chunk_sample)
            column_steps += steps
        n_steps += column_steps
        if col.size > 1:  # the column's largest less its smallest (np.max, as col.max(), keeps a NaN)
            span = max(span, float(np.max(ends[0::2]) - np.min(ends[1::2])))
        if span > (2**16 + 1) * q:
            return None  # as below, decided early: over the columns left q can only fall and the span only grow
    if n_steps < 10:
        return None
    if span > (2**16 + 1) * q:
        return None
    if q < 1.0 and abs(np.log10(q) - round(np.log10(q))) < 1e-6:
        return None  # a step of exactly 10⁻ᵏ is the printing of k decimals, not a converter's step
    ratio = np.concatenate(sample)
    ratio /= q
    off = np.round(ratio)  # |ratio − round(ratio)|, in place: the distance of each step from a whole multiple
    np.subtract(ratio, off, out=off)
    np.abs(off, out=off)
    return q if np.count_nonzero(off < 1e-3) / off.size >= 0.99 else None


def _non_zero_steps(d: NDArray[np.float64], first: int, stride: int) -> tuple[int, float, NDArray[np.float64]]:
    """Of the steps ``d`` (``|diff|``, a buffer it may overwrite), those above zero (a NaN is not): their count, the
    smallest (``inf`` when none) and a copy of every ``stride``-th from the ``first``, as ``d[d > 0]`` gives them.

    A signal that steps at nearly every sample (a noisy one) has few zero steps: they are set to ``inf`` in place and
    the sample taken by position, the non-zero step of rank ``r`` sitting after the ``r`` + (zero steps before it)
    others, instead of a copy of the whole chunk's non-zero steps (a quarter of :func:`quantum`'s time).
    """
    above = d > 0
    steps = int(np.count_nonzero(above))
    if steps == d.size:
        return steps, float(d.min()) if steps else np.inf, d[first::stride].copy()
    if 2 * steps < d.size:  # mostly zero steps (a quantised signal): the non-zero ones, copied
        kept = d[above]
        return steps, float(kept.min()) if steps else np.inf, kept[first::stride].copy()
    gaps = np.flatnonzero(~above)  # the zero (or NaN) steps, fewer than half
    d[gaps] = np.inf
    rank = np.arange(first, steps, stride)
    # gap i has gaps[i] − i non-zero steps before it: it lies before the non-zero step of rank r when that is ≤ r
    at = rank + np.searchsorted(gaps - np.arange(gaps.size), rank, side="right")
    return steps, float(d.min()), d[at]
