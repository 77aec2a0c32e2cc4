"""The model of a recording that the rest detector tests: blocks of samples, and one test per property of a rest.

**Model.**  A calibration recording is a sequence of rests and moves.  In a rest ``r`` the
accelerometer reads ``a_i = μ_r + e_i`` and the gyro ``ω_i = b + ν_i``: a constant specific force,
the recording's gyro bias, and stationary noise whose level is the rest's own (hand-held or on a
table, orientation, vibration) and whose colour (filtering, flicker) is the sensor's.  A move is
anything else.  The samples are cut into blocks of ``L`` consecutive samples (never across a hole in
the time stamps); each block keeps its mean and its within-block variance per axis
(:func:`block_moments`, one ``reduceat`` per column).  The variance of a block mean is
``κ_j v_j / n`` with ``κ_j`` the noise colour of axis ``j`` (1 for white noise; the integrated
autocorrelation of the noise, in samples, for coloured noise: :func:`noise_colour`, measured on the
recording, at a block length chosen beyond the noise's correlation time by :func:`choose_block`, the
batch-means idea).  Every test below is then scale-free: it compares a change with the noise of the
very blocks that change, at a stated false-alarm probability, so the noise of a rest may differ
from rest to rest.

* **step** (:func:`step_statistic`): consecutive block means differ by more than the quieter block's noise
  of the mean — a move, or a jump between two holds with no motion samples between them (a block holding
  the jump steps away from both neighbours);
* **gyro** (:func:`gyro_statistic`): a block's mean rate is away from the bias (the densest value of
  the block means, :func:`half_sample_mode`) beyond the noise of that mean — a turn, which the
  accelerometer does not see when it is about the vertical;
* **drift** (:func:`trend_statistic`): along a stretch of quiet blocks, the means follow a
  straight line in time beyond the stretch's own scatter about it — a slow turn or a creep.

:mod:`optcal.data.static` applies them and cuts the rests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from optcal.data.window_stats import centre_of

#: Fraction of the steps between consecutive blocks assumed to lie inside rests when the noise
#: colour is measured (:func:`noise_colour`): its quantile at this fraction is a rest's.  A calibration
#: recording rests at least this much of its time; one that does not gets a lenient step test, and the
#: drift test guards against the slow moments of its motion.
REST_FRACTION: float = 0.25
#: Largest growth of the measured colour when the block doubles for it to be the noise's (:func:`noise_colour`):
#: the colour of noise is constant beyond its correlation time and grows more slowly than the block below it,
#: whereas the ratio of a smooth motion's steps to its spread inside a block grows as the block (a factor 2 per
#: doubling).  Above 2^(3/4) the quietest steps are a motion's, not noise: the recording's quietest quarter
#: does not rest, and white noise is assumed instead (the strictest reading).
COLOUR_GROWTH: float = 2.0 ** 0.75
#: Fewest blocks a recording must hold for its noise colour to be measured (below: white noise assumed).
MIN_COLOUR_PAIRS: int = 12
#: Fewest blocks of a stretch for the drift test (two degrees of freedom about a line).
MIN_TREND_BLOCKS: int = 4


@dataclass(frozen=True)
class Blocks:
    """Consecutive blocks of samples and their moments.

    Attributes
    ----------
    starts : ndarray of int, shape (K,)
        First sample of each block (positions in the arrays the blocks were cut from); block ``k``
        ends where block ``k + 1`` starts, the last one at ``size``.
    size : int
        Samples in all.
    n : ndarray, shape (K,)
        Samples per block.
    after_hole : ndarray of bool, shape (K,)
        A hole in the time stamps lies just before the block (no step is tested across it).
    acc_mean, acc_var : ndarray, shape (K, 3)
        Mean and variance (ddof 1, at least the quantisation floor) of each accelerometer axis.
    gyro_mean, gyro_var : ndarray, shape (K, 3) or None
    t_mid : ndarray, shape (K,)
        Mean time of each block, seconds.
    """

    starts: NDArray[np.int64]
    size: int
    n: NDArray[np.float64]
    after_hole: NDArray[np.bool_]
    acc_mean: NDArray[np.float64]
    acc_var: NDArray[np.float64]
    gyro_mean: NDArray[np.float64] | None
    gyro_var: NDArray[np.float64] | None
    t_mid: NDArray[np.float64]

    @property
    def stops(self) -> NDArray[np.int64]:
        return np.append(self.starts[1:], self.size)

    @property
    def count(self) -> int:
        return int(self.starts.size)

    def linked(self) -> NDArray[np.bool_]:
        """Whether block ``k + 1`` follows block ``k`` without a hole, shape (K − 1,)."""
        return ~self.after_hole[1:]


def block_starts(t: NDArray[np.float64], length: int, max_gap: float) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Cut ``t`` into blocks of ``length`` samples that never straddle a step longer than ``max_gap``.

    A run between two holes holds ``max(1, run // length)`` blocks, the last one taking the remainder
    (blocks of ``length`` to ``2 length − 1`` samples).

    Returns
    -------
    starts : ndarray of int
    after_hole : ndarray of bool
        Whether a hole precedes each block.
    """
    m = t.size
    holes = np.flatnonzero(np.diff(t) > max_gap) + 1
    run_start = np.concatenate(([0], holes)).astype(np.int64)
    run_len = np.diff(np.append(run_start, m))
    per_run = np.maximum(run_len // length, 1)
    owner = np.repeat(np.arange(run_start.size), per_run)
    first_of_run = np.cumsum(per_run) - per_run
    offset = np.arange(int(per_run.sum())) - np.repeat(first_of_run, per_run)
    starts = run_start[owner] + offset * length
    after_hole = np.zeros(starts.size, dtype=bool)
    after_hole[first_of_run[1:]] = True
    return starts, after_hole


def block_moments(
    x: NDArray[np.float64], starts: NDArray[np.int64], variance_floor: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per block and column: count, mean and variance (ddof 1, at least ``variance_floor``).

    One ``reduceat`` of the centred column and one of its square per column (the centre keeps the
    sums of squares exact for counts far from zero).
    """
    m, k = x.shape
    n = np.diff(np.append(starts, m)).astype(float)
    mean = np.empty((starts.size, k))
    var = np.empty((starts.size, k))
    for j in range(k):
        col = x[:, j]
        centre = centre_of(col)
        d = col - centre
        s1 = np.add.reduceat(d, starts)
        np.multiply(d, d, out=d)
        s2 = np.add.reduceat(d, starts)
        mean[:, j] = s1 / n + centre
        with np.errstate(invalid="ignore", divide="ignore"):
            var[:, j] = np.where(n > 1, (s2 - s1 * s1 / n) / np.maximum(n - 1, 1), np.inf)
    np.maximum(var, variance_floor, out=var)
    return n, mean, var


def make_blocks(
    t: NDArray[np.float64], acc: NDArray[np.float64], gyro: NDArray[np.float64] | None, length: int,
    max_gap: float, acc_floor: float, gyro_floor: float,
) -> Blocks:
    """The blocks of a recording's usable samples (:func:`block_starts`, :func:`block_moments`)."""
    starts, after_hole = block_starts(t, length, max_gap)
    n, acc_mean, acc_var = block_moments(acc, starts, acc_floor)
    g_mean = g_var = None
    if gyro is not None:
        _, g_mean, g_var = block_moments(gyro, starts, gyro_floor)
    t_mid = np.add.reduceat(t - t[0], starts) / n + t[0]
    return Blocks(starts, int(t.size), n, after_hole, acc_mean, acc_var, g_mean, g_var, t_mid)


def pair_ratios(mean: NDArray[np.float64], var: NDArray[np.float64], n: NDArray[np.float64],
                linked: NDArray[np.bool_]) -> NDArray[np.float64]:
    """``Δm_j² / (v_kj/n_k + v_k+1,j/n_k+1)`` for each linked pair of consecutive blocks, shape (P, 3).

    For white noise at rest each entry follows (about) a χ² with one degree of freedom; coloured noise
    scales it by the noise colour ``κ_j``.
    """
    d = np.diff(mean, axis=0)[linked]
    w = var / n[:, None]
    noise = (w[:-1] + w[1:])[linked]
    with np.errstate(divide="ignore", invalid="ignore"):
        r: NDArray[np.float64] = d * d / noise
    return r


def noise_colour(blocks: Blocks, sensor: str = "acc", doubled: Blocks | None = None) -> NDArray[np.float64] | None:
    """The noise colour ``κ_j`` of each axis: how much more the block means scatter than white noise.

    Measured on the quietest :data:`REST_FRACTION` of the steps between consecutive blocks: their
    quantile of :func:`pair_ratios` over the same quantile of χ²₁ (white noise).  Never below 1 (sensor
    noise is not anti-correlated); ``None`` when the recording has fewer than :data:`MIN_COLOUR_PAIRS`
    linked pairs of blocks.  With ``doubled`` (the same samples in blocks twice as long), a colour that grows
    by more than :data:`COLOUR_GROWTH` is a motion's, and white noise (1) is returned.
    """
    mean, var = (blocks.acc_mean, blocks.acc_var) if sensor == "acc" else (blocks.gyro_mean, blocks.gyro_var)
    assert mean is not None and var is not None
    r = pair_ratios(mean, var, blocks.n, blocks.linked())
    if r.shape[0] < MIN_COLOUR_PAIRS:
        return None
    white = float(stats.chi2.ppf(REST_FRACTION, 1))
    kappa = np.maximum(np.nan_to_num(np.nanquantile(r, REST_FRACTION, axis=0) / white, nan=1.0, posinf=1.0), 1.0)
    if doubled is not None:
        longer = noise_colour(doubled, sensor)
        if longer is not None and float(np.median(longer / kappa)) > COLOUR_GROWTH:
            return np.ones_like(kappa)
    return kappa


def step_statistic(mean: NDArray[np.float64], var: NDArray[np.float64], n: NDArray[np.float64],
                   kappa: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(1/3) Σ_j Δm_j² / (2 κ_j min(v_kj/n_k, v_k+1,j/n_k+1))`` between every pair of consecutive blocks, shape (K − 1,).

    The change is measured against the quieter block's noise of the mean: a block that holds the start of a
    move, or a jump between two holds, has the noise of neither rest (its variance holds the change itself),
    so it steps away from both neighbours.  At rest it follows (about) ``F(3, dof)``.
    """
    d = np.diff(mean, axis=0)
    w = var / n[:, None]
    noise = 2.0 * np.minimum(w[:-1], w[1:]) * kappa
    with np.errstate(divide="ignore", invalid="ignore"):
        s: NDArray[np.float64] = np.nan_to_num(np.sum(d * d / noise, axis=1) / 3.0, nan=np.inf)
    return s


def effective_dof(n: NDArray[np.float64] | float, kappa: NDArray[np.float64]) -> NDArray[np.float64] | float:
    """Degrees of freedom of a block's variance over three axes: ``3 (n − 1) / κ̄`` (coloured noise has fewer
    independent samples)."""
    return 3.0 * (np.asarray(n) - 1.0) / float(np.mean(kappa))


def f_quantile(p_false: float, dfn: float | NDArray[np.float64], dfd: float | NDArray[np.float64]) -> NDArray[np.float64]:
    """The ``1 − p_false`` quantile of F(dfn, dfd) (a statistic at rest exceeds it with probability ``p_false``)."""
    return np.asarray(stats.f.isf(p_false, dfn, np.maximum(dfd, 1.0)), dtype=float)


def half_sample_mode(x: NDArray[np.float64]) -> float:
    """The half-sample mode (Bickel & Frühwirth 2006): the densest value of ``x``.

    Halves the sorted sample to its narrowest half until two or three values remain; robust while the
    values at the mode outnumber any other cluster (the block means of the rests, against the spread
    rates of the moves).
    """
    y = np.sort(x[np.isfinite(x)])
    while y.size > 3:
        h = (y.size + 1) // 2
        widths = y[h - 1:] - y[: y.size - h + 1]
        i = int(np.argmin(widths))
        y = y[i:i + h]
    if y.size == 3:
        return float(y[1] if (y[1] - y[0]) == (y[2] - y[1]) else (y[:2].mean() if y[1] - y[0] < y[2] - y[1] else y[1:].mean()))
    return float(np.mean(y)) if y.size else 0.0


def bias_wander(mean: NDArray[np.float64], var: NDArray[np.float64], n: NDArray[np.float64],
                kappa: NDArray[np.float64], bias: NDArray[np.float64], calm: NDArray[np.bool_]) -> NDArray[np.float64]:
    """How far a resting block's mean rate strays from the bias beyond its own noise, per axis (a variance).

    The robust variance (MAD) of the calm blocks' mean rates about the bias, less their median noise of the
    mean ``κ v / n``: the bias's wander (bias instability, the Earth's rate in each orientation, temperature).
    Zero when the calm blocks are fewer than :data:`MIN_COLOUR_PAIRS`.
    """
    if calm.sum() < MIN_COLOUR_PAIRS:
        return np.zeros(mean.shape[1])
    d = mean[calm] - bias
    robust = (1.4826 * np.median(np.abs(d), axis=0)) ** 2
    own = np.median(kappa * var[calm] / n[calm, None], axis=0)
    wander: NDArray[np.float64] = np.maximum(robust - own, 0.0)
    return wander


def gyro_statistic(mean: NDArray[np.float64], var: NDArray[np.float64], n: NDArray[np.float64],
                   kappa: NDArray[np.float64], bias: NDArray[np.float64], calm: NDArray[np.bool_],
                   wander: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """``(1/3) Σ_j (ω̄_kj − b_j)² / (κ_j max(v_kj, ṽ_j) / n_k + w_j)`` of every block: its mean rate against the
    noise of that mean and the bias's wander ``w`` (:func:`bias_wander`).

    ``ṽ_j`` is the median variance of the ``calm`` blocks: a block's own variance (few degrees of freedom when
    the noise is coloured) never makes its mean look quieter than a typical rest's, and the statistic is
    compared with χ²₃/3 (:func:`chi2_quantile`).  The tremor of a hand-held rest raises the variance, not the mean.
    """
    d = mean - bias
    typical = np.median(var[calm], axis=0) if calm.any() else np.median(var, axis=0)
    extra = 0.0 if wander is None else wander
    with np.errstate(divide="ignore", invalid="ignore"):
        noise = kappa * np.maximum(var, typical) / n[:, None] + extra
        g: NDArray[np.float64] = np.nan_to_num(np.sum(d * d / noise, axis=1) / 3.0, nan=np.inf)
    return g


def chi2_quantile(p_false: float, dof: int = 3) -> float:
    """The ``1 − p_false`` quantile of χ²_dof / dof."""
    return float(stats.chi2.isf(p_false, dof) / dof)


def trend_statistic(means: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
    """The t statistic of the slope of each axis's block means on time, against their scatter about the line.

    Scale-free and the stretch's own: at rest (block means independent) each follows Student's t with
    ``K − 2`` degrees of freedom; a slow turn or a creep moves the means along a line.
    """
    k = means.shape[0]
    tc = t - t.mean()
    sxx = float(tc @ tc)
    mc = means - means.mean(axis=0)
    slope = tc @ mc / sxx
    resid = mc - np.outer(tc, slope)
    s2 = np.sum(resid * resid, axis=0) / max(k - 2, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tstat: NDArray[np.float64] = np.abs(slope) / np.sqrt(s2 / sxx)
    return np.nan_to_num(tstat, nan=0.0, posinf=np.inf)


def t_quantile(p_false: float, dof: int) -> float:
    """The two-sided ``1 − p_false`` quantile of Student's t with ``dof`` degrees of freedom."""
    return float(stats.t.isf(p_false / 2.0, max(dof, 1)))


#: Median of χ² with one degree of freedom: the median pair ratio (:func:`pair_ratios`) of white noise at rest.
REST_QUANTILE_WHITE: float = float(stats.chi2.ppf(0.5, 1))
