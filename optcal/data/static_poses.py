"""One pose per static interval: the interval's sample range, mean, spread and the standard deviation of its mean.

:func:`reduce_interval` reduces the samples of a group of static stretches (found by
:func:`optcal.data.static.detect_static`) to a :class:`StaticInterval`: the mean, the per-axis
standard deviation, the standard deviation of the mean ``σ_k`` (:func:`sigma_of_mean`, by batch
means, since sensor noise is not white; the maximum-likelihood weights of Lu 2017, eq. 14), the
sample count, the times, the mean temperature and the mean gyro reading.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.recording import Recording


@dataclass
class StaticInterval:
    """One static interval and its pose.

    Attributes
    ----------
    number : int
        1-based interval number (the pose's ``rows`` entry).
    start, stop : int
        Sample range in the recording, ``stop`` exclusive.
    first_row, last_row : int
        Data rows of the file.
    t_start, t_end : float
        Seconds.
    n_samples : int
    mean, std : ndarray, shape (3,)
        Mean and per-axis standard deviation of the samples, raw units.
    sigma : float
        Standard deviation of the mean (pooled over the axes), raw units.
    gyro_mean : ndarray, shape (3,) or None
    temp_mean : float or None
    """

    number: int
    start: int
    stop: int
    first_row: int
    last_row: int
    t_start: float
    t_end: float
    n_samples: int
    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    sigma: float
    gyro_mean: NDArray[np.float64] | None
    temp_mean: float | None

    @property
    def duration_s(self) -> float:
        return self.t_end - self.t_start

    @property
    def t_mid(self) -> float:
        return 0.5 * (self.t_start + self.t_end)

    def to_dict(self) -> dict[str, Any]:
        d = {
            "number": self.number,
            "first_row": self.first_row,
            "last_row": self.last_row,
            "sample_start": self.start,
            "sample_stop": self.stop,
            "t_start": self.t_start,
            "t_end": self.t_end,
            "duration_s": self.duration_s,
            "n_samples": self.n_samples,
            "mean": self.mean.tolist(),
            "std": self.std.tolist(),
            "sigma_mean": self.sigma,
        }
        if self.gyro_mean is not None:
            d["gyro_mean"] = self.gyro_mean.tolist()
        if self.temp_mean is not None:
            d["temp_mean"] = self.temp_mean
        return d


def sigma_of_mean(x: NDArray[np.float64], blocks: int, var: NDArray[np.float64] | None = None) -> float:
    """Standard deviation of the mean of the samples ``x`` (n, 3), pooled over the axes.

    White noise gives ``σ/√n``; sensor noise is not white (flicker, drift: the block means
    of the IMU-TK Xsens rest scatter 1.2-3× more than ``σ/√n`` predicts), so the batch-means
    estimate ``std(block means)/√blocks`` over ``blocks`` consecutive blocks is taken when it
    is larger.  These ``σ_k`` feed the maximum-likelihood weights (Lu 2017, eq. 14).
    ``var`` is the per-axis sample variance (ddof 1) of ``x`` when already computed.
    """
    # numpy's mean and var written as their reductions (bit for bit): hundreds of intervals per recording
    n, k = x.shape
    if var is None:
        var = _mean_var(x)[1]
    white = float(np.sqrt(np.add.reduce(var) / k) / np.sqrt(n)) if n > 1 else 0.0
    if blocks < 2 or n < 4 * blocks:
        return white
    size = n // blocks
    # (blocks, size) per axis as a view of the axis's samples (no transposing copy); the same sums
    means = (np.add.reduce(x[: size * blocks].T.reshape(k, blocks, size), axis=2) / size).T
    batch = float(np.sqrt(np.add.reduce(_mean_var(means)[1]) / k) / np.sqrt(blocks))
    return max(white, batch)


def _rows(index: slice | NDArray[np.int64]) -> slice | NDArray[np.int64]:
    """A slice (a view, no copy) for increasing indices without a gap, else the indices."""
    if isinstance(index, slice):
        return index
    return slice(int(index[0]), int(index[-1]) + 1) if int(index[-1] - index[0]) + 1 == index.size else index


def _mean_var(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Column means and sample variances (ddof 1) of ``x`` (n, k): ``x.mean(axis=0)`` and
    ``x.var(axis=0, ddof=1)`` bit for bit (the same reductions, without numpy's per-call checks;
    a recording has hundreds of intervals)."""
    n = x.shape[0]
    mean = np.add.reduce(x, axis=0) / n
    dev = x - mean
    np.square(dev, out=dev)
    var = np.add.reduce(dev, axis=0) / max(n - 1, 0) if n > 1 else np.zeros(x.shape[1])
    return mean, var


def counted_interval(number: int, rec: Recording, use: NDArray[np.int64] | None,
                     stretches: Sequence[tuple[int, int]]) -> StaticInterval:
    """The interval of the samples of ``stretches`` (positions ``[a, b)``, in the order
    :func:`~optcal.data.static_stretches.group_positions` concatenates them), as :func:`reduce_interval` gives it,
    counted only: its place and samples from the stretches' ends (no array of its positions: a 12-hour log's one
    pose held 35 MB of them), its mean, spread and standard error not computed (NaN)."""
    held = [(int(a), int(b)) for a, b in stretches if b > a]
    first, last = held[0][0], held[-1][1] - 1
    n = sum(b - a for a, b in held)
    if use is not None:
        first, last = int(use[first]), int(use[last])
    nan = np.full(3, np.nan)
    return StaticInterval(number=number, start=first, stop=last + 1, first_row=int(rec.row[first]),
                          last_row=int(rec.row[last]), t_start=float(rec.t[first]), t_end=float(rec.t[last]),
                          n_samples=int(n), mean=nan, std=nan.copy(), sigma=float("nan"), gyro_mean=None, temp_mean=None)


def reduce_interval(
    number: int, rec: Recording, use: NDArray[np.int64] | None, pos: slice | NDArray[np.int64],
    gyro: NDArray[np.float64] | None, sigma_blocks: int,
) -> StaticInterval:
    if use is None:  # every sample is usable: positions are the recording's samples
        rows = _rows(pos)
        first, last = (pos.start, pos.stop - 1) if isinstance(pos, slice) else (int(pos[0]), int(pos[-1]))
    else:
        idx = use[pos]
        rows = _rows(idx)
        first, last = int(idx[0]), int(idx[-1])
    x = rec.acc[rows]
    n = x.shape[0]
    mean, var = _mean_var(x)
    std = np.sqrt(var)
    sigma = sigma_of_mean(x, sigma_blocks, var=var)
    return StaticInterval(
        number=number,
        start=first,
        stop=last + 1,
        first_row=int(rec.row[first]),
        last_row=int(rec.row[last]),
        t_start=float(rec.t[first]),
        t_end=float(rec.t[last]),
        n_samples=int(n),
        mean=mean,
        std=std,
        sigma=sigma,
        gyro_mean=None if gyro is None else np.add.reduce(gyro[_rows(pos)], axis=0) / n,
        temp_mean=None if rec.temp is None else float(np.add.reduce(rec.temp[rows]) / n),
    )
