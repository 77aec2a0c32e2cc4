"""The gyro's bias at rest as a real gyro's: a bias, its g-sensitivity and its steps after knocks.

:func:`fit_bias_model` fits :class:`BiasModel` to the rests' mean rates (the rest model's
:meth:`~optcal.data.rest_tests.RestModel._measure_wander`): the steps first, by binary segmentation of the rates in
time order (:func:`_steps`, kept where they persist), then ``b₀`` and ``G`` by Tukey's biweight, ``G`` kept by the
Bayesian information criterion within a MEMS gyro's range (:data:`MAX_G_SENSITIVITY_RAD_S_PER_G`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.data.quantiles import MAD_TO_SIGMA, column_mad_sigmas, column_medians
from optcal.data.rest_model import BIAS_SPAN_S, chi2_limit

#: Fewest rests on which the gyro's g-sensitivity is fitted (4 coefficients per axis: the bias and the three
#: terms of its row of ``G``, with as many rests again to judge them by).
MIN_RESTS_G_SENSITIVITY: int = 8
#: Fewest rests a bias step holds for: one rest off the others is a turn or a knock of its own, two or more that
#: agree after a move are the bias that stepped.
MIN_RESTS_PER_STEP: int = 2
#: Least time, s, the rests on either side of a bias step span: the bias track's resolution (its points lie a
#: quarter of :data:`BIAS_SPAN_S` apart).  A level the gyro holds for less, among rests, cannot be told from a slow
#: turn those rests took part in (cut into pieces by the accelerometer's steps), and a knock's step persists.
MIN_STEP_HOLD_S: float = BIAS_SPAN_S / 4.0
#: Split points a long segment's search tries first (then every point next to the best): the statistic changes
#: smoothly with the split point on either side of a step.
STEP_SEARCH_POINTS: int = 20
#: Most bias steps looked for in one session (a knock each; the binary segmentation stops earlier when a step
#: does not pay for its parameters).
MAX_BIAS_STEPS: int = 8
#: Largest g-sensitivity term a MEMS gyro has, rad/s per g (0.5 °/s/g: 2.5 times the worst datasheet figure,
#: 0.2 °/s/g).  A row of ``G`` fitted beyond it is not the gyro's: a turn about gravity, ``ω = ψ̇ f̂``, reads as
#: ``G = ψ̇ I`` in the rests it happens in, and it is a turn.
MAX_G_SENSITIVITY_RAD_S_PER_G: float = float(np.radians(0.5))
#: Tukey's biweight constant (95 % efficiency at the normal): the rests whose mean rate is this many robust
#: standard deviations off the model weigh nothing in the fit (a slow turn the accelerometer did not see).
BIWEIGHT_C: float = 4.685


@dataclass(frozen=True)
class BiasModel:
    """A real gyro's bias at rest (Tedaldi et al. 2014 §III; datasheets' g-sensitivity): ``b(t, f) = b₀ + G f̂ +
    s(t)``, fitted to the rests' mean rates.

    Attributes
    ----------
    b0 : ndarray (3,)
        The bias, gyro units.
    g_sensitivity : ndarray (3, 3)
        ``G``: the rate error per unit specific force direction (gyro units per g; zero where the rests do not
        pay for it by the Bayesian information criterion).
    step_times : ndarray (k,)
        Where the bias steps (between two rests: the knock is in the move).
    step_levels : ndarray (k + 1, 3)
        The bias' offset from ``b₀`` between the steps.
    residual_scatter : ndarray (3,)
        Robust standard deviation of the rests' mean rates about the model.
    """

    b0: NDArray[np.float64]
    g_sensitivity: NDArray[np.float64]
    step_times: NDArray[np.float64]
    step_levels: NDArray[np.float64]
    residual_scatter: NDArray[np.float64]

    def at(self, t: NDArray[np.float64], direction: NDArray[np.float64]) -> NDArray[np.float64]:
        """The bias at times ``t`` (m,) with the specific force's unit ``direction`` (m, 3) (gyro units)."""
        level = self.step_levels[_segment_of(t, self.step_times)]
        return np.asarray(self.b0 + direction @ self.g_sensitivity.T + level)


def _weighted_solve(x: NDArray[np.float64], y: NDArray[np.float64], w: NDArray[np.float64],
                    fallback: NDArray[np.float64]) -> NDArray[np.float64]:
    """Weighted least squares of each column of ``y`` (n, m) on ``x`` (n, p) with that column's weights ``w`` (n, m),
    all columns by one batched solve of the normal equations (p, m); a column with fewer than ``p`` weighted rows, or
    whose equations are singular, keeps its ``fallback``."""
    xw = np.einsum("np,nj->jpn", x, w)
    a = xw @ x
    b = np.einsum("jpn,nj->jp", xw, y)
    out = np.array(fallback, dtype=float, copy=True)
    ok = np.count_nonzero(w, axis=0) >= x.shape[1]
    try:
        out[:, ok] = np.linalg.solve(a[ok], b[ok][..., None])[..., 0].T
    except np.linalg.LinAlgError:
        for j in np.flatnonzero(ok):
            sw = np.sqrt(w[:, j])
            out[:, j] = np.linalg.lstsq(x * sw[:, None], y[:, j] * sw, rcond=None)[0]
    return out


#: A biweight iteration that moves no coefficient by more than this share of its standard error has converged: the
#: next ones would change the bias model by less than any test of it can see.
BIWEIGHT_TOLERANCE_SE: float = 1e-4


def _biweight_fit(x: NDArray[np.float64], y: NDArray[np.float64], iterations: int = 20) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Tukey-biweight regression of each column of ``y`` (n, 3) on ``x`` (n, p): coefficients (p, 3), weights (n, 3).

    Iteratively reweighted least squares from the ordinary fit, until no coefficient moves by more than
    :data:`BIWEIGHT_TOLERANCE_SE` of its standard error (the residuals' robust scale through ``(XᵀX)⁻¹``)."""
    coef = np.asarray(np.linalg.lstsq(x, y, rcond=None)[0], dtype=float)
    w = np.ones_like(y)
    smallest = np.finfo(float).eps * np.maximum(np.abs(y).max(axis=0), 1.0)  # a scale at the data's own rounding
    intercept = x.shape[1] == 1 and bool(np.all(x == 1.0))
    try:
        leverage = np.sqrt(np.diag(np.linalg.inv(x.T @ x)))[:, None]  # a coefficient's SE per unit residual scale
    except np.linalg.LinAlgError:
        leverage = np.zeros((x.shape[1], 1))  # singular: converged only when nothing moves
    for _ in range(iterations):
        r = y - x @ coef
        scale = np.maximum(column_mad_sigmas(r), smallest)
        u = r / (BIWEIGHT_C * scale)
        w = np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)
        if intercept:  # a weighted mean per column
            total = w.sum(axis=0)
            new = np.where(total > 0.0, (w * y).sum(axis=0) / np.where(total > 0.0, total, 1.0), coef[0])[None, :]
        else:
            new = _weighted_solve(x, y, w, coef)
        moved = np.abs(new - coef)
        coef = new
        if bool(np.all(moved <= BIWEIGHT_TOLERANCE_SE * leverage * scale)):
            break
    return np.asarray(coef, dtype=float), np.asarray(w, dtype=float)


def _robust_ss(r: NDArray[np.float64]) -> float:
    """A robust sum of squares of ``r`` (k, m) about its median: ``k`` times the squared MAD-σ, summed over the columns."""
    if r.shape[0] == 0:
        return 0.0
    return float(r.shape[0] * np.sum(column_mad_sigmas(r) ** 2))


def _segment_of(t: NDArray[np.float64], cut_times: NDArray[np.float64]) -> NDArray[np.intp]:
    """The segment between bias steps (at ``cut_times``) of each time ``t``."""
    return np.asarray(np.searchsorted(cut_times, t, side="right"), dtype=np.intp)


def _levels(r: NDArray[np.float64], cuts: list[int]) -> NDArray[np.float64]:
    """The median of ``r`` (k, 3) over each segment between the ``cuts`` (indices) (segments, 3)."""
    edges = [0, *cuts, r.shape[0]]
    return np.array([column_medians(r[a:z]) for a, z in zip(edges[:-1], edges[1:])])


def _median_difference(left: NDArray[np.float64], right: NDArray[np.float64], noise2: NDArray[np.float64]) -> float:
    """χ² of the difference of the column medians of ``left`` and ``right`` over their variances (a median's:
    ``π/2`` times the larger of the robust variance and ``noise2``, over the count)."""
    d = column_medians(left) - column_medians(right)
    v = sum((np.pi / 2.0) * np.maximum(column_mad_sigmas(side) ** 2, noise2) / side.shape[0] for side in (left, right))
    return float(np.sum(d * d / np.maximum(v, np.finfo(float).tiny)))


def _padded_medians(x: NDArray[np.float64], lengths: NDArray[np.intp]) -> NDArray[np.float64]:
    """The column medians of each of ``K`` samples stacked in ``x`` (K, L, m), sample ``i`` in its first
    ``lengths[i]`` rows and ``+inf`` below them (as :func:`~optcal.data.quantiles.column_medians` of each)."""
    s = np.sort(x, axis=1)
    k = np.arange(x.shape[0])
    return np.asarray(0.5 * (s[k, (lengths - 1) // 2] + s[k, lengths // 2]))


def _split_statistics(r: NDArray[np.float64], a: int, z: int, ks: NDArray[np.intp],
                      noise2: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_median_difference` of ``r[a:k]`` and ``r[k:z]`` for each split ``k`` of ``ks``, all splits at once
    (each side stacked with ``+inf`` padding, its medians and MADs by one sort)."""
    span = np.arange(z - a)
    sides = []
    for lengths, first in ((ks - a, np.full(ks.size, a)), (z - ks, ks)):
        idx = first[:, None] + span[None, :]
        inside = span[None, :] < lengths[:, None]
        x = np.where(inside[..., None], r[np.minimum(idx, z - 1)], np.inf)
        med = _padded_medians(x, lengths)
        mad = MAD_TO_SIGMA * _padded_medians(np.where(inside[..., None], np.abs(x - med[:, None, :]), np.inf), lengths)
        sides.append((med, (np.pi / 2.0) * np.maximum(mad * mad, noise2) / lengths[:, None]))
    (m0, v0), (m1, v1) = sides
    d = m0 - m1
    return np.asarray(np.sum(d * d / np.maximum(v0 + v1, np.finfo(float).tiny), axis=1))


def _steps(t: NDArray[np.float64], r: NDArray[np.float64], noise2: NDArray[np.float64]) -> list[int]:
    """Indices where the rests' residual rates ``r`` (k, 3; time order) step, by binary segmentation.

    A split of a segment is kept when its two sides' medians differ by more than their noise can (χ²₃ of the
    difference over the sides' robust variances of their medians, at the Bonferroni share of 1 % over the possible
    split points), each side holding at least :data:`MIN_RESTS_PER_STEP` rests (a persistent change, which one rest
    that turned cannot make) and spanning at least :data:`MIN_STEP_HOLD_S`.  A long segment's splits are tried on
    :data:`STEP_SEARCH_POINTS` points first, then at every point next to the best.
    """
    out: list[int] = []
    queue = [(0, r.shape[0])]
    while queue and len(out) < MAX_BIAS_STEPS:
        a, z = queue.pop()
        if z - a < 2 * MIN_RESTS_PER_STEP:
            continue
        ks = np.arange(a + MIN_RESTS_PER_STEP, z - MIN_RESTS_PER_STEP + 1)
        ks = ks[(t[ks - 1] - t[a] >= MIN_STEP_HOLD_S) & (t[z - 1] - t[ks] >= MIN_STEP_HOLD_S)]
        if not ks.size:
            continue
        stride = max(1, ks.size // STEP_SEARCH_POINTS)
        coarse = ks[::stride]
        values = _split_statistics(r, a, z, coarse, noise2)
        centre = int(coarse[int(np.argmax(values))])
        near = ks[(ks > centre - stride) & (ks < centre + stride) & ~np.isin(ks, coarse)]
        if near.size:
            coarse = np.concatenate([coarse, near])
            values = np.concatenate([values, _split_statistics(r, a, z, near, noise2)])
        stats = dict(zip(coarse.tolist(), values.tolist()))
        best = max(stats, key=lambda k: stats[k])
        points = max(z - a - 2 * MIN_RESTS_PER_STEP + 1, 1)
        if stats[best] > chi2_limit(0.01 / points, 3):
            out.append(best)
            queue += [(a, best), (best, z)]
    return _persistent(t, r, noise2, sorted(out))


def _persistent(t: NDArray[np.float64], r: NDArray[np.float64], noise2: NDArray[np.float64], cuts: list[int]) -> list[int]:
    """The ``cuts`` less the pairs whose bias comes back within :data:`BIAS_SPAN_S`: a knock's step persists, and a
    level that returns to the one before it within a span is a turn the rests between took part in (a slow turn cut
    into pieces by the accelerometer's steps), not the bias."""
    out = list(cuts)
    changed = True
    while changed and len(out) >= 2:
        changed = False
        edges = [0, *out, r.shape[0]]
        for i in range(len(out) - 1):
            before, after = r[edges[i]:edges[i + 1]], r[edges[i + 2]:edges[i + 3]]
            if t[edges[i + 2]] - t[edges[i + 1]] >= BIAS_SPAN_S:
                continue
            if _median_difference(before, after, noise2) <= chi2_limit(0.01, 3):
                del out[i:i + 2]
                changed = True
                break
    return out


def fit_bias_model(t: NDArray[np.float64], direction: NDArray[np.float64], rates: NDArray[np.float64],
                   noise2: NDArray[np.float64], g_limit: float | None = None) -> BiasModel:
    """Fit :class:`BiasModel` to the rests' mean ``rates`` (k, 3) at times ``t`` (k,) with their specific force's
    unit ``direction`` (k, 3) and each mean's noise variance ``noise2`` (k, 3).

    The bias steps first (:func:`_steps`, on the rates less their median), then ``b₀`` and ``G`` by Tukey's biweight
    on the rates less the steps; ``G`` is kept when the Bayesian information criterion of the robust residuals
    prefers it (its three terms per axis must explain more of the rests' scatter than ``3 ln k`` pays for) and the
    directions span the sphere (the smallest singular value of the centred directions above a tenth: otherwise a
    rest set about one axis, whose ``G`` is not determined), and no term of its row exceeds ``g_limit`` (gyro units
    per g: :data:`MAX_G_SENSITIVITY_RAD_S_PER_G` in the gyro's unit; without it, a gyro whose unit is unknown, no
    ``G`` is fitted).  Without :data:`MIN_RESTS_G_SENSITIVITY` rests: the
    median and the steps only.
    """
    k = rates.shape[0]
    zero = np.zeros(3)
    if k == 0:
        return BiasModel(zero, np.zeros((3, 3)), np.zeros(0), np.zeros((1, 3)), zero)
    order = np.argsort(t)
    t, direction, rates, noise2 = t[order], direction[order], rates[order], noise2[order]
    floor = column_medians(noise2)

    cuts = _steps(t, rates - column_medians(rates), floor)
    ones = np.ones((k, 1))
    g = np.zeros((3, 3))
    b0 = np.zeros(3)
    for _ in range(3):  # the steps, and b₀ and G, each on the rates less the other
        cut_times = np.array([0.5 * (t[c - 1] + t[c]) for c in cuts])
        levels = _levels(rates - direction @ g.T, cuts)
        y = rates - (levels - levels[0])[_segment_of(t, cut_times)]
        b0 = _biweight_fit(ones, y)[0][0]
        g = np.zeros((3, 3))
        if k >= MIN_RESTS_G_SENSITIVITY and g_limit is not None:
            centred = direction - direction.mean(axis=0)
            if np.linalg.svd(centred / np.sqrt(k), compute_uv=False)[-1] > 0.1:
                x = np.column_stack([ones, direction])
                coef = _biweight_fit(x, y)[0]
                ss0 = np.array([_robust_ss((y - b0)[:, [j]]) for j in range(3)])
                ss1 = np.array([_robust_ss((y - x @ coef)[:, [j]]) for j in range(3)])
                tiny = np.finfo(float).tiny
                bic0 = k * np.log(np.maximum(ss0 / k + floor, tiny))
                bic1 = k * np.log(np.maximum(ss1 / k + floor, tiny)) + 3.0 * np.log(k)
                keep = (bic1 < bic0) & np.all(np.abs(coef[1:]) <= g_limit, axis=0)
                g = np.where(keep[:, None], coef[1:].T, 0.0)
                b0 = np.where(keep, coef[0], b0)
        new_cuts = _steps(t, rates - direction @ g.T - b0, floor)
        if new_cuts == cuts:
            break
        cuts = new_cuts
    cut_times = np.array([0.5 * (t[c - 1] + t[c]) for c in cuts])
    levels = _levels(rates - direction @ g.T - b0, cuts)
    model = BiasModel(np.asarray(b0, float), g, cut_times, levels, zero)
    scatter = column_mad_sigmas(rates - model.at(t, direction))
    return BiasModel(model.b0, g, cut_times, levels, scatter)
