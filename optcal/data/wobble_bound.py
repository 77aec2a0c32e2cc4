"""The stretches' rate spread from which :func:`optcal.data.wobble.wobbles` bounds a wobble: sums over each
stretch's samples (:func:`_span_sums`), or over the rest model's blocks of them, O(blocks)
(:func:`_block_span_sums`), with the margin for the two ways' rounding (:func:`_spread_margin`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.data import rest_model as rm


def _span_sums(x: NDArray[np.float64], a: NDArray[np.intp], z: NDArray[np.intp], centre: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The sums of ``x − centre`` (n, 3) and of its squares over each span ``[a[i], z[i])`` (spans in order, not
    overlapping, none empty), by one pass over the samples, column by column through one buffer of a column's length
    (the same sums as of the (n, 3) differences: on a 12-hour log two temporaries of 100 MB and their page faults
    were 0.2 s)."""
    edges = np.column_stack([a, z]).ravel()
    if edges.size and edges[-1] == x.shape[0]:
        edges = edges[:-1]  # the last span runs to the end: reduceat's last sum does
    if not (edges.size and bool(np.all(np.diff(edges) >= 0))):
        d = x - centre
        s1 = np.array([d[i:j].sum(axis=0) for i, j in zip(a, z)]).reshape(-1, x.shape[1])
        s2 = np.array([np.square(d[i:j]).sum(axis=0) for i, j in zip(a, z)]).reshape(-1, x.shape[1])
        return s1, s2
    s1 = np.empty((edges.size, x.shape[1]))
    s2 = np.empty((edges.size, x.shape[1]))
    buffer = np.empty(x.shape[0])
    for j in range(x.shape[1]):
        np.subtract(x[:, j], centre[j], out=buffer)
        s1[:, j] = np.add.reduceat(buffer, edges)
        s2[:, j] = np.add.reduceat(np.multiply(buffer, buffer, out=buffer), edges)
    return s1[0::2], s2[0::2]


def _block_span_sums(x: NDArray[np.float64], blocks: rm.Blocks, a: NDArray[np.intp], z: NDArray[np.intp],
                     centre: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_span_sums` of the gyro's rates ``x`` (n, 3) over each span ``[a[i], z[i])`` (none empty), from the rest
    model's blocks of the same samples: the blocks wholly inside a span by their moments, ``Σ (x − c) = n (x̄ − c)``
    and ``Σ (x − c)² = (n − 1) s² + n (x̄ − c)²`` (O(blocks)), the samples of the part-blocks at its two ends by
    themselves (fewer than two blocks' worth).  The second sums are at least the samples' (``blocks.gvar`` carries
    the rounding floor and ``q²/12`` of :func:`~optcal.data.rest_model.make_blocks`, and is clipped at 0), up to the
    rounding of the two ways of summing (:func:`_spread_margin`)."""
    assert blocks.gmean is not None and blocks.gvar is not None
    k0 = np.searchsorted(blocks.start, a)  # the first block starting at or after a
    k1 = np.searchsorted(blocks.stop, z, side="right")  # the blocks before k1 end at or before z
    whole = k1 > k0
    s1 = np.zeros((a.size, x.shape[1]))
    s2 = np.zeros((a.size, x.shape[1]))
    if whole.any():
        # every block's two sums (O(blocks)), then each span's by reduceat over its blocks' edges when the spans
        # come in order (as the rest model's stretches do), else over their blocks gathered
        first, stop = k0[whole], k1[whole]
        edges = np.column_stack([first, stop]).ravel()
        ordered = bool(np.all(np.diff(edges) >= 0))
        rows = None if ordered else rm.Ranges.of(first, stop)
        n = blocks.n[:, None] if rows is None else blocks.n[rows.rows, None]
        d = np.subtract(blocks.gmean if rows is None else blocks.gmean[rows.rows], centre)
        b1 = n * d
        b2 = np.multiply(b1, d, out=d)
        b2 += (n - 1.0) * (blocks.gvar if rows is None else blocks.gvar[rows.rows])
        if rows is not None:
            s1[whole], s2[whole] = rows.sums(b1), rows.sums(b2)
        else:
            if edges[-1] == blocks.count:
                edges = edges[:-1]  # the last span runs to the last block: reduceat's last sum does
            s1[whole] = np.add.reduceat(b1, edges, axis=0)[0::2]
            s2[whole] = np.add.reduceat(b2, edges, axis=0)[0::2]
    # the samples outside the whole blocks: a span's head and tail, or all of a span that holds no whole block
    head_stop = np.where(whole, blocks.start[np.minimum(k0, blocks.count - 1)], z)
    tail_start = np.where(whole, blocks.stop[np.maximum(k1 - 1, 0)], z)
    lo = np.concatenate([a, tail_start])
    hi = np.concatenate([np.maximum(head_stop, a), z])
    owner = np.concatenate([np.arange(a.size), np.arange(a.size)])
    keep = hi > lo
    if keep.any():
        e = rm.Ranges.of(lo[keep], hi[keep])
        d = x[e.rows] - centre
        np.add.at(s1, owner[keep], e.sums(d))
        np.add.at(s2, owner[keep], e.sums(d * d))
    return s1, s2


#: Units in the last place, per sample of a stretch, by which its rate spread² summed sample by sample and block by
#: block (:func:`_block_span_sums`) may differ: a sequential sum of ``k`` terms errs by at most ``k`` ulps of its
#: magnitude; each way sums at most ``2m`` terms (the samples, then the blocks) into ``s2/m`` and into ``s1/m``, whose
#: square is at most ``s2/m``; two ways, two terms, ``2m`` each: 8.
SPREAD_ROUNDING_ULPS: float = 8.0


def _spread_margin(mean_square: NDArray[np.float64], m: NDArray[np.intp]) -> NDArray[np.float64]:
    """What the spread² ``Σ_axes (s2/m − (s1/m)²)`` of a stretch of ``m`` samples may lose to rounding, of its
    mean squares ``s2/m`` (k, 3) about the centre (:data:`SPREAD_ROUNDING_ULPS`; ten more terms for the divisions and
    the subtraction): added to the blocks' spread² it stays above the samples' as computed, so a bound that clears a
    stretch by the blocks clears it by the samples too (10⁻⁸ of it on a 12-hour, 100 Hz stretch)."""
    eps = float(np.finfo(float).eps)
    return np.asarray(SPREAD_ROUNDING_ULPS * eps * (np.maximum(m, 1) + 10.0) * mean_square.sum(axis=1))

