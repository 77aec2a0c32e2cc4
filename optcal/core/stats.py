"""Summary statistics shared by every layer, each written once."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def rms(values: ArrayLike, mask: NDArray[np.bool_] | None = None) -> float:
    """Root mean square of ``values`` (of those selected by ``mask`` when given).

    Parameters
    ----------
    values : array_like
        Any shape; every entry counts.
    mask : ndarray of bool, optional
        Selects the entries to include (same shape as ``values``, or indexing its first axis).

    Returns
    -------
    float
        ``sqrt(mean(values²))``; NaN when no value is selected.
    """
    selected = np.asarray(values, dtype=float)
    if mask is not None:
        selected = selected[mask]
    return float(np.sqrt(np.mean(np.square(selected)))) if selected.size else float("nan")


def sorted_unique(values: NDArray[np.intp]) -> NDArray[np.intp]:
    """The distinct values of an index array, sorted: ``np.unique(values)``'s, without its import of ``numpy.ma``
    (numpy 2's ``unique`` asks ``numpy.ma`` whether the array is masked: 15 ms of CPU, once per process).

    Parameters
    ----------
    values : ndarray of intp
        Any shape (flattened).

    Returns
    -------
    ndarray
        1-D, ascending, each value once.
    """
    ordered = np.sort(np.asarray(values).ravel())
    if ordered.size < 2:
        return ordered
    keep = np.empty(ordered.size, dtype=bool)
    keep[0] = True
    np.not_equal(ordered[1:], ordered[:-1], out=keep[1:])
    return ordered[keep]
