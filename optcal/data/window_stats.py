"""Moving-window statistics of a recording's columns, the data's resolution and its converter's step.

The rest model (:mod:`optcal.data.rest_tests`) takes the converter's step from here (:func:`quantum`;
its ``q²/12`` enters every block's variance).  The centred moving windows (:class:`MovingWindow`, one
cumulative sum per column in reused buffers; :class:`HalfWindowDrift`; :func:`noise_floor`, never below
:func:`resolution`) were the previous static detector's statistics; they are kept, with their tests, for
moving statistics elsewhere, and no longer decide where a recording rests.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from optcal.data.quantiles import column_medians, median, quantiles

#: Rows a centring value is taken from (evenly strided): the median of 10⁶ samples costs a sort.
CENTRE_ROWS: int = 4096


def centre_of(x: NDArray[np.float64]) -> NDArray[np.float64] | float:
    """A value inside the data's range to centre cumulative sums on (columnwise for 2-D).

    The median of at most :data:`CENTRE_ROWS` evenly strided rows: the sums need a centre
    near the data (raw counts carry a large offset), not the exact median.
    """
    stride = max(1, x.shape[0] // CENTRE_ROWS)
    return median(x[::stride]) if x.ndim == 1 else column_medians(x[::stride])


def moving_mean_var(x: NDArray[np.float64], window: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Centred moving mean and variance (windows clipped at the ends), columnwise.

    Uses cumulative sums of the data centred near the data (:func:`centre_of`), so it is O(n) and exact
    enough for raw counts with a large offset (:func:`column_window_stats`, column by column).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        return column_window_stats(x, window)
    pairs = [column_window_stats(x[:, j], window) for j in range(x.shape[1])]
    return np.column_stack([p[0] for p in pairs]), np.column_stack([p[1] for p in pairs])


def half_window_drift(x: NDArray[np.float64], window: int) -> NDArray[np.float64]:
    """‖mean of the next half window − mean of the previous half window‖ at each sample.

    A rotation at rate ω moves the specific force by about ``ω · window/2`` between the two
    halves, while at rest the difference is the noise of two means; this sees slow turns
    that the moving variance misses.  Zero within half a window of the ends.
    """
    x = np.asarray(x, dtype=float)
    drift = HalfWindowDrift(x.shape[0], window)
    for j in range(x.shape[1]):
        column_window_stats(x[:, j], window, drift)
    return drift.result()


class HalfWindowDrift:
    """The squared half-window drift summed over columns (:func:`half_window_drift`), filled by
    :class:`MovingWindow` from the cumulative sum it makes anyway (one pass per column)."""

    def __init__(self, m: int, window: int) -> None:
        self.m = m
        self.h = max(1, window // 2)
        size = max(0, m - 2 * self.h + 1)
        self.squared = np.zeros(size)
        self._after: NDArray[np.float64] | None = np.empty(size)  # scratch, reused for every column

    def add(self, c: NDArray[np.float64], scratch: NDArray[np.float64] | None = None) -> None:
        """Add one column's squared drift from ``c``, the cumulative sum of the centred column (``c[0] = 0``).

        ``scratch`` is a free buffer of at least ``m − 2h + 1`` floats (else one is allocated).
        """
        m, h = self.m, self.h
        if m < 2 * h + 1:
            return
        # samples i = h .. m − h: before = c[i] − c[i−h], after = c[i+h] − c[i]
        centre = c[h:m - h + 1]
        after = self._after if self._after is not None else np.empty(centre.size)
        before = scratch[:centre.size] if scratch is not None else np.empty(centre.size)
        np.subtract(c[2 * h:], centre, out=after)
        np.subtract(centre, c[:m - 2 * h + 1], out=before)
        np.subtract(after, before, out=after)
        np.multiply(after, after, out=after)
        self.squared += after

    def result(self) -> NDArray[np.float64]:
        """The drift at each sample (zero within half a window of the ends); the sums are used up."""
        self._after = None
        out = np.zeros(self.m)
        if self.m >= 2 * self.h + 1:
            drift = np.sqrt(self.squared, out=self.squared)
            drift /= self.h
            out[self.h:self.m - self.h + 1] = drift
        self.squared = np.zeros(0)
        return out


class MovingWindow:
    """Centred moving mean and variance (windows clipped at the ends) of columns of ``m`` samples, O(m) each.

    Differences of one cumulative sum of the column centred near its data (:func:`centre_of`)
    give the window sums; the same sum gives ``drift``'s half-window means when given, and the
    cumulative sum of the squares the variance.  The buffers are allocated once and reused
    for every column (a recording's statistics take seven columns): :meth:`column` returns
    views of them, valid until its next call.
    """

    def __init__(self, m: int, window: int) -> None:
        self.m, self.window = m, window
        self._cumsum = np.empty(m + 1)
        self._cumsum[0] = 0.0
        self._mean = np.empty(m)
        self._var = np.empty(m)

    def column(
        self, x: NDArray[np.float64], drift: HalfWindowDrift | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The moving mean and variance of one column ``x`` (m,): views of this object's buffers.

        ``drift`` accumulates the column's half-window drift from the same cumulative sum.
        """
        window, c, mean, var = self.window, self._cumsum, self._mean, self._var
        centre = centre_of(x)
        xc = np.subtract(x, centre, out=var)  # the centred column, then its squares, then the variance
        np.cumsum(xc, out=c[1:])
        if drift is not None:  # before the window sums: the mean's buffer is its scratch
            drift.add(c, scratch=mean)
        interior, edge, count = _window_sums(c, window, mean)
        np.multiply(xc, xc, out=xc)
        np.cumsum(xc, out=c[1:])
        _window_sums(c, window, var)  # the window sums of the squares overwrite the squares (read from c only)
        for a in (mean, var):
            a[interior] /= window
            a[edge] /= count
        square = np.multiply(mean, mean, out=c[1:])  # the cumulative sums are no longer needed
        var -= square
        np.clip(var, 0.0, None, out=var)
        mean += centre
        return mean, var

    def scratch(self) -> NDArray[np.float64]:
        """A free buffer of ``m`` floats (the cumulative sums'), overwritten by the next :meth:`column`."""
        return self._cumsum[1:]


def column_window_stats(
    x: NDArray[np.float64], window: int, drift: HalfWindowDrift | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Centred moving mean and variance of one column (windows clipped at the ends), O(n) (:class:`MovingWindow`)."""
    return MovingWindow(x.shape[0], window).column(x, drift)


def _window_sums(
    c: NDArray[np.float64], window: int, out: NDArray[np.float64]
) -> tuple[slice, NDArray[np.int64], NDArray[np.float64]]:
    """Sums over the centred window at each sample from the cumulative sum ``c`` (``c[0] = 0``), into ``out``.

    Returns the interior rows (full windows), the edge rows and their (clipped) window sizes.
    """
    m = out.size
    h = window // 2
    full = m - window + 1
    if full > 0:
        np.subtract(c[window:], c[:full], out=out[h:h + full])
        interior = slice(h, h + full)
        edge = np.concatenate([np.arange(0, h), np.arange(h + full, m)])
    else:
        interior = slice(0, 0)
        edge = np.arange(m)
    lo = np.clip(edge - h, 0, m)
    hi = np.clip(edge - h + window, 0, m)
    out[edge] = c[hi] - c[lo]
    return interior, edge, (hi - lo).astype(float)


def noise_floor(
    stat: NDArray[np.float64], quantile: float, resolution: float, scratch: NDArray[np.float64] | None = None
) -> float:
    """Noise floor of a windowed statistic: its low quantile, at least the data's resolution.

    ``scratch`` is a free buffer of the statistic's size to partition in (:func:`quantiles`)."""
    return float(max(quantiles(stat, [quantile], scratch)[0], resolution))


#: Steps per chunk of :func:`_abs_step_chunks` (temporaries of 2 MB, whatever the recording's length).
STEP_CHUNK: int = 2**18


def _abs_step_chunks(col: NDArray[np.float64]) -> Iterator[NDArray[np.float64]]:
    """``|diff(col)|`` in consecutive chunks of at most :data:`STEP_CHUNK` steps."""
    for start in range(0, max(0, col.size - 1), STEP_CHUNK):
        d = np.diff(col[start:start + STEP_CHUNK + 1])
        yield np.abs(d, out=d)


def resolution(x: NDArray[np.float64]) -> float:
    """Smallest standard deviation the data can resolve.

    The quantisation noise ``q/√12`` of the smallest non-zero step, and at least the
    rounding error of the moving variances from cumulative sums, ``√(ε n) · max|x − c|``
    (``c`` the centre of those sums, :func:`centre_of`).  The steps are taken in chunks
    (:func:`_abs_step_chunks`): no temporary of the data's length.
    """
    if x.size == 0:
        return 0.0
    columns = x.reshape(x.shape[0], -1)
    smallest, spread = np.inf, 0.0
    for j in range(columns.shape[1]):  # column by column: temporaries of one column
        col = columns[:, j]
        for d in _abs_step_chunks(col):
            smallest = min(smallest, float(np.min(d, where=d > 0, initial=np.inf)))
        # max |x − c| from the extremes: rounding x − c is monotonic in x, so this is exact
        centre = centre_of(col)
        spread = max(spread, float(col.max() - centre), float(centre - col.min()))
    step = smallest / np.sqrt(12.0) if np.isfinite(smallest) else 0.0
    return max(step, float(np.sqrt(np.finfo(float).eps * x.shape[0])) * spread)


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
        for d in _abs_step_chunks(col):
            d = d[d > 0]
            if d.size:
                q = min(q, float(d.min()))
                sample.append(d[(-column_steps) % stride::stride].copy())  # a view would keep the chunk
            column_steps += d.size
        n_steps += column_steps
        span = max(span, float(col.max() - col.min()))
    if n_steps < 10:
        return None
    if span > (2**16 + 1) * q:
        return None
    if q < 1.0 and abs(np.log10(q) - round(np.log10(q))) < 1e-6:
        return None  # a step of exactly 10⁻ᵏ is the printing of k decimals, not a converter's step
    ratio = np.concatenate(sample) / q
    return q if float(np.mean(np.abs(ratio - np.round(ratio)) < 1e-3)) >= 0.99 else None
