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
    chunk's largest and smallest value (read while the chunk is in the processor's cache, not in a pass of its own)."""
    for start in range(0, max(0, col.size - 1), STEP_CHUNK):
        chunk = col[start:start + STEP_CHUNK + 1]
        d = np.diff(chunk)
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
            d = d[d > 0]
            if d.size:
                q = min(q, float(d.min()))
                sample.append(d[(-column_steps) % stride::stride].copy())  # a view would keep the chunk
            column_steps += d.size
        n_steps += column_steps
        if col.size > 1:  # the column's largest less its smallest (np.max, as col.max(), keeps a NaN)
            span = max(span, float(np.max(ends[0::2]) - np.min(ends[1::2])))
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
