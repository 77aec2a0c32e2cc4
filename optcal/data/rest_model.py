"""The statistical model of a recording's rests: blocks, and the tests that say where the sensor moves.

A rest is a stretch over which the true specific force (and, with a gyro, the true rate, zero)
does not change, so that every block of samples in it has the same mean up to the noise of a
block mean.  The model makes no assumption about how noisy a rest is, nor that every rest is as
noisy as the others: every test compares a change with the noise measured where the change is.

* **Blocks.**  The usable samples are cut into blocks of ``window_s`` (never across a time gap),
  and each block reduced to its mean and variance per axis (:func:`make_blocks`), with the
  converter's quantisation variance ``q²/12`` added (a quantised rest may show no spread at all).
* **Noise colour.**  Sensor noise is not white (MEMS flicker, a logger's low-pass filter, a hand's
  tremor), so the scatter of block means exceeds ``σ²/n`` by a factor ``κ²``.  ``κ²`` is measured
  on the recording itself (:func:`noise_colour`): the ratio of the squared change between
  consecutive block means to its white-noise expectation, at the quietest quarter of the pairs
  (recordings are mostly at rest, so the quarter of smallest changes are pairs inside a rest), and
  again inside the rests first found; never below 1.
* **Rounding.**  Where the signal's own noise is below half a converter step (a filtered or very quiet
  signal), the rounding does not average down in a block mean: each mean keeps ``q²/12``
  (:func:`rounding_floor`), added to the white noise of a mean before the colour multiplies it.
* **A step** between consecutive blocks (:func:`step_statistic`): ``Σ_j d_j² / (κ_j² v_j (1/n_a +
  1/n_b))`` with ``v_j`` the pooled variance of the two blocks, which at rest follows ``3 F(3,
  n_a + n_b − 2)``; a step beyond its ``1 − false_alarm`` quantile is motion, or a jump between
  two holds with no motion stored.
* **The gyro** (:func:`gyro_statistic`): a block's mean rate against the bias, ``Σ_j (ω̄_j −
  b_j)² / (κ_j² v_j / n + u_j²)`` with ``u_j²`` the bias' wander between rests, against ``3 F(3, n
  − 1)``.  The bias is the half-sample mode of the block means the accelerometer calls still
  (:func:`half_sample_mode`), then the median of the rests' own means, each over a minute
  (:func:`bias_track`: a warming gyro's bias drifts, no faster than :data:`MAX_BIAS_DRIFT_RAD_S2`), the
  wander the scatter of the rests' means about it beyond their noise.  In the second pass the bias is a real
  gyro's (:func:`fit_bias_model`): ``b₀ + G f̂`` (g-sensitivity) with steps after knocks, fitted robustly to the
  rests' mean rates, the rests whose accelerometer turns as their gyro says left out; a block or stretch whose
  rate is off it significantly but turns the sensor through less than a pose's tolerance over the time it is
  judged on is still (:func:`turn_is_relevant`).
* **Drift** (:func:`trend_statistic`): a stretch whose mean creeps (a slow turn, seen or not by
  a gyro) is found by the t statistic of the slope of its batch means against their own scatter
  (scale-free, coloured noise included), against Student's ``t`` at ``false_alarm`` (Bonferroni over
  the axes).

Every threshold is a quantile of the test's distribution at rest at the stated false-alarm
probability, times a user's multiplier (``--static-threshold``, ``--gyro-threshold``,
``--drift-threshold``; 1 by default).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from optcal.core import quantiles  # the distributions' quantiles without scipy (see its docstring)
from optcal.core.units import RAD_PER_UNIT
from optcal.data.quantiles import column_quantile, median, np_median

#: Two rests closer than a dwell whose means differ by less than this many per-sample standard deviations are
#: one pose: the shift lies inside the samples' own ±3σ spread (a flicker noise wanders so between two
#: pieces of one rest), far below any change of orientation a calibration uses.
SAME_POSE_SAMPLE_SIGMAS: float = 3.0
#: Largest shrink of a pose mean's norm, relative to 1 g, that an orientation wobbling about its mean may cause:
#: a wobble of rms angle θ shrinks the mean of gravity's projection by about θ²/2, so a rest must hold its
#: orientation within θ = √(2 × 10⁻⁴) ≈ 0.8° rms (0.1 mg, the accuracy the calibrations here are judged at).
WOBBLE_SHRINK: float = 1e-4
#: Dwells over which the wobble is measured: long enough to see a hand's slow sway (about 1 Hz), short
#: enough that the gyro's own angle random walk and bias wander, integrated over it, stay far below the tolerance.
WOBBLE_DWELLS: float = 8.0
#: Per-sample noise, in g, below which two rests' noise levels are not told apart (1 µg: far below any
#: accelerometer's noise; what is left below it is the rounding of simulated or converted values).
NOISE_FLOOR_G: float = 1e-6
#: Largest change of a MEMS gyro's bias between the rests of one session, rad/s (1 °/s): in-run bias stability is
#: 0.001-0.1 °/s and the thermal drift at most about 0.1 °/s per °C over the few °C of a session; rests whose mean
#: rates scatter more are not all rests.
MAX_BIAS_WANDER_RAD_S: float = float(np.radians(1.0))
#: Largest turn-on bias of a MEMS gyro, rad/s on any axis (75 °/s): the widest zero-rate level of the consumer
#: parts' datasheets (L3G4200D's ±75 °/s typical at its ±2000 °/s range; the MPU-6050's ±20 °/s, the BMI160's
#: ±10 °/s).  A gyro at rest reads its bias, so a block whose mean rate is beyond it on an axis is no rest, whatever
#: its accelerometer says (a steady spin keeps the accelerometer still in the sensor's frame).
MAX_GYRO_BIAS_RAD_S: float = float(np.radians(75.0))
#: The fewest radians per second one unit of a gyro whose unit is unknown can be worth, and so the most units
#: a rate can take: samples with decimals are rad/s or °/s (°/s the smaller, π/180 rad/s); whole-number samples
#: are counts, one worth at least a 16-bit converter's step over the smallest full scale a MEMS gyro has,
#: ±125 °/s.  A rate bound divided by it is at least the bound in the gyro's true unit, so a rest is never
#: taken for a turn for not knowing the unit.
MIN_RAD_S_PER_UNIT: dict[str, float] = {"decimal": float(np.radians(1.0)), "counts": float(np.radians(125.0) / 32768)}


def gyro_unit_bound(gyro_units: str | None, counts: bool) -> tuple[float, str]:
    """Radians per second of one unit of the gyro's samples: as stated (``rad/s``, ``deg/s``), else the fewest it can
    be worth (:data:`MIN_RAD_S_PER_UNIT`: whole-number samples, ``counts``, as a ±125 °/s 16-bit gyro's counts; others
    as °/s), so a rate bound divided by it is at least the bound in the true unit; and how it was taken, in words."""
    if gyro_units in RAD_PER_UNIT:
        return RAD_PER_UNIT[gyro_units], f"{gyro_units} as stated"
    if counts:
        return MIN_RAD_S_PER_UNIT["counts"], "counts, bounded as a ±125 °/s 16-bit gyro's"
    return MIN_RAD_S_PER_UNIT["decimal"], "unknown; bounded as °/s, the smaller of rad/s and °/s"
#: Span, seconds, over which the gyro's bias is taken as constant (:func:`bias_track`): a MEMS gyro's bias follows
#: its temperature through the package's thermal time constant, minutes, so over a minute it moves by a fraction
#: of its drift in a session, while a minute of a calibration recording holds several rests, enough for their
#: mode to pass over one that turns.
BIAS_SPAN_S: float = 60.0
#: Fastest change of a MEMS gyro's bias within a session, rad/s per second (1 °/s per minute): its thermal
#: sensitivity is at most about 0.16 °/s per °C (the MPU-6050's datasheet: ±20 °/s over 125 °C), and a package
#: warms by a few °C per minute at most; a bias that seems to move faster is a turn.
MAX_BIAS_DRIFT_RAD_S2: float = float(np.radians(1.0) / 60.0)
#: Quantile of the block-to-block rates at which the gyro's readings are set against the accelerometer's turn rate:
#: the fast moves, where a gyro's bias is small beside the rate.
UNIT_RATE_QUANTILE: float = 0.9

def turn_is_relevant(rate_rad_s: NDArray[np.float64], duration_s: NDArray[np.float64] | float,
                     multiplier: float = 1.0) -> NDArray[np.bool_]:
    """Whether a turn at ``rate_rad_s`` held for ``duration_s`` moves a pose beyond its wobble tolerance.

    A rest may hold its orientation within ``√(2 WOBBLE_SHRINK)`` rad (:data:`WOBBLE_SHRINK`: the shrink of the
    pose mean's norm, 0.1 mg, that the calibrations here are judged at); a rate that turns the sensor through less
    over the time it is judged on moves no pose, however significant it is: a real gyro's bias (g-sensitivity, a
    step after a knock, the Earth's rate) differs from rest to rest by that much and more.
    """
    return np.asarray(np.asarray(rate_rad_s) * duration_s > np.sqrt(2.0 * WOBBLE_SHRINK) * multiplier)


#: Units in the last place, per summed sample, allowed for the rounding of a block's sums.
ROUNDING_ULPS: float = 8.0
#: Quantile of the pairs' squared changes taken as the quiet ones when the noise colour is first measured.
QUIET_PAIRS_QUANTILE: float = 0.25
#: Fewest pairs of calm blocks on which the noise colour is measured (else on the quietest pairs).
MIN_COLOUR_PAIRS: int = 8
#: Batch means over which a stretch's trend is tested (Brockwell & Davis' batch means: few enough that each
#: batch mean carries the noise of many samples, enough to measure their scatter: 8 leave 6 degrees of freedom).
TREND_BATCHES: int = 8
#: Fewest batches a trend test is made on (3 leave one degree of freedom for the scatter).
TREND_MIN_BATCHES: int = 4
#: Fewest independent samples (samples over the noise colour ``κ²``) of the accelerometer in a rest: two
#: independent means are the least that show that the mean does not move, against the range of the block
#: means (:meth:`optcal.data.rest_tests.RestModel.creeps`), which needs no estimate of the noise of the mean.
MIN_INDEPENDENT_ACC: float = 2.0
#: Fewest independent samples of the gyro in a rest where the gyro is evidence of motion: its mean rate is
#: tested against the noise of that mean (:meth:`optcal.data.rest_tests.RestModel.turns`), which a stretch
#: measures only over :data:`TREND_MIN_BATCHES` batches of at least one independent sample each.  A shorter
#: stretch lasts less than a few correlation times of its own rate noise: a hand's slow sway through it
#: cannot be told from a rest.
MIN_INDEPENDENT_GYRO: float = float(TREND_MIN_BATCHES)


@dataclass
class Blocks:
    """A recording cut into blocks of consecutive usable samples.

    Attributes
    ----------
    start, stop : ndarray of int
        Sample positions ``[start, stop)`` of each block (in the usable samples).
    n : ndarray of float
        Samples per block.
    mean, var : ndarray (nb, 3)
        Accelerometer mean and variance (``ddof=1``, plus ``q²/12``) per axis.
    gmean, gvar : ndarray (nb, 3) or None
        The same for the gyro.
    joined : ndarray of bool
        ``joined[k]``: block ``k`` follows block ``k − 1`` with no time gap between them.
    t_mid : ndarray of float
        Mid time of each block.
    var_ref : ndarray (nb, 3)
        The noise each block's mean is measured against (:func:`local_noise`; the block's own until set).
    """

    start: NDArray[np.int64]
    stop: NDArray[np.int64]
    n: NDArray[np.float64]
    mean: NDArray[np.float64]
    var: NDArray[np.float64]
    gmean: NDArray[np.float64] | None
    gvar: NDArray[np.float64] | None
    joined: NDArray[np.bool_]
    t_mid: NDArray[np.float64]
    var_ref: NDArray[np.float64]

    @property
    def count(self) -> int:
        return int(self.start.size)


def block_edges(m: int, block: int, breaks: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Start positions of blocks of about ``block`` samples over ``m`` samples, new segments at ``breaks``.

    Each segment between breaks is cut into ``max(1, L // block)`` blocks of equal length (± 1); the
    second array says which blocks continue the previous one without a break.
    """
    bounds = np.concatenate([[0], np.asarray(breaks, dtype=np.int64), [m]])
    starts: list[NDArray[np.int64]] = []
    joined: list[NDArray[np.bool_]] = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        length = int(b - a)
        if length <= 0:
            continue
        nb = max(1, length // block)
        s = a + (np.arange(nb) * length) // nb
        starts.append(s.astype(np.int64))
        j = np.ones(nb, dtype=bool)
        j[0] = False
        joined.append(j)
    return np.concatenate(starts), np.concatenate(joined)


#: Samples per piece of :func:`_block_moments`: the piece's rows (three columns, 1.5 MB) are read from memory once and
#: its deviations (512 KB) stay in the processor's cache through the sums, the extremes and the squares (a pass of
#: each over the whole column read the 12-hour log's 104 MB of samples three times per column).  Speed only.
BLOCK_PIECE: int = 1 << 16


def _block_moments(x: NDArray[np.float64], starts: NDArray[np.int64], n: NDArray[np.float64],
                   quant_var: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    m, k = x.shape[0], x.shape[1]
    s1 = np.empty((starts.size, k))
    s2 = np.empty((starts.size, k))
    centres = [median(x[:: max(1, m // 1000), j]) for j in range(k)]
    highs: list[list[float]] = [[] for _ in range(k)]
    lows: list[list[float]] = [[] for _ in range(k)]
    # pieces of whole blocks (a block's sums are the same whatever piece holds it; the starts increase, block_edges),
    # the first from sample 0; one buffer of the longest piece's length for the deviations, then their squares
    cuts = sorted({0, starts.size, *np.searchsorted(starts, np.arange(BLOCK_PIECE, m, BLOCK_PIECE)).tolist()})
    dev = np.empty(0)
    for i0, i1 in zip(cuts[:-1], cuts[1:]):
        a, z = (int(starts[i0]) if i0 else 0), (int(starts[i1]) if i1 < starts.size else m)
        if z - a > dev.size:
            dev = np.empty(z - a)
        at = starts[i0:i1] - a
        piece = x[a:z]
        for j in range(k):
            d = dev[: z - a]
            np.subtract(piece[:, j], centres[j], out=d)
            s1[i0:i1, j] = np.add.reduceat(d, at)
            if d.size:
                highs[j].append(d.max())
                lows[j].append(d.min())
            s2[i0:i1, j] = np.add.reduceat(np.multiply(d, d, out=d), at)
    mean, var = s1, s2  # each column's sums replaced by its moments in place (no two more arrays to fault in)
    for j in range(k):
        # the rounding of these sums: a noise-free rest shows this much spread, no less (else its blocks' log
        # variances, at the mercy of rounding, would differ by orders of magnitude)
        largest = max(float(np.max(highs[j])), -float(np.min(lows[j]))) if highs[j] else 0.0
        mu = s1[:, j] / n
        mean[:, j] = mu + centres[j]
        rounding = (ROUNDING_ULPS * np.finfo(float).eps * float(np.max(n)) * largest) ** 2
        var[:, j] = np.maximum(s2[:, j] - n * mu * mu, 0.0) / np.maximum(n - 1.0, 1.0) + quant_var + rounding
    return mean, var


def make_blocks(t: NDArray[np.float64], acc: NDArray[np.float64], gyro: NDArray[np.float64] | None, block: int,
                breaks: NDArray[np.int64], acc_quantum: float, gyro_quantum: float) -> Blocks:
    """Cut the samples into blocks (:func:`block_edges`) and reduce each to its mean and variance."""
    m = acc.shape[0]
    starts, joined = block_edges(m, block, breaks)
    stops = np.append(starts[1:], m)
    n = (stops - starts).astype(float)
    mean, var = _block_moments(acc, starts, n, acc_quantum**2 / 12.0)
    gmean = gvar = None
    if gyro is not None:
        gmean, gvar = _block_moments(gyro, starts, n, gyro_quantum**2 / 12.0)
    t_mid = 0.5 * (t[starts] + t[stops - 1])
    return Blocks(starts, stops, n, mean, var, gmean, gvar, joined, t_mid, var)


def local_noise(var: NDArray[np.float64], half_width: int) -> NDArray[np.float64]:
    """Per block and axis, the smallest block variance within ``half_width`` blocks on either side.

    The noise a block's mean is measured against.  A block's own variance will not do: a smooth
    motion (and any motion of a low-pass filtered recording) spreads a block's samples by its own
    slope, so that its change of mean looks like its noise.  A rest is one noise level for at least a
    dwell, so the quietest block near a block is its rest's noise, or a quieter neighbour's, which
    makes the test stricter, never more lenient; the minimum's low bias is absorbed by the noise
    colour, measured with the same statistic (:func:`noise_colour`).
    """
    out = var.copy()
    for shift in range(1, half_width + 1):
        out[shift:] = np.minimum(out[shift:], var[:-shift])
        out[:-shift] = np.minimum(out[:-shift], var[shift:])
    return out


def rounding_floor(var: NDArray[np.float64], quantum: float) -> NDArray[np.float64]:
    """Per axis, the variance a block mean keeps from the converter's rounding: ``q²/12`` where the signal's own
    noise is below the quantum, else 0.

    Rounding adds white noise of ``q²/12`` per sample, which a block mean averages down, only while the signal's
    own noise spans the quantum (Widrow's quantisation theorem: a standard deviation of half a quantum or
    more); a quieter signal (a filtered one, or a very quiet sensor) is rounded to the same few values over many
    samples, and its block means step by a fraction of a quantum as it drifts across a rounding edge.  The
    signal's own variance is the calm blocks' (the :data:`QUIET_PAIRS_QUANTILE` quantile) less ``q²/12``.
    """
    if quantum <= 0 or var.shape[0] == 0:
        return np.zeros(var.shape[1])
    q2 = quantum * quantum / 12.0
    own = column_quantile(var, QUIET_PAIRS_QUANTILE) - q2
    return np.where(own < 0.25 * quantum * quantum, q2, 0.0)


def pair_ratios(mean: NDArray[np.float64], var: NDArray[np.float64], n: NDArray[np.float64],
                floor: NDArray[np.float64] | float = 0.0) -> NDArray[np.float64]:
    """Per axis, the squared change between consecutive block means over its white-noise variance, each mean's
    rounding ``floor`` (:func:`rounding_floor`) added (nb − 1, 3)."""
    # column by column: in this numpy a (k,) or (3,) operand broadcast across an (nb, 3) array costs about ten
    # times the same arithmetic on a column; the same operations in the same order, so the same values
    inv = 1.0 / n[1:] + 1.0 / n[:-1]
    floor2 = np.broadcast_to(2.0 * np.asarray(floor), (mean.shape[1],))
    out = np.empty((max(mean.shape[0] - 1, 0), mean.shape[1]))
    for j in range(mean.shape[1]):
        d = np.diff(mean[:, j])
        scale = 0.5 * (var[1:, j] + var[:-1, j]) * inv + floor2[j]
        out[:, j] = d * d / np.maximum(scale, np.finfo(float).tiny)
    return out


def log_variance_steps(var: NDArray[np.float64]) -> NDArray[np.float64]:
    """``|ln(v_{k+1} / v_k)|`` of the total (summed over the axes) variance of consecutive blocks."""
    total = np.maximum(var.sum(axis=1), np.finfo(float).tiny)
    return np.asarray(np.abs(np.diff(np.log(total))))


def variance_step_limit(steps: NDArray[np.float64], false_alarm: float, samples: float) -> float:
    """The critical value of :func:`log_variance_steps` at rest, scaled from the pairs themselves.

    At rest the log-ratio of two variance estimates is close to normal with mean 0; its spread is taken
    from the pairs' median absolute value (most pairs lie inside rests; ``median |x| = 0.6745 σ`` for a
    normal ``x``), never below the white-noise ``√(4/(n − 1))`` of blocks of ``samples`` (their estimation
    noise alone; a tremor or a coloured noise spreads them more), and the critical value is the normal
    two-sided ``false_alarm`` quantile of that spread.
    """
    if steps.size == 0:
        return float("inf")
    white = float(np.sqrt(4.0 / max(samples - 1.0, 1.0)))
    spread = max(float(np_median(steps)) / 0.6744897501960817, white)
    return normal_limit(false_alarm / 2.0) * spread


def calm_pairs(var: NDArray[np.float64], valid: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Pairs of consecutive blocks both among the quietest :data:`QUIET_PAIRS_QUANTILE` of the blocks (total variance)."""
    total = var.sum(axis=1)
    calm = total <= column_quantile(total[:, None], QUIET_PAIRS_QUANTILE)[0]
    return np.asarray(valid & calm[1:] & calm[:-1])


def noise_colour(ratios: NDArray[np.float64], dof: float, quantile: float) -> NDArray[np.float64]:
    """``κ²`` per axis: the ``quantile`` of the pairs' ratios over the same quantile of ``F(1, dof)`` (at least 1)."""
    if ratios.shape[0] == 0:
        return np.ones(ratios.shape[1])
    expected = _f_ppf(quantile, 1.0, max(float(dof), 1.0))
    return np.asarray(np.maximum(column_quantile(ratios, quantile) / expected, 1.0))


@lru_cache(maxsize=256)
def _f_ppf(probability: float, d1: float, d2: float) -> float:
    """:func:`optcal.core.quantiles.f_ppf`, each (probability, d1, d2) computed once per process (a bisection of
    200 steps, about a millisecond; the rest model asks for the same few noise-colour quantiles several times)."""
    return quantiles.f_ppf(probability, d1, d2)


def step_statistic(ratios: NDArray[np.float64], kappa2: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Σ_j ratio_j / κ_j²`` of each consecutive pair: ``3 F(3, dof)`` at rest."""
    out = ratios[:, 0] / kappa2[0]
    for j in range(1, ratios.shape[1]):  # column by column, added in order (as the row sum of three): the same values
        out = out + ratios[:, j] / kappa2[j]
    return np.asarray(out)


@lru_cache(maxsize=4096)
def _f_isf(false_alarm: float, d1: float, d2: float) -> float:
    return quantiles.f_isf(false_alarm, d1, d2)


def step_limit_one(false_alarm: float, dof: float) -> float:
    """The ``1 − false_alarm`` quantile of ``3 F(3, dof)`` for one ``dof`` (at least 1)."""
    return 3.0 * _f_isf(false_alarm, 3.0, max(float(dof), 1.0))


def step_limit(false_alarm: float, dof: NDArray[np.float64] | float) -> NDArray[np.float64]:
    """:func:`step_limit_one` of each ``dof`` (each distinct dof computed once)."""
    d = np.maximum(np.asarray(dof, dtype=float), 1.0)
    unique, inverse = np.unique(d, return_inverse=True)
    values = np.array([step_limit_one(false_alarm, float(u)) for u in unique])
    return np.asarray(values[inverse].reshape(d.shape))


@lru_cache(maxsize=256)
def chi2_limit(false_alarm: float, dof: int) -> float:
    """The ``1 − false_alarm`` quantile of χ² with ``dof`` degrees of freedom."""
    return quantiles.chi2_isf(false_alarm, dof)


@lru_cache(maxsize=256)
def normal_limit(false_alarm: float) -> float:
    """The one-sided ``1 − false_alarm`` quantile of the standard normal."""
    return quantiles.norm_isf(false_alarm)


def column_half_sample_modes(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bickel & Frühwirth's half-sample mode of each column of ``x`` (n, m) of finite values: the densest half,
    halved until two or three values remain; the columns side by side (they halve in step)."""
    y = np.sort(np.asarray(x, dtype=float), axis=0)
    cols = np.arange(y.shape[1])
    while y.shape[0] > 3:
        h = (y.shape[0] + 1) // 2
        widths = y[h - 1:] - y[: y.shape[0] - h + 1]
        start = np.argmin(widths, axis=0)
        y = y[start[None, :] + np.arange(h)[:, None], cols]
    if y.shape[0] == 3:
        lower, upper = y[1] - y[0], y[2] - y[1]
        return np.where(lower < upper, 0.5 * (y[0] + y[1]), np.where(lower > upper, 0.5 * (y[1] + y[2]), y[1]))
    return np.asarray(y.mean(axis=0)) if y.shape[0] else np.full(y.shape[1], np.nan)


def windowed_half_sample_modes(x: NDArray[np.float64], lo: NDArray[np.intp], hi: NDArray[np.intp]
                               ) -> NDArray[np.float64]:
    """:func:`column_half_sample_modes` of ``x[lo[i]:hi[i]]`` (``x`` (n, m) of finite values) for every window ``i``
    at once (w, m): the windows' values sorted side by side, padded with +inf (never inside a densest half), and
    halved in step, each window by its own count; the same values and the same ties as one call per window."""
    x = np.asarray(x, dtype=float)
    lo, hi = np.asarray(lo, dtype=np.intp), np.asarray(hi, dtype=np.intp)
    w, m = lo.size, x.shape[1]
    counts = np.maximum(hi - lo, 0)
    if w == 0:
        return np.empty((0, m))
    width = int(counts.max()) if counts.size else 0
    if width == 0:
        return np.full((w, m), np.nan)
    at = np.arange(width)
    # one row per window and column: each column's values from the window's first, +inf past its count (and past the
    # data: the columns padded with +inf, so that every window is a view of them), sorted along the row
    padded = np.full((m, x.shape[0] + width), np.inf)
    padded[:, : x.shape[0]] = x.T
    y = np.ascontiguousarray(sliding_window_view(padded, width, axis=1)[:, lo].transpose(1, 0, 2))  # (w, m, width)
    np.copyto(y, np.inf, where=(at[None, :] >= counts[:, None])[:, None, :])
    y.sort(axis=2)
    y = y.reshape(w * m, width)
    n = np.repeat(counts, m)
    rows = np.arange(w * m)

    def runs_from(y: NDArray[np.float64], first: NDArray[np.intp], length: int) -> NDArray[np.float64]:
        """``y[i, first[i] + k]`` for ``k < length`` (+inf past the row's end), by rows of windows of ``y``: no index
        array of ``y``'s size.  What lies past a window's count is masked by the caller, as it was when clipped."""
        over = int((first + length).max()) - y.shape[1]
        if over > 0:  # only about windows of three values or fewer, which are not halved
            y = np.concatenate([y, np.full((y.shape[0], over), np.inf)], axis=1)
        return np.asarray(sliding_window_view(y, length, axis=1)[rows, first])

    while bool((n > 3).any()):
        halve = n > 3
        h = np.where(halve, (n + 1) // 2, n)
        span = int((n - h + 1)[halve].max())  # the densest half's possible starts
        j = np.arange(span)
        upper = runs_from(y, np.where(halve, h - 1, 0), span)  # y[i, j + h_i − 1] (a window not halved: unused)
        with np.errstate(invalid="ignore"):  # inf − inf beyond a window's values: masked below
            widths = np.where(j[None, :] <= (n - h)[:, None], upper - y[:, :span], np.inf)
        start = np.where(halve, np.argmin(widths, axis=1), 0)
        keep = int(h.max())
        k = np.arange(keep)
        y = runs_from(y, start, keep)
        np.copyto(y, np.inf, where=k[None, :] >= h[:, None])
        n = h
    out = np.full(n.size, np.nan)
    one, two, three = n == 1, n == 2, n == 3
    out[one] = y[one, 0]
    out[two] = 0.5 * (y[two, 0] + y[two, 1])
    if three.any():
        y3 = y[three, :3]
        lower, upper3 = y3[:, 1] - y3[:, 0], y3[:, 2] - y3[:, 1]
        out[three] = np.where(lower < upper3, 0.5 * (y3[:, 0] + y3[:, 1]),
                              np.where(lower > upper3, 0.5 * (y3[:, 1] + y3[:, 2]), y3[:, 1]))
    return out.reshape(w, m)


def half_sample_mode(x: NDArray[np.float64]) -> float:
    """Bickel & Frühwirth's half-sample mode of ``x``'s finite values (:func:`column_half_sample_modes`)."""
    y = np.asarray(x, dtype=float).ravel()
    return float(column_half_sample_modes(y[np.isfinite(y), None])[0])


@dataclass(frozen=True)
class SpanEstimates:
    """The gyro bias estimated over spans of :data:`BIAS_SPAN_S` a quarter span apart (:func:`span_estimates`).

    Attributes
    ----------
    whole : ndarray (3,)
        The whole recording's estimate.
    grid : ndarray (g,) or None
        The spans' centres (None: a recording shorter than a span, or fewer than three rates).
    local : ndarray (g, 3) or None
        Each span's estimate (the whole recording's where a span holds fewer than three rates).
    """

    whole: NDArray[np.float64]
    grid: NDArray[np.float64] | None
    local: NDArray[np.float64] | None


def span_estimates(t: NDArray[np.float64], rates: NDArray[np.float64],
                   estimate: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
                   step: float = BIAS_SPAN_S / 4.0) -> SpanEstimates:
    """Per axis, ``estimate`` (of the columns of a (k, 3) array; the half-sample mode by default) of the ``rates``
    (k, 3) at ``t`` (k,) over the whole recording and within :data:`BIAS_SPAN_S` centred on points ``step`` apart (a
    quarter span by default)."""
    estimate = estimate or column_half_sample_modes
    whole = np.asarray(estimate(rates), dtype=float) if t.size else np.zeros(3)
    if t.size < 3 or float(t[-1] - t[0]) <= BIAS_SPAN_S:
        return SpanEstimates(whole, None, None)
    grid = np.arange(float(t[0]), float(t[-1]) + step, step)
    lo = np.searchsorted(t, grid - BIAS_SPAN_S / 2.0)
    hi = np.searchsorted(t, grid + BIAS_SPAN_S / 2.0)
    if estimate is column_half_sample_modes:  # all the spans at once, the same values
        local = windowed_half_sample_modes(rates, lo, hi)
        local[hi - lo < 3] = whole
    else:
        local = np.array([estimate(rates[a:z]) if z - a >= 3 else whole for a, z in zip(lo, hi)])
    return SpanEstimates(whole, grid, local)


def follow_spans(spans: SpanEstimates, times: NDArray[np.float64], max_drift: float | None) -> NDArray[np.float64]:
    """The bias at ``times`` from :func:`span_estimates`: followed from the span nearest the whole recording's
    estimate with its change limited to ``max_drift`` per second, interpolated between the spans (constant, the
    whole recording's, without ``max_drift`` or spans)."""
    if max_drift is None or spans.grid is None or spans.local is None:
        return np.broadcast_to(spans.whole, (times.size, 3)).copy()
    grid, local = spans.grid, spans.local
    limit = max_drift * (float(grid[1] - grid[0]) if grid.size > 1 else BIAS_SPAN_S)
    track = np.empty_like(local)
    for j in range(3):
        values = local[:, j].tolist()  # Python floats: the walk is sequential, scalar numpy calls cost 20x more
        out = list(values)
        anchor = int(np.argmin(np.abs(local[:, j] - spans.whole[j])))
        for i in range(anchor + 1, grid.size):
            out[i] = min(max(values[i], out[i - 1] - limit), out[i - 1] + limit)
        for i in range(anchor - 1, -1, -1):
            out[i] = min(max(values[i], out[i + 1] - limit), out[i + 1] + limit)
        track[:, j] = out
    return np.column_stack([np.interp(times, grid, track[:, j]) for j in range(3)])


def bias_track(t: NDArray[np.float64], rates: NDArray[np.float64], times: NDArray[np.float64],
               max_drift: float | None, estimate: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None
               ) -> NDArray[np.float64]:
    """The gyro's bias at each of ``times`` (m,), from the ``rates`` (k, 3) of still blocks or rests at ``t`` (k,).

    Per axis, ``estimate`` (of the columns; the half-sample mode by default) of the rates within :data:`BIAS_SPAN_S` centred on
    points a quarter span apart, followed from the point nearest the whole recording's estimate with its change
    limited to ``max_drift`` (gyro units per second; :data:`MAX_BIAS_DRIFT_RAD_S2` in the gyro's units), and
    interpolated linearly between the points: a warming gyro's bias drifts through a session, a turn that
    dominates a span does not move it.  Without ``max_drift`` (a gyro in counts: no rate is known), a recording
    shorter than a span, or fewer than three rates: the whole recording's estimate, constant.
    (:func:`span_estimates`, then :func:`follow_spans`.)
    """
    if max_drift is None:
        whole = np.asarray((estimate or column_half_sample_modes)(rates), dtype=float) if t.size else np.zeros(3)
        return np.broadcast_to(whole, (times.size, 3)).copy()
    return follow_spans(span_estimates(t, rates, estimate), times, max_drift)


def gyro_statistic(gmean: NDArray[np.float64], gvar: NDArray[np.float64], n: NDArray[np.float64],
                   bias: NDArray[np.float64], kappa2: NDArray[np.float64], wander2: NDArray[np.float64],
                   floor: NDArray[np.float64] | float = 0.0) -> NDArray[np.float64]:
    """``Σ_j (ω̄_j − b_j)² / (κ_j² (v_j / n + f_j) + u_j²)`` of each block (``f``: the rounding floor of a block
    mean, :func:`rounding_floor`; the colour ``κ²`` is measured against the same white noise, :func:`pair_ratios`):
    ``3 F(3, n − 1)`` at rest."""
    # column by column, the axes' terms added in order (as ``sum(axis=1)`` adds three): :func:`pair_ratios`
    floor = np.broadcast_to(np.asarray(floor, dtype=float), (gmean.shape[1],))
    out = np.zeros(gmean.shape[0])  # no axis: zeros, as the empty sum
    for j in range(gmean.shape[1]):
        d = gmean[:, j] - bias[:, j]
        scale = kappa2[j] * (gvar[:, j] / n + floor[j]) + wander2[j]
        term = d * d / np.maximum(scale, np.finfo(float).tiny)
        out = term if j == 0 else out + term
    return out


@dataclass(frozen=True)
class Ranges:
    """Disjoint ranges ``[start, stop)`` of rows (of blocks), in order, and their rows concatenated.

    The tests of many stretches at once: a statistic of each range is a sum over its rows
    (:meth:`sums`, by :func:`numpy.add.reduceat` on the concatenated rows), and a value of each range is
    spread back to its rows by :attr:`owner`.
    """

    start: NDArray[np.intp]
    stop: NDArray[np.intp]
    rows: NDArray[np.intp]  # the rows of every range, concatenated
    owner: NDArray[np.intp]  # the range of each concatenated row
    offset: NDArray[np.intp]  # where each range begins among the concatenated rows

    @classmethod
    def of(cls, start: NDArray[np.intp] | list[int], stop: NDArray[np.intp] | list[int]) -> Ranges:
        a = np.asarray(start, dtype=np.intp)
        z = np.asarray(stop, dtype=np.intp)
        length = z - a
        if np.any(length < 1):
            raise ValueError("every range holds at least one row")
        offset = np.concatenate([[0], np.cumsum(length)[:-1]]).astype(np.intp)
        owner = np.repeat(np.arange(a.size, dtype=np.intp), length)
        rows = np.arange(int(length.sum()), dtype=np.intp) - offset[owner] + a[owner]
        return cls(a, z, rows, owner, offset)

    @property
    def length(self) -> NDArray[np.intp]:
        return np.asarray(self.stop - self.start)

    @property
    def count(self) -> int:
        return int(self.start.size)

    def sums(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Per range, the sum of ``x`` (given over the concatenated rows) along its first axis."""
        return np.asarray(np.add.reduceat(x, self.offset, axis=0))


def batch_ranges(r: Ranges, batches: NDArray[np.intp] | int, larger_first: bool = False) -> tuple[Ranges, NDArray[np.intp]]:
    """The batches of consecutive rows of each range: ``batches`` per range (at most its rows), sizes differing by
    one, spread evenly (batch ``i`` of ``k`` rows starts at row ``⌊i k / batches⌋``) or the larger first (as
    :func:`numpy.array_split`).  Returns the batches as ranges of the concatenated rows of ``r``, and each
    batch's range.  The tests each keep the grouping they were measured with: near its critical value a
    test's verdict depends on which blocks share a batch."""
    k = r.length
    nb = np.minimum(np.broadcast_to(np.asarray(batches, dtype=np.intp), k.shape), k)
    owner = np.repeat(np.arange(r.count, dtype=np.intp), nb)
    first = np.concatenate([[0], np.cumsum(nb)[:-1]]).astype(np.intp)
    i = np.arange(int(nb.sum()), dtype=np.intp) - first[owner]
    kb, nbb = k[owner], nb[owner]
    if larger_first:
        size, extra = kb // nbb, kb % nbb
        within = i * size + np.minimum(i, extra)
    else:
        within = (i * kb) // nbb
    start = r.offset[owner] + within
    stop = np.append(start[1:], int(r.length.sum()))  # the ranges are concatenated: a range's last batch ends at the next's first
    return Ranges.of(start, stop), owner


def trend_statistics(t: NDArray[np.float64], x: NDArray[np.float64], r: Ranges, batches: int = TREND_BATCHES
                     ) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`trend_statistic` of each range of rows ``r`` of ``t`` (nb,) and ``x`` (nb, 3): arrays of the
    largest |t|, its degrees of freedom, the fitted change and the range of the batch means."""
    nb = np.minimum(batches, r.length)
    bt, owner = batch_ranges(r, batches)
    sizes = bt.length.astype(float)
    tb = bt.sums(t[r.rows]) / sizes
    xb = bt.sums(x[r.rows]) / sizes[:, None]
    tc = tb - (_range_sums(tb, nb) / nb)[owner]
    xc = xb - (_range_sums(xb, nb) / nb[:, None])[owner]
    sxx = _range_sums(tc * tc, nb)
    tiny = np.finfo(float).tiny
    slope = _range_sums(tc[:, None] * xc, nb) / np.maximum(sxx, tiny)[:, None]
    resid = xc - tc[:, None] * slope[owner]
    s2 = _range_sums(resid * resid, nb) / np.maximum(nb - 2, 1)[:, None]
    se = np.sqrt(np.maximum(s2, tiny) / np.maximum(sxx, tiny)[:, None])
    tstat = np.max(np.abs(slope) / se, axis=1)
    change = np.linalg.norm(slope, axis=1) * (t[r.stop - 1] - t[r.start])
    first = np.concatenate([[0], np.cumsum(nb)[:-1]]).astype(np.intp)
    spread = np.linalg.norm(np.maximum.reduceat(xb, first, axis=0) - np.minimum.reduceat(xb, first, axis=0), axis=1)
    valid = (nb >= TREND_MIN_BATCHES) & (sxx > 0)
    zero = np.zeros(r.count)
    return (np.where(valid, tstat, zero), np.where(valid, nb - 2, 0), np.where(valid, change, zero),
            np.where(valid, spread, zero))


def _range_sums(x: NDArray[np.float64], counts: NDArray[np.intp]) -> NDArray[np.float64]:
    """Sums of ``x`` over consecutive groups of ``counts`` rows."""
    return np.asarray(np.add.reduceat(x, np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.intp), axis=0))


def trend_statistic(t: NDArray[np.float64], x: NDArray[np.float64],
                    batches: int = TREND_BATCHES) -> tuple[float, int, float, float]:
    """The largest |t| over the axes of the slope of ``x``'s batch means against time, and its degrees of freedom.

    ``x`` (k, 3) are the block means of a stretch, ``t`` their times; they are grouped into
    ``min(batches, k)`` batches of consecutive blocks, each batch's mean regressed on its time, and
    the slope divided by its standard error from the residual scatter (``batches − 2`` dof).
    Also returns the size of the fitted change over the stretch and the range of the batch means (norms
    over the axes).  Returns zeros for fewer than :data:`TREND_MIN_BATCHES` batches.  (One range of
    :func:`trend_statistics`.)
    """
    tstat, dof, change, spread = trend_statistics(t, x, Ranges.of([0], [x.shape[0]]), batches)
    return float(tstat[0]), int(dof[0]), float(change[0]), float(spread[0])


@lru_cache(maxsize=256)
def trend_limit(false_alarm: float, dof: int, axes: int = 3) -> float:
    """Two-sided Student ``t`` quantile at ``false_alarm`` shared over ``axes`` (Bonferroni)."""
    return quantiles.t_isf(false_alarm / (2 * axes), max(dof, 1))


def mean_shift_statistic(block_mean: NDArray[np.float64], block_var: NDArray[np.float64], n_block: float,
                         rest_mean: NDArray[np.float64], kappa2: NDArray[np.float64], n_rest: float,
                         floor: NDArray[np.float64] | float = 0.0) -> float:
    """A block's mean against the mean of the rest of its stretch, in units of their noise (each mean's rounding
    ``floor`` added, :func:`rounding_floor`): ``3 F(3, ·)`` at rest."""
    d = block_mean - rest_mean
    scale = kappa2 * (block_var * (1.0 / n_block + 1.0 / max(n_rest, 1.0)) + 2.0 * np.asarray(floor))
    return float((d * d / np.maximum(scale, np.finfo(float).tiny)).sum())
