"""Power-law noise identification and the uncertainty of an Allan variance, without scipy or allantools.

Three published algorithms, written from the papers (the project's reference peer, allantools, implements the same
ones; the tests compare them):

* **Noise identification by the lag-1 autocorrelation** (Riley & Greenhall 2004, "Power law noise identification
  using the lag 1 autocorrelation", EFTF 2004).  The phase, taken every ``m`` samples (τ = m τ_0) and rid of a
  quadratic (a frequency offset and drift), is differenced ``d`` times until it is stationary: its lag-1
  autocorrelation ``r1`` (eq. 2) gives ``δ = r1 / (1 + r1)`` (eq. 5), stationary below ``δ = 1/4``; the power law of
  the phase is then ``p = −2 (δ + d)`` and of the frequency ``α = p + 2`` (S_y ∝ f^α), rounded to an integer
  (:func:`lag1_noise_id`).
* **Equivalent degrees of freedom** of an overlapping or non-overlapping Allan (``d = 2``), first-difference
  (``d = 1``) or Hadamard (``d = 3``) variance of unmodified form (Greenhall & Riley 2003, "Uncertainty of
  stability variances based on finite differences", PTTI 2003, section 4 and its algorithm): the estimator's
  variance as a sum of the squared autocovariances ``sz`` of the phase's ``d``-th difference (eqs. 7-10), summed
  exactly while it has at most ``J_max = 100`` terms and read from the paper's large-``m`` coefficients (its
  Tables 2 and 3) beyond (:func:`greenhall_edf`).
* **χ² confidence intervals**: ``edf · σ̂² / σ²`` is χ² with ``edf`` degrees of freedom (NIST SP 1065, Riley 2008,
  section 5.3, eq. 45), so the two-sided interval at level ``c`` is ``σ̂ √(edf / χ²_{1−p})`` to ``σ̂ √(edf / χ²_p)``
  with ``p = (1 − c)/2`` (:func:`chi2_interval`; quantiles from :mod:`optcal.core.quantiles`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.core.quantiles import chi2_ppf

#: The probability within one standard deviation of a normal mean, ``erf(1/√2)``: the "one-sigma" level of an
#: interval (NIST SP 1065, section 5.3).
ONE_SIGMA: float = math.erf(1.0 / math.sqrt(2.0))

#: Riley & Greenhall 2004, section 4: a series differenced until ``δ`` is below 1/4 is stationary (a fractionally
#: integrated noise ``(2 sin πf)^(−2δ)`` is stationary for ``δ < 1/4``).
STATIONARY_DELTA: float = 0.25
#: Riley & Greenhall 2004, section 5: the lag-1 autocorrelation identifies the noise from about 30 points on.
NOISE_ID_MIN_POINTS: int = 30
#: Greenhall & Riley 2003, algorithm: the sum of eq. 10 is evaluated exactly up to this many terms.
J_MAX: int = 100

# Greenhall & Riley 2003, Table 2: (a0, a1) of 1/edf ≈ (a0 − a1/r)/r for unmodified variances at large m, by the
# noise exponent α (rows) and the difference order d = 1, 2, 3 (columns); None where α + 2d ≤ 1 (no such variance)
_TABLE2: dict[int, tuple[tuple[float, float] | None, ...]] = {
    1: ((78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)),
    0: ((2.0 / 3.0, 1.0 / 6.0), (2.0 / 3.0, 1.0 / 3.0), (7.0 / 9.0, 1.0 / 2.0)),
    -1: (None, (0.852, 0.375), (0.997, 0.617)),
    -2: (None, (1.079, 0.368), (1.033, 0.607)),
    -3: (None, None, (1.053, 0.553)),
    -4: (None, None, (1.302, 0.535)),
}
# Greenhall & Riley 2003, Table 3: (b0, b1) of sz(0) ≈ b0 + b1 ln m for white phase noise (α = 1), d = 1, 2, 3
_TABLE3: tuple[tuple[float, float], ...] = ((6.0, 4.0), (15.23, 12.0), (47.8, 40.0))


@dataclass(frozen=True)
class NoiseId:
    """The power law identified by the lag-1 autocorrelation (Riley & Greenhall 2004).

    Attributes
    ----------
    alpha : int
        The frequency noise's exponent (S_y ∝ f^α), rounded: 2 white phase, 1 flicker phase, 0 white frequency,
        −1 flicker frequency, −2 random walk of frequency.
    alpha_estimate : float
        The unrounded ``p + 2``.
    differences : int
        How many times the phase was differenced to reach stationarity.
    delta : float
        ``δ = r1 / (1 + r1)`` of the stationary series.
    """

    alpha: int
    alpha_estimate: float
    differences: int
    delta: float


def lag1_autocorrelation(z: NDArray[np.float64]) -> float:
    """The lag-1 autocorrelation ``r1 = Σ (z_t − z̄)(z_{t+1} − z̄) / Σ (z_t − z̄)²`` (Riley & Greenhall 2004, eq. 2)."""
    centred = z - np.mean(z)
    spread = float(np.dot(centred, centred))
    return float(np.dot(centred[:-1], centred[1:]) / spread) if spread > 0.0 else math.nan


def lag1_noise_id(phase: NDArray[np.float64], m: int, max_differences: int = 2) -> NoiseId:
    """The power-law noise of ``phase`` at τ = m τ_0 by the lag-1 autocorrelation (Riley & Greenhall 2004).

    Parameters
    ----------
    phase : ndarray
        Phase samples (:func:`optcal.families.noise.allan.phase_from_rate`).
    m : int
        Averaging factor; the phase is taken every ``m`` samples.
    max_differences : int
        The largest number of differences (``d_max``: 2 for the Allan variance, whose second difference makes
        α > −3 stationary; Riley & Greenhall 2004, section 6).

    Returns
    -------
    NoiseId

    Raises
    ------
    ValueError
        If fewer than :data:`NOISE_ID_MIN_POINTS` points remain at this ``m``, or they (or their differences)
        do not vary: no autocorrelation to read (a quantised sensor whose head of the log reads one value).
    """
    z = np.asarray(phase, dtype=float)[:: max(int(m), 1)]
    if z.size < NOISE_ID_MIN_POINTS:
        raise ValueError(f"noise identification needs at least {NOISE_ID_MIN_POINTS} points, got {z.size} at m={m}")
    # Riley & Greenhall 2004, section 6: remove a quadratic from the phase (a frequency offset and a linear drift)
    t = np.arange(z.size, dtype=float)
    z = z - np.polyval(np.polyfit(t, z, 2), t)
    d = 0
    while True:
        r1 = lag1_autocorrelation(z)
        if not math.isfinite(r1):
            raise ValueError(f"the phase at m={m} does not vary after {d} difference(s): no noise to identify")
        delta = r1 / (1.0 + r1)  # Riley & Greenhall 2004, eq. 5
        if delta < STATIONARY_DELTA or d >= max_differences:
            p = -2.0 * (delta + d)  # the phase's power law, S_x ∝ f^p
            # α = p + 2 for phase data; rounded as round(2δ), half to even
            return NoiseId(alpha=2 - 2 * d - int(np.round(2.0 * delta)), alpha_estimate=p + 2.0,
                           differences=d, delta=float(delta))
        z = np.diff(z)
        d += 1


# ------------------------------------------------------------------ Greenhall & Riley 2003
def _sw(t: NDArray[np.float64], alpha: int) -> NDArray[np.float64]:
    """The generalized autocovariance of the phase's power law α (Greenhall & Riley 2003, eq. 7):
    ``|t|^(3 − α)`` for even α, ``t^(3 − α) ln |t|`` for odd α (0 at t = 0), and ``−|t|`` for α = 2."""
    a = np.abs(t)
    if alpha == 2:
        return -a
    power = 3 - alpha
    if alpha % 2 == 0:
        return a**power
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a > 0.0, a**power * np.log(np.where(a > 0.0, a, 1.0)), 0.0)


def _sx(t: NDArray[np.float64], f: float, alpha: int) -> NDArray[np.float64]:
    """eq. 8: the filter of the averaging over ``1/F`` (``F = m`` unmodified), its limit ``sw(t, α + 2)`` at ``F = ∞``."""
    if math.isinf(f):
        return _sw(t, alpha + 2)
    return f * f * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: NDArray[np.float64], f: float, alpha: int, d: int) -> NDArray[np.float64]:
    """eq. 9: the autocovariance of the d-th difference, ``Σ_k (−1)^k C(2d, d + k) sx(t + k)``, k = −d … d."""
    total = np.zeros_like(t)
    for k in range(-d, d + 1):
        total = total + (-1) ** k * math.comb(2 * d, d + k) * _sx(t + k, f, alpha)
    return total


def _basic_sum(j: int, big_m: float, s: float, f: float, alpha: int, d: int) -> float:
    """eq. 10: ``sz(0)² + (1 − J/M) sz(J/S)² + 2 Σ_{j<J} (1 − j/M) sz(j/S)²``."""
    lags = np.arange(j + 1, dtype=float)
    sz2 = _sz(lags / s, f, alpha, d) ** 2
    inner = float(np.sum(2.0 * (1.0 - lags[1:j] / big_m) * sz2[1:j]))
    return float(sz2[0] + (1.0 - j / big_m) * sz2[j] + inner)


def greenhall_edf(alpha: int, d: int, m: int, n_phase: int, overlapping: bool = True) -> float:
    """Equivalent degrees of freedom of an unmodified variance of difference order ``d`` (Greenhall & Riley 2003).

    ``d = 2`` is the Allan variance, 1 the first-difference, 3 the Hadamard variance; ``overlapping`` the estimator
    over every start (stride S = m), otherwise one per τ (S = 1).  The paper's algorithm for ``F = m``:
    ``L = 1 + m d`` phase points per term, ``M = 1 + ⌊S (N − L)/m⌋`` terms, ``J = min(M, (d + 1) S)`` correlated
    neighbours, ``r = M/S``; the sum of eq. 10 over the J neighbours while ``J ≤ J_max`` (with ``m' = ∞`` for α ≤ 0
    once ``m (d + 1) > J_max``), the large-m coefficients of Tables 2 and 3 when ``r > d + 1``, and the sum at
    ``J_max`` with ``m' = J_max / r`` between.

    Parameters
    ----------
    alpha : int
        Noise exponent, S_y ∝ f^α, with ``α + 2d > 1`` (−4 … 2).
    d : int
        Difference order, 1 to 3.
    m : int
        Averaging factor.
    n_phase : int
        Number of phase points N.
    overlapping : bool
        The overlapping estimator (as :func:`~optcal.families.noise.allan.overlapping_adev`).

    Returns
    -------
    float

    Raises
    ------
    ValueError
        For α + 2d ≤ 1, d outside 1-3, fewer than L phase points, or white phase noise (α = 2) with ``⌈r⌉ ≤ d``,
        which the algorithm leaves out.
    """
    alpha, d, m = int(alpha), int(d), int(m)
    if d not in (1, 2, 3) or not -4 <= alpha <= 2 or alpha + 2 * d <= 1:
        raise ValueError(f"no equivalent degrees of freedom for α = {alpha} with difference order d = {d}")
    f = float(m)
    s = float(m) if overlapping else 1.0
    length = m / f + m * d
    if n_phase < length:
        raise ValueError(f"{n_phase} phase points hold no difference of order {d} at m = {m}")
    big_m = 1.0 + math.floor(s * (n_phase - length) / m)
    j = int(min(big_m, (d + 1) * s))
    r = big_m / s
    if alpha == 2:
        if math.ceil(r) <= d:
            raise ValueError(f"white phase noise with {big_m:g} terms at m = {m}: too few for the paper's formula")
        a0 = math.comb(4 * d, 2 * d) / math.comb(2 * d, d) ** 2
        return 1.0 / ((a0 - (d / 2.0) / r) / big_m)
    if alpha <= 0:
        if j <= J_MAX:
            m_prime = f if m * (d + 1) <= J_MAX else math.inf
            inverse = _basic_sum(j, big_m, s, m_prime, alpha, d) / (_sz(np.zeros(1), m_prime, alpha, d)[0] ** 2 * big_m)
        elif r > d + 1:
            a0, a1 = _table2(alpha, d)
            inverse = (a0 - a1 / r) / r
        else:
            m_prime = J_MAX / r
            inverse = _basic_sum(J_MAX, J_MAX, m_prime, math.inf, alpha, d) / (
                _sz(np.zeros(1), math.inf, alpha, d)[0] ** 2 * J_MAX)
        return 1.0 / inverse
    # α = 1, flicker phase noise: sz(0) grows as ln m (Table 3)
    b0, b1 = _TABLE3[d - 1]
    if j <= J_MAX:
        inverse = _basic_sum(j, big_m, s, f, 1, d) / (_sz(np.zeros(1), f, 1, d)[0] ** 2 * big_m)
    elif r > d + 1:
        a0, a1 = _table2(1, d)
        inverse = (a0 - a1 / r) / ((b0 + b1 * math.log(m)) ** 2 * r)
    else:
        m_prime = J_MAX / r
        inverse = _basic_sum(J_MAX, J_MAX, m_prime, m_prime, 1, d) / ((b0 + b1 * math.log(m)) ** 2 * J_MAX)
    return 1.0 / inverse


def _table2(alpha: int, d: int) -> tuple[float, float]:
    entry = _TABLE2[alpha][d - 1]
    assert entry is not None  # excluded by α + 2d > 1
    return entry


def chi2_interval(dev: float, edf: float, confidence: float = ONE_SIGMA) -> tuple[float, float]:
    """The two-sided ``confidence`` interval of a deviation estimated with ``edf`` degrees of freedom.

    NIST SP 1065 (Riley 2008), eq. 45: ``σ̂² edf / χ²_{1−p} ≤ σ² ≤ σ̂² edf / χ²_p`` with ``p = (1 − c)/2``.
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"a confidence level lies in (0, 1), got {confidence}")
    tail = 0.5 * (1.0 - confidence)
    return (dev * math.sqrt(edf / chi2_ppf(1.0 - tail, edf)), dev * math.sqrt(edf / chi2_ppf(tail, edf)))
