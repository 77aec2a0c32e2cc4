"""How a still stretch's orientation wobbles: the RMS angle the gyro's rates turn it through about its mean within
windows, less the gyro's own angle random walk (:func:`wobbles`), or a bound of it from the stretch's rate spread
(:mod:`optcal.data.wobble_bound`) when that bound cannot reach the tolerance.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.data import rest_model as rm
from optcal.data.quantiles import np_column_medians
from optcal.data.rest_model import WOBBLE_SHRINK
from optcal.data.wobble_bound import _block_span_sums, _span_sums, _spread_margin


#: Largest share of the wobble tolerance (``√(2 WOBBLE_SHRINK)``) the gyro's own angle random walk over a window may
#: reach for the gyro to be evidence of a wobble: a mean square of a random walk over one window scatters by about
#: its own size, so a noisier gyro's wobble is its noise, and the tolerance is left to the accelerometer's tests.
RESOLVED_WOBBLE_SHARE: float = 0.5


#: Samples × axes of gathered windows held at once by :func:`wobbles` (a bound on its scratch memory: about 8 MB per
#: array of them, a handful of arrays).
WOBBLE_CHUNK_VALUES: int = 1 << 20


def wobble(gyro: NDArray[np.float64], t: NDArray[np.float64], rad_per_unit: float, window: int,
           tolerance: float | None = None) -> float:
    """RMS angle (rad, norm over the axes) by which the orientation moves about its mean within windows of ``window``
    samples: :func:`wobbles` of the one stretch ``gyro`` (m, 3) at ``t`` (m,)."""
    return float(wobbles(gyro, t, rad_per_unit, window, [(0, gyro.shape[0])], tolerance)[0])


def wobbles(gyro: NDArray[np.float64], t: NDArray[np.float64], rad_per_unit: float, window: int,
            spans: list[tuple[int, int]], tolerance: float | None = None,
            blocks: rm.Blocks | None = None) -> NDArray[np.float64]:
    """RMS angle (rad, norm over the axes) by which the orientation moves about its mean within windows of ``window``
    samples, for each stretch ``spans[i]`` (samples ``[a, z)`` of ``gyro`` (n, 3) at ``t`` (n,); all at once).

    In each window (:data:`WOBBLE_DWELLS` dwells; a stretch's samples past its last whole window are one more
    window, when three or more) the rates less their mean (the bias, and a steady turn, which
    :meth:`optcal.data.rest_tests.RestModel.turns` tests) are integrated by the trapezoid rule over the true time
    steps, less what the gyro's own white noise gives (its angle random walk, from the rates' sample-to-sample
    differences): a hand's tremor or a vibration is left.  0 when that random walk reaches
    :data:`RESOLVED_WOBBLE_SHARE` of the tolerance: the gyro cannot resolve it.

    With ``tolerance`` (rad), a stretch whose wobble cannot reach it returns that bound instead: within a window
    of ``T`` the angle moves from its mean by at most ``∫|ω − ω̄| ≤ T·rms(ω − ω̄)``, and the windows' mean squares
    are at most the stretch's, so the wobble is at most ``T`` times the stretch's rate spread.

    ``blocks``: the rest model's blocks of these very samples (``blocks.gmean``, ``blocks.gvar`` of ``gyro``), from
    which that spread is summed block by block (:func:`_block_span_sums`) instead of sample by sample: the same
    spread, from the blocks' moments, at least as large (their variances carry ``q²/12`` and a rounding floor), with a
    margin for the rounding of either sum added (:func:`_spread_margin`), so that it stays a bound and no stretch's
    verdict changes: a stretch it cannot clear is measured window by window as without it.
    """
    a = np.array([span[0] for span in spans], dtype=np.intp)
    z = np.array([span[1] for span in spans], dtype=np.intp)
    m = z - a
    out = np.zeros(a.size)
    todo = m >= 3
    if tolerance is not None and todo.any():
        # each stretch's rate spread by sums over it (one pass over the samples for all stretches)
        # about the stretches' first rates' median (a gyro's bias: a large one would cancel the spread's digits)
        centre = np_column_medians(gyro[a[todo]])
        if blocks is None:
            s1, s2 = _span_sums(gyro, a, z, centre)
        else:
            s1, s2 = _block_span_sums(gyro, blocks, a, z, centre)
        mm = np.maximum(m, 1)[:, None]
        spread2 = np.maximum(s2 / mm - (s1 / mm) ** 2, 0.0).sum(axis=1)
        if blocks is not None:
            spread2 += _spread_margin(s2 / mm, m)
        spread = np.sqrt(spread2)
        window_s = t[a + np.minimum(window, m) - 1] - t[a]
        bound = window_s * spread * rad_per_unit
        within = todo & (bound <= tolerance)
        out[within] = bound[within]
        todo &= ~within
    rows = np.flatnonzero(todo)
    if not rows.size:
        return out
    # the windows: each stretch's whole windows, then its remainder (three samples or more)
    whole = m[rows] // window
    rest = m[rows] - whole * window
    owner = np.concatenate([np.repeat(rows, whole), rows[rest >= 3]])
    first = np.concatenate([np.repeat(a[rows], whole) + _ranks(whole) * window, (a[rows] + whole * window)[rest >= 3]])
    length = np.concatenate([np.full(int(whole.sum()), window), rest[rest >= 3]]).astype(np.intp)
    total = np.zeros(a.size)
    noise = np.zeros(a.size)
    count = np.bincount(owner, weights=length, minlength=a.size)
    size = int(length.max())
    chunk = max(1, WOBBLE_CHUNK_VALUES // (3 * size))
    j = np.arange(size)
    padded = np.zeros((gyro.shape[0] + 1, 3))  # the rates, then a zero row: a window's samples past its end
    padded[:-1] = gyro
    for c0 in range(0, owner.size, chunk):
        f, n = first[c0:c0 + chunk], length[c0:c0 + chunk]
        # the samples along the first axis (sample, window, axis): a sum over a window's samples adds whole rows of
        # windows × axes in the samples' order, the same sums as a window at a time, without a call per sample
        idx = np.minimum(f[None, :] + j[:, None], gyro.shape[0] - 1)
        inside = j[:, None] < n[None, :]
        pair = inside[1:] & inside[:-1]
        # two scratch arrays of (size, windows, 3), every step in place (the expressions in the comments)
        w = np.take(padded, np.where(inside, idx, gyro.shape[0]), axis=0)  # w = where(inside, gyro[idx], 0)
        tt = np.take(t, idx)
        dt = np.where(pair, np.diff(tt, axis=0), 0.0)
        # the gyro's own white noise, from its sample-to-sample differences (var(Δω) = 2σ² for white noise; a
        # tremor of a few hertz hardly changes from one sample to the next): integrated, a random walk whose
        # mean square about its mean over a window of T, the mean rate removed (a Brownian bridge), is σ² dt T / 12
        d = np.diff(w, axis=0)  # d = where(pair, diff(w), 0): past a window's end w is 0, so only its last step
        short = np.flatnonzero(n < size)
        d[n[short] - 1, short] = 0.0
        k = (n - 1.0)[:, None]
        d_sum = d.sum(axis=0)
        d2_sum = np.multiply(d, d, out=d).sum(axis=0)
        white = np.sum(d2_sum / k - (d_sum / k) ** 2, axis=1) / 2.0
        mean = w.sum(axis=0) / n[:, None]
        # angle = cumsum((0.5 (w[1:] + w[:-1]) − mean) dt), 0 past the window's end (and at its first sample)
        angle = np.add(w[1:], w[:-1], out=d)
        angle *= 0.5
        angle -= mean
        angle *= dt[..., None]
        np.cumsum(angle, axis=0, out=angle)
        np.copyto(angle, 0.0, where=~pair[..., None])
        # the angle's squares about its mean over the window's samples: Σ A² − (Σ A)² / n
        angle_sum = angle.sum(axis=0)
        spread2 = np.sum(np.multiply(angle, angle, out=angle).sum(axis=0) - angle_sum ** 2 / n[:, None], axis=1)
        span = tt[n - 1, np.arange(n.size)] - tt[0]
        owners = owner[c0:c0 + chunk]
        total += np.bincount(owners, weights=spread2, minlength=a.size)
        noise += np.bincount(owners, weights=n * white * (span / (n - 1.0)) * span / 12.0, minlength=a.size)
    r2 = rad_per_unit * rad_per_unit  # the rates' unit to rad/s: the angles scale by it
    total, noise = total[rows] * r2, noise[rows] * r2
    n_all = np.maximum(count[rows], 1.0)
    # the gyro's own random walk not below the tolerance: it cannot tell a wobble (the accelerometer's tests do)
    resolved = noise <= RESOLVED_WOBBLE_SHARE**2 * 2.0 * WOBBLE_SHRINK * n_all
    out[rows] = np.where(resolved, np.sqrt(np.maximum(total - noise, 0.0) / n_all), 0.0)
    return out


def _ranks(counts: NDArray[np.intp]) -> NDArray[np.intp]:
    """0, 1, …, ``counts[i]`` − 1 for each ``i``, concatenated."""
    total = int(counts.sum())
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    return np.asarray(np.arange(total) - starts, dtype=np.intp)
