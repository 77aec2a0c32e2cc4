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
