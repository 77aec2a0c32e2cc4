"""Upper quantiles of the F, χ², Student t and normal distributions, without scipy.

The rest model (:mod:`optcal.data.rest_model`) sets each test's critical value at a quantile of its
distribution at rest.  ``scipy.stats`` (or even ``scipy.special``) would add 0.25-0.8 s to the start of every
command that reads a recording, more than the whole calibration of a recording takes; these few quantiles are
computed here from the regularized incomplete beta and gamma functions (Numerical Recipes, 3rd ed., §6.2 and
§6.4: their continued fractions by the modified Lentz method), each inverted by bisection on the logarithm of
its argument to the double precision's resolution.  The tests check them against ``scipy.stats`` (relative
error below 10⁻¹⁰).
"""

from __future__ import annotations

import math
from collections.abc import Callable


def _c_inv_cdf() -> Callable[[float, float, float], float] | None:
    """CPython's C form of ``statistics.NormalDist.inv_cdf`` (the function it calls), or None on another Python: no
    import of :mod:`statistics`, which brings fractions, decimal and random with it (5 ms of every command's start)."""
    try:
        from _statistics import _normal_dist_inv_cdf
    except ImportError:
        return None
    return _normal_dist_inv_cdf


_normal_dist_inv_cdf = _c_inv_cdf()

_EPS = 1e-16
_TINY = 1e-300
_MAX_TERMS = 10_000
_BISECTIONS = 200


def _beta_fraction(a: float, b: float, x: float) -> float:
    """The continued fraction of the incomplete beta function (NR eq. 6.4.5), by the modified Lentz method."""
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > _TINY else _TINY)
    h = d
    for m in range(1, _MAX_TERMS):
        m2 = 2 * m
        for aa in (m * (b - m) * x / ((qam + m2) * (a + m2)), -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))):
            d = 1.0 + aa * d
            d = 1.0 / (d if abs(d) > _TINY else _TINY)
            c = 1.0 + aa / c
            c = c if abs(c) > _TINY else _TINY
            h *= d * c
        if abs(d * c - 1.0) < _EPS:
            break
    return h


def beta_lower(a: float, b: float, x: float) -> float:
    """The regularized incomplete beta function ``I_x(a, b)`` (NR eq. 6.4.1)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = math.exp(math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _beta_fraction(a, b, x) / a
    return 1.0 - front * _beta_fraction(b, a, 1.0 - x) / b


def gamma_upper(a: float, x: float) -> float:
    """The regularized upper incomplete gamma function ``Q(a, x)`` (NR §6.2: the series below ``a + 1``, the
    continued fraction above)."""
    if x <= 0.0:
        return 1.0
    front = math.exp(-x + a * math.log(x) - math.lgamma(a))
    if x < a + 1.0:
        term = total = 1.0 / a
        ap = a
        for _ in range(_MAX_TERMS):
            ap += 1.0
            term *= x / ap
            total += term
            if abs(term) < abs(total) * _EPS:
                break
        return 1.0 - front * total
    b = x + 1.0 - a
    c, d = 1.0 / _TINY, 1.0 / b
    h = d
    for i in range(1, _MAX_TERMS):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = b + an / c
        c = c if abs(c) > _TINY else _TINY
        h *= d * c
        if abs(d * c - 1.0) < _EPS:
            break
    return front * h


def _solve_log(tail: Callable[[float], float], log_slope: Callable[[float], float], p: float,
               lo: float, hi: float, start: float | None = None) -> float:
    """The ``s`` in ``[lo, hi]`` where the increasing ``tail(s)`` equals ``p``: Newton's steps where they stay inside
    the bracket and shrink it fast enough, bisection otherwise (NR §9.4, ``rtsafe``), from ``start`` (the bracket's
    middle by default).  ``log_slope(s)`` is the logarithm of ``tail``'s derivative at ``s``."""
    s = 0.5 * (lo + hi) if start is None or not lo < start < hi else start
    step_before = step = hi - lo
    for _ in range(_BISECTIONS):
        value = tail(s) - p
        if value == 0.0:
            return s
        if value < 0.0:
            lo = s
        else:
            hi = s
        slope = math.exp(min(log_slope(s), 700.0))
        newton = s - value / slope if slope > 0.0 else math.nan
        if lo < newton < hi and abs(2.0 * (s - newton)) < abs(step_before):
            step_before, step = step, s - newton
            s = newton
        else:
            step_before = step = 0.5 * (hi - lo)
            s = 0.5 * (lo + hi)
        if abs(step) < 4.0 * _EPS * max(1.0, abs(s)) or hi - lo < 4.0 * _EPS * max(1.0, abs(s)):
            return s
    return s


def _log_beta(a: float, b: float) -> float:
    return math.lgamma(a) + math.lgamma(b) - math.lgamma(a + b)


def _check(p: float) -> None:
    if not 0.0 < p < 1.0:
        raise ValueError(f"a tail probability lies in (0, 1), got {p}")


def f_isf(p: float, d1: float, d2: float) -> float:
    """The ``1 − p`` quantile of Snedecor's F with ``(d1, d2)`` degrees of freedom.

    ``P(F > f) = I_y(d2/2, d1/2)`` with ``y = d2 / (d2 + d1 f)`` (NR eq. 6.14.49), solved for ``y``, which is
    small where ``f`` is large, so that no precision is lost to ``1 − y``.
    """
    _check(p)
    a, b = 0.5 * d2, 0.5 * d1
    log_b = _log_beta(a, b)
    # in log y: I_y(a, b) increases with y; its derivative is y^a (1 − y)^(b − 1) / B(a, b)
    log_y = _solve_log(lambda v: beta_lower(a, b, math.exp(v)),
                       lambda v: a * v + (b - 1.0) * math.log1p(-min(math.exp(v), 1.0 - _EPS)) - log_b,
                       p, math.log(_TINY), 0.0)
    y = math.exp(log_y)
    return d2 * (1.0 - y) / (d1 * y)


def f_ppf(q: float, d1: float, d2: float) -> float:
    """The ``q`` quantile of Snedecor's F with ``(d1, d2)`` degrees of freedom."""
    return f_isf(1.0 - q, d1, d2)


def chi2_isf(p: float, dof: float) -> float:
    """The ``1 − p`` quantile of χ² with ``dof`` degrees of freedom: ``Q(dof/2, x/2) = p``."""
    _check(p)
    a = 0.5 * dof
    # Newton's steps from the Wilson-Hilferty approximation (x/dof)^(1/3) ~ N(1 - 2/(9 dof), 2/(9 dof)), within
    # a few per cent of the root: a few steps where the bracket's middle took dozens
    c = 2.0 / (9.0 * dof)
    guess = dof * (1.0 - c + norm_isf(p) * math.sqrt(c)) ** 3 if 0.0 < p < 1.0 else 0.0
    # in log h (h = x/2): −Q(a, h) increases with h; its derivative is h^a e^(−h) / Γ(a)
    log_h = _solve_log(lambda v: -gamma_upper(a, math.exp(v)), lambda v: a * v - math.exp(v) - math.lgamma(a),
                       -p, math.log(_TINY), math.log(1e300), math.log(0.5 * guess) if guess > 0.0 else None)
    return 2.0 * math.exp(log_h)


def t_isf(p: float, dof: float) -> float:
    """The ``1 − p`` quantile of Student's t with ``dof`` degrees of freedom (``t² ~ F(1, dof)``)."""
    _check(p)
    if p >= 0.5:
        return -t_isf(1.0 - p, dof) if p > 0.5 else 0.0
    return math.sqrt(f_isf(2.0 * p, 1.0, dof))


def norm_isf(p: float) -> float:
    """The ``1 − p`` quantile of the standard normal."""
    _check(p)
    if _normal_dist_inv_cdf is not None and 0.0 < p < 1.0:
        return float(-_normal_dist_inv_cdf(p, 0.0, 1.0))
    from statistics import NormalDist

    return -NormalDist().inv_cdf(p)


#: From this shape ``a = dof/2`` on, :func:`chi2_ppf` sums the series of ``P(a, x)`` in one numpy pass and takes
#: ``ln Γ(a + 1)`` from Stirling's series: :func:`gamma_upper`'s loop of at most 10,000 terms stops short of the
#: ``~9 √a`` terms the series needs near ``x = a`` for ``a`` above about 10⁶ (an overlapping Allan variance of a
#: 12-hour 100-Hz log at τ_0 has about 4·10⁶ degrees of freedom), and its ``ln Γ(a)`` loses ``a ln a · 10⁻¹⁶`` of
#: the logarithm there.  At 10³ Stirling's series stopped after the ``a⁻⁵`` term is exact to ``10⁻²⁵``.
_LARGE_SHAPE = 1e3


def _log_gamma_front(a: float, x: float) -> float:
    """``ln(x^a e^(−x) / Γ(a + 1))`` for ``a ≥`` :data:`_LARGE_SHAPE`, without the cancellation of ``a ln x``
    against ``ln Γ(a + 1)``: ``a (ln(1 + u) − u) − ½ ln(2πa) − c(a)`` with ``u = (x − a)/a`` and ``c`` Stirling's
    correction ``1/(12a) − 1/(360a³) + 1/(1260a⁵)`` (DLMF 5.11.1)."""
    u = (x - a) / a
    stirling = 1.0 / (12.0 * a) - 1.0 / (360.0 * a**3) + 1.0 / (1260.0 * a**5)
    # far below a (where P is nil anyway) ln(x/a) directly: 1 + u rounds to 0 near x = 0
    log_ratio = math.log1p(u) - u if u > -0.5 else math.log(x / a) - u
    return a * log_ratio - 0.5 * math.log(2.0 * math.pi * a) - stirling


def _gamma_lower_large(a: float, x: float) -> float:
    """The regularized lower incomplete gamma function ``P(a, x)`` for ``a ≥`` :data:`_LARGE_SHAPE` from its series
    ``x^a e^(−x) / Γ(a + 1) · Σ_k x^k / ((a + 1)…(a + k))`` (NR eq. 6.2.5), the terms as one cumulative product
    until they fall below the double precision's resolution of the sum (past ``k = x − a`` they fall like
    ``exp(−k²/2a)``: ``12 √x`` terms more reach ``e^(−72)``)."""
    import numpy as np

    # beyond 40 standard deviations of the Gamma(a) distribution from its mean a, P is 0 or 1 to the double
    # precision (a tail of exp(−z²/2) at most: e^(−800)), and the series would need x − a terms
    z = (x - a) / math.sqrt(a)
    if z < -40.0:
        return 0.0
    if z > 40.0:
        return 1.0
    terms = int(max(x - a, 0.0) + 12.0 * math.sqrt(x) + 64.0)
    # the terms' logarithms, scaled by the largest (above a they first grow, to e^(z²/2) at k = x − a)
    logs = np.cumsum(np.log(x / (a + np.arange(1.0, terms + 1.0))))
    peak = max(0.0, float(np.max(logs)))
    series = np.exp(logs - peak)
    total = math.exp(-peak) + float(np.sum(series))
    if series[-1] > _EPS * total:  # not reached with the count above; kept so that a short sum cannot pass unseen
        raise ArithmeticError(f"the incomplete gamma series did not converge (a={a}, x={x})")
    return min(1.0, math.exp(_log_gamma_front(a, x) + peak) * total)


def chi2_ppf(q: float, dof: float) -> float:
    """The ``q`` quantile of χ² with ``dof`` degrees of freedom: ``P(dof/2, x/2) = q``, for any ``dof > 0``.

    Below ``dof = 2·``:data:`_LARGE_SHAPE` it is :func:`chi2_isf` of ``1 − q``; above, the lower incomplete gamma
    function's series summed in one numpy pass (:func:`_gamma_lower_large`), inverted by Newton's steps from the
    Wilson-Hilferty guess, safeguarded by bisection.  The tests check it against ``scipy.stats.chi2``
    (relative error below 10⁻¹⁰ up to 10⁸ degrees of freedom).
    """
    _check(q)
    if not dof > 0.0:
        raise ValueError(f"χ² has a positive number of degrees of freedom, got {dof}")
    a = 0.5 * dof
    if a < _LARGE_SHAPE:
        return chi2_isf(1.0 - q, dof)
    c = 2.0 / (9.0 * dof)
    h = 0.5 * dof * max(1.0 - c - norm_isf(q) * math.sqrt(c), 0.5) ** 3  # Wilson-Hilferty, within 10⁻⁴ here
    # Newton's steps on P(a, h) = q (its derivative h^(a−1) e^(−h) / Γ(a)) inside the bracket of the signs seen,
    # halving where a step would leave it: two or three steps from the guess (the sum's rounding, about 10⁻¹⁴ of P,
    # would keep smaller steps wandering)
    lo, hi = 0.0, math.inf
    for _ in range(_BISECTIONS):
        value = _gamma_lower_large(a, h) - q
        if value == 0.0:
            break
        if value < 0.0:
            lo = h
        else:
            hi = h
        log_slope = math.log(a / h) + _log_gamma_front(a, h)
        new = h - value * math.exp(-log_slope) if log_slope > -700.0 else math.nan
        if not lo < new < hi:
            new = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * h
        if abs(new - h) <= 1e-10 * h:  # Newton's error after a step this small is about its square: the last step
            h = new
            break
        h = new
    return 2.0 * h
