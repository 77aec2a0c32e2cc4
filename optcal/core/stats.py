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


#: Most columns :func:`row_norms` adds one by one: numpy's reduction adds a row of up to 7 values in order, left to
#: right (from 8 it keeps several partial sums), so up to 7 the two give the same bits.
ROW_SUM_IN_ORDER: int = 7


def row_norms(x: ArrayLike) -> NDArray[np.float64]:
    """``np.linalg.norm(x, axis=1)`` of a 2-D array, the same values bit for bit, column by column.

    numpy 2 reduces a row of three values in about ten times the time of the same arithmetic done on whole columns
    (172,800 rows: about 8 ms against 1 ms); the squares are added in numpy's order (left to right), so the values
    are the same.  Arrays of more than :data:`ROW_SUM_IN_ORDER` columns go to numpy.

    Parameters
    ----------
    x : array_like
        2-D, (n, m).

    Returns
    -------
    ndarray
        (n,), each row's Euclidean norm.
    """
    a = np.asarray(x, dtype=float)
    if a.ndim != 2 or not 1 <= a.shape[1] <= ROW_SUM_IN_ORDER:
        return np.asarray(np.linalg.norm(a, axis=1))
    total = a[:, 0] * a[:, 0]
    for j in range(1, a.shape[1]):
        total += a[:, j] * a[:, j]
    return np.sqrt(total, out=total)


def row_max_abs(x: ArrayLike, centre: ArrayLike) -> NDArray[np.float64]:
    """``np.max(np.abs(x - centre), axis=1)`` of a 2-D array less a row ``centre``, the same values, column by column
    (:func:`row_norms`: the row reduction costs ten times the arithmetic); a NaN in a row gives NaN, as numpy's.

    Parameters
    ----------
    x : array_like
        2-D, (n, m), m at least 1.
    centre : array_like
        (m,) or a scalar.

    Returns
    -------
    ndarray
        (n,), each row's largest absolute difference from ``centre``.
    """
    a = np.asarray(x, dtype=float)
    c = np.broadcast_to(np.asarray(centre, dtype=float), (a.shape[1],))
    out = np.abs(a[:, 0] - c[0])
    for j in range(1, a.shape[1]):
        np.maximum(out, np.abs(a[:, j] - c[j]), out=out)
    return out


def column_ptp(x: ArrayLike) -> NDArray[np.float64]:
    """``np.ptp(x, axis=0)`` of a 2-D array (each column's largest less its smallest), the same values, column by
    column: numpy's reduction along the rows of a C-ordered (n, 3) array takes about 30 times as long."""
    a = np.asarray(x, dtype=float)
    return np.array([a[:, j].max() - a[:, j].min() for j in range(a.shape[1])])


def mean_and_se(values: ArrayLike, weights: ArrayLike | None = None) -> tuple[float, float]:
    """Weighted mean of independent ``values`` and its standard error measured by their own scatter.

    The standard error of a paired held-out difference (one value per held-out unit, the units independent),
    and of a mean of per-unit estimates whose noise is of unknown size: ``se² = k/(k − 1) Σ wᵢ² (dᵢ − d̄)²``
    with the weights normalised to sum to one (equal weights: ``sd/√k``, Student's one-sample form).

    Parameters
    ----------
    values : array_like, shape (k,)
        One value per independent unit.
    weights : array_like, shape (k,), optional
        Non-negative weights (equal by default).

    Returns
    -------
    mean, se : float
        ``Σ wᵢ dᵢ / Σ wᵢ`` and its standard error; the standard error is 0 for fewer than two units and NaN
        (both) for none.
    """
    d = np.asarray(values, dtype=float).ravel()
    w = np.ones(d.size) if weights is None else np.asarray(weights, dtype=float).ravel()
    total = float(np.sum(w))
    if d.size == 0 or total <= 0:
        return float("nan"), float("nan")
    w = w / total
    mean = float(np.sum(w * d))
    k = d.size
    se = float(np.sqrt(k / (k - 1) * np.sum(w * w * (d - mean) ** 2))) if k > 1 else 0.0
    return mean, se
