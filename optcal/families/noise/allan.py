"""Allan deviation of one axis of a static log and its noise parameters (Yin 2014, section 2.2; IEEE Std 952).

One analysis serves the accelerometer and the gyroscope: the Allan deviation and its three
slopes are the same for both; only the names and units of the coefficients and the scale of
raw counts differ (:mod:`optcal.families.noise.sensors`).  The three axes of a log, the
summary, the report and the figure are :mod:`optcal.families.noise.analysis`.

What the paper does (its equations 5-6 were lost in the text extraction; reconstructed here)
------------------------------------------------------------------------------------------
A long static log (12 h in the paper) ``y_1 … y_N`` sampled at ``f_s = 1/τ_0`` is cut into
clusters of ``m`` samples, ``τ = m τ_0``.  With ``ȳ_k(τ)`` the mean of cluster ``k``, the
Allan variance is (Yin 2014, eq. 5)::

    σ²(τ) = 1 / (2 (K − 1)) · Σ_{k=1}^{K−1} (ȳ_{k+1}(τ) − ȳ_k(τ))²

"take the difference of the means of two consecutive clusters, square, sum, divide by a
scaling factor, take the square root".  τ grows until only 9 clusters remain (K ≥ 9,
:data:`MIN_CLUSTERS`).  optcal uses the *overlapping* estimator of the same quantity
(NIST SP 1065, eq. 11), computed from the cumulative sum of the samples (:func:`overlapping_adev`,
O(N) per τ, the numbers allantools' ``oadev`` gives) on octave-spaced τ = 2^j τ_0, with
confidence intervals from the lag-1 autocorrelation noise identification (Riley & Greenhall 2004)
and Greenhall's equivalent degrees of freedom (Greenhall & Riley 2003), both in
:mod:`optcal.families.noise.stability`.

Table 1 (eq. 6) relates the Allan deviation to the noise terms (IEEE Std 952, Annex C)::

    noise density         N :  σ(τ) = N / √τ                  log-log slope −1/2, read at τ = 1 s
    bias instability      B :  σ(τ) = √(2 ln 2 / π) · B ≈ 0.664 B   slope 0, the flat minimum
    rate random walk      K :  σ(τ) = K √(τ / 3)              slope +1/2, read at τ = 3 s

N is the velocity random walk of an accelerometer (its white noise integrates to a random walk
of velocity) and the angle random walk of a gyroscope (IEEE Std 952's name).
The paper reads N on the −1/2 line at τ = 1 s and B as the flat minimum (σ_min / 0.664).
Where the three regions overlap, the plain minimum over-states B (white noise and rate random
walk still add to it), so optcal fits the sum of the three terms (independent noises add in
Allan variance)::

    σ²(τ) = N² / τ + (0.664 B)² + K² τ / 3

by weighted non-negative least squares (linear in N², B², K²; weights from each point's
equivalent degrees of freedom, ``var(σ̂²) ≈ 2 σ⁴ / edf``, iterated on the model) and reads the
three lines of the fit: N is the −1/2 line at τ = 1 s, B the flat line divided by 0.664, K the
+1/2 line at τ = 3 s.  A term is reported as present when its coefficient exceeds twice its
standard error; otherwise rate random walk is ``None`` and bias instability is the upper bound
``σ_min / 0.664`` (the paper's reading), with a note saying so.  Every term is non-negative, so
the curve bounds the rate random walk from above whether or not it shows it: the largest K
consistent with the measured curve is ``min_τ σ̂(τ) √(3/τ)`` (:func:`rate_random_walk_bound`, a
point value), and the bound at a stated confidence reads the upper confidence limit of σ(τ) at
the longest τ instead (:func:`rate_random_walk_confidence_bound`, χ² with Greenhall's edf).

Units: parameters are kept in the log's units ``u`` (g, m/s², rad/s, °/s or counts): N in
u·√s (= u/√Hz), B in u, K in u/√s.  The sensor converts them to SI
(:meth:`~optcal.families.noise.sensors.NoiseSensor.si_per_unit`: for the accelerometer N in
m/s/√s, B in m/s², K in m/s²/√s; for the gyroscope N in rad/s/√Hz, B in rad/s, K in
rad/s²/√Hz) and lists the conventional units of a report (m/s/√h and µg/√Hz, µg; °/√h, °/h).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from itertools import combinations
from statistics import NormalDist

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.quantiles import chi2_ppf
from optcal.errors import InputError
from optcal.families.noise.sensors import ACCELEROMETER, NoiseSensor
from optcal.families.noise.stability import NOISE_ID_MIN_POINTS, ONE_SIGMA, chi2_interval, greenhall_edf, lag1_noise_id

#: Yin 2014, section 2.2: grow τ only while at least 9 clusters remain.
MIN_CLUSTERS: int = 9
#: The flat level of flicker noise: σ = √(2 ln 2 / π) B (IEEE Std 952, Table C.1).
FLICKER_FACTOR: float = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: τ at which the noise density (velocity or angle random walk) is read on the −1/2 line (Yin 2014, section 3).
NOISE_DENSITY_TAU_S: float = 1.0
#: τ at which the rate random walk is read on the +1/2 line (IEEE Std 952).
RRW_TAU_S: float = 3.0
#: Phase points per piece of :func:`overlapping_adev`'s sums, each piece's sum of squares one dot product
#: (the sum is the same as over the whole log to rounding, about 1e-15 of σ): the temporary of second
#: differences stays in the processor's cache, so each τ reads the phase once from memory instead of
#: writing and reading a temporary of the log's length three times (2× faster on a 12-hour log).
ADEV_PIECE: int = 2**13
#: Pieces of :data:`ADEV_PIECE` points whose second differences are formed in one pass (a 1 MiB
#: temporary, within a core's second-level cache), each piece's sum still its own dot product (``np.vecdot``
#: of the rows, as ``np.dot`` of each), added in order: σ is the same to the last bit as one piece at a time,
#: with 16× fewer interpreter round trips per τ.  Speed only: on a 12-hour log at 100 Hz the 527 pieces per τ
#: one at a time cost 0.11 s of CPU per axis, 16 at a time 0.08 s; 64 at a time (4 MiB, out of that cache)
#: 0.10 s.
ADEV_ROWS: int = 16
#: Clusters used for noise identification at each τ: 2048 points give r1 to about ±0.02 (its standard error
#: ~1/√n), ample to tell the integer α apart (steps of 1 in α are steps of 0.5 in δ).
_NOISE_ID_MAX_POINTS: int = 2048
#: A fitted term counts as present when its coefficient exceeds this many standard errors.
_PRESENCE_SIGMAS: float = 2.0
#: Noise-type exponents α (S_y ∝ f^α) accepted for the EDF: the three terms of the model
#: (α = 0, −1, −2) plus flicker phase noise (α = 1) from an anti-aliasing filter.
_ALPHA_RANGE: tuple[int, int] = (-2, 1)

#: The three fitted coefficients, sensor-neutral names (:class:`NoiseParameters`).
PARAMETERS: tuple[str, str, str] = ("noise_density", "bias_instability", "rate_random_walk")

# --------------------------------------------------------------------------- Allan deviation
@dataclass
class AllanCurve:
    """Overlapping Allan deviation of one axis, with confidence intervals.

    Attributes
    ----------
    taus : ndarray
        Averaging times τ, s (octave-spaced, ``τ = 2^j / f_s``).
    adev : ndarray
        Overlapping Allan deviation σ(τ), input units.
    ci_low, ci_high : ndarray
        Confidence interval of σ(τ) at level :attr:`confidence`.
    n_terms : ndarray
        Number of second differences in each estimate (allantools' ``ns``: N − 2m).
    edf : ndarray
        Greenhall's equivalent degrees of freedom.
    alpha : ndarray of int
        Identified noise exponent (S_y ∝ f^α) used for the EDF.
    confidence : float
        Confidence level of the intervals.
    """

    taus: NDArray[np.float64]
    adev: NDArray[np.float64]
    ci_low: NDArray[np.float64]
    ci_high: NDArray[np.float64]
    n_terms: NDArray[np.float64]
    edf: NDArray[np.float64]
    alpha: NDArray[np.int64]
    confidence: float = ONE_SIGMA


def octave_taus(n_samples: int, rate_hz: float, max_tau_s: float | None = None) -> NDArray[np.float64]:
    """Octave-spaced τ with at least :data:`MIN_CLUSTERS` clusters each (Yin 2014, section 2.2).

    Raises
    ------
    InputError
        If the log is too short for τ = 1 s (where the noise density is read) or for
        the ``max_tau_s`` asked.
    """
    duration = n_samples / rate_hz
    m_max = n_samples // MIN_CLUSTERS
    if m_max < round(NOISE_DENSITY_TAU_S * rate_hz):
        raise InputError(
            f"the log is {duration:.3g} s long ({n_samples} samples at {rate_hz:g} Hz): reading the noise density "
            f"(velocity or angle random walk) at τ = {NOISE_DENSITY_TAU_S:g} s needs at least {MIN_CLUSTERS} clusters "
            f"of that length, i.e. {MIN_CLUSTERS * NOISE_DENSITY_TAU_S:g} s of static data; record a longer static log"
        )
    if max_tau_s is not None:
        if not max_tau_s > 0:
            raise InputError(f"the largest τ must be positive, got {max_tau_s}")
        clusters = max_tau_s * rate_hz  # may overflow to inf (--max-tau 1e308): then longer than any log
        if not np.isfinite(clusters) or int(round(clusters)) > m_max:
            raise InputError(
                f"the log is {duration:.4g} s long: τ = {max_tau_s:g} s needs at least {MIN_CLUSTERS} clusters, "
                f"i.e. {MIN_CLUSTERS * max_tau_s:.4g} s of static data; record a longer log or ask for "
                f"τ ≤ {m_max / rate_hz:.4g} s"
            )
        m_max = max(int(round(clusters)), 1)
    exponents = np.arange(int(np.floor(np.log2(m_max))) + 1)
    return (2.0**exponents) / rate_hz  # type: ignore[return-value]  # numpy stubs type float ** int array as floating[Any]


def phase_from_rate(samples: NDArray[np.float64], rate_hz: float) -> NDArray[np.float64]:
    """The phase (time integral) of a rate series: ``x_0 = 0``, ``x_{i+1} = x_i + (y_i − ȳ) / f_s``.

    The mean is removed before the sum so that a large mean (1 g on a vertical accelerometer
    axis) does not cost the fluctuations their digits over millions of samples (as allantools'
    ``frequency2phase``, whose numbers this reproduces).  One array of ``n + 1`` numbers is
    allocated; the sum and the scaling are done in place.

    Parameters
    ----------
    samples : ndarray, shape (n,)
        Rate samples (any units).
    rate_hz : float
        Sample rate.

    Returns
    -------
    ndarray, shape (n + 1,)
        Phase, input units times seconds.
    """
    phase = np.empty(samples.size + 1)
    phase[0] = 0.0
    body = phase[1:]
    np.subtract(samples, np.mean(samples), out=body)
    np.cumsum(body, out=body)
    body *= 1.0 / float(rate_hz)
    return phase


def overlapping_adev(phase: NDArray[np.float64], rate_hz: float, ms: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Overlapping Allan deviation from phase, O(N) per cluster length (Riley, NIST SP 1065, eq. 11).

    σ²(mτ_0) = Σ_{i=1}^{N−2m} (x_{i+2m} − 2 x_{i+m} + x_i)² / (2 (N − 2m) (mτ_0)²), with x the
    phase (:func:`phase_from_rate`): the difference of two consecutive cluster means of the
    rate, each a difference of the cumulative sum.  The second differences are summed piece by
    piece (:data:`ADEV_PIECE` points), :data:`ADEV_ROWS` pieces at a time in one small temporary, and the
    pieces' sums are added in order.

    Parameters
    ----------
    phase : ndarray, shape (N,)
        Phase samples (:func:`phase_from_rate`).
    rate_hz : float
        Sample rate.
    ms : array_like of int
        Cluster lengths m (τ = m / f_s), each with ``N − 2m ≥ 1``.

    Returns
    -------
    adev : ndarray
        σ(τ) for each m, the rate's units.
    n_terms : ndarray of int
        The number of second differences summed (N − 2m).
    """
    lengths = np.asarray(ms, dtype=int).reshape(-1)
    adev = np.empty(lengths.size)
    n_terms = np.empty(lengths.size, dtype=np.int64)
    piece = min(ADEV_PIECE, max(1, phase.size))
    pieces = np.empty(piece * ADEV_ROWS)
    for i, m in enumerate(lengths):
        n = phase.size - 2 * int(m)
        if m < 1 or n < 1:
            raise InputError(f"a cluster of {m} samples needs at least {2 * m + 1} phase points, got {phase.size}")
        total = 0.0
        for start in range(0, n, pieces.size):
            end = min(n, start + pieces.size)
            second = pieces[: end - start]
            np.multiply(phase[m + start : m + end], -2.0, out=second)  # Riley, NIST SP 1065, eq. 11: x_{i+2m} − 2 x_{i+m} + x_i
            second += phase[2 * m + start : 2 * m + end]
            second += phase[start:end]
            whole = second.size - second.size % piece
            rows = second[:whole].reshape(-1, piece)
            for row_sum in np.vecdot(rows, rows).tolist():  # each row's dot product, as one piece's np.dot
                total += row_sum
            if whole < second.size:
                total += float(np.dot(second[whole:], second[whole:]))
        adev[i] = np.sqrt(total / (2.0 * n)) / m * rate_hz
        n_terms[i] = n
    return adev, n_terms


def _noise_alpha(phase: NDArray[np.float64], m: int) -> int | None:
    """The lag-1 autocorrelation noise identification (Riley & Greenhall 2004), or None when too few points or
    when they do not vary.

    Uses the first :data:`_NOISE_ID_MAX_POINTS` clusters of length ``m`` (enough to identify
    the noise type of a stationary record).
    """
    if (phase.size - 1) // m < NOISE_ID_MIN_POINTS:
        return None
    head = phase[: _NOISE_ID_MAX_POINTS * m + 1]
    try:
        return int(np.clip(lag1_noise_id(head, m, max_differences=2).alpha, *_ALPHA_RANGE))
    except ValueError:  # a head that does not vary (one quantised value): the τ before's exponent is kept
        return None


def allan_deviation(
    samples: ArrayLike,
    rate_hz: float,
    max_tau_s: float | None = None,
    confidence: float = ONE_SIGMA,
) -> AllanCurve:
    """Overlapping Allan deviation of a static log of one axis (Yin 2014, eq. 5).

    Parameters
    ----------
    samples : array_like, shape (n,)
        Static samples of one axis (any units).
    rate_hz : float
        Sample rate.
    max_tau_s : float, optional
        Largest τ; by default the largest octave τ with at least 9 clusters.
    confidence : float
        Level of the confidence intervals (one sigma by default).

    Returns
    -------
    AllanCurve
    """
    y = np.asarray(samples, dtype=float).reshape(-1)
    if not np.all(np.isfinite(y)):
        raise InputError("the static log contains NaN or infinite samples; remove them first")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"the sample rate must be a positive number of Hz, got {rate_hz}")
    if np.ptp(y) == 0:
        raise InputError(
            "the axis is constant over the whole log: there is no noise to analyse "
            "(a stuck sensor, or a quantisation step larger than the noise)"
        )
    taus = octave_taus(y.size, rate_hz, max_tau_s)
    ms = np.rint(taus * rate_hz).astype(int)
    taus = ms / rate_hz
    phase = phase_from_rate(y, rate_hz)
    adev, n_terms = overlapping_adev(phase, rate_hz, ms)
    alpha = np.zeros(ms.size, dtype=int)
    last: int | None = None
    for i, m in enumerate(ms):
        found = _noise_alpha(phase, int(m))
        last = found if found is not None else last
        # beyond the noise-ID limit, keep the exponent identified at the largest τ that allowed it
        alpha[i] = 0 if last is None else last
    edf = np.array([greenhall_edf(int(a), 2, int(m), phase.size, overlapping=True) for a, m in zip(alpha, ms)])
    bounds = np.array([chi2_interval(float(dev), float(e), confidence) for dev, e in zip(adev, edf)])
    return AllanCurve(
        taus=np.asarray(taus, dtype=float),
        adev=np.asarray(adev, dtype=float),
        ci_low=bounds[:, 0],
        ci_high=bounds[:, 1],
        n_terms=np.asarray(n_terms, dtype=float),
        edf=edf,
        alpha=alpha,
        confidence=confidence,
    )


# ------------------------------------------------------------------- noise-parameter fit
@dataclass
class NoiseParameters:
    """Noise density, bias instability and rate random walk of one axis (either sensor).

    Attributes
    ----------
    noise_density : float
        N, input units·√s (= input units/√Hz; the −1/2 line at τ = 1 s): the velocity random walk
        of an accelerometer, the angle random walk of a gyroscope.
    bias_instability : float
        B, input units (flat line / 0.664; an upper bound when ``bias_instability_bound``).
    rate_random_walk : float or None
        K, input units/√s (the +1/2 line at τ = 3 s); None when not present in the log.
    ci : dict
        Confidence interval ``[low, high]`` of each parameter (None where not available) and
        the ``level``.
    bias_instability_bound : bool
        True when no flat region was resolved and B is the upper bound σ_min / 0.664.
    min_reading : float
        The paper's direct reading σ_min / 0.664 (input units), for comparison.
    correlation_time_s : float
        τ at which the fitted Allan deviation is least within the analysed range (used as the
        bias correlation time of the EKF).
    notes : list of str
    """

    noise_density: float
    bias_instability: float
    rate_random_walk: float | None
    ci: dict[str, Any]
    bias_instability_bound: bool
    min_reading: float
    correlation_time_s: float
    notes: list[str] = field(default_factory=list)

    def model_adev(self, taus: ArrayLike) -> NDArray[np.float64]:
        """The fitted σ(τ) = √(N²/τ + (0.664 B)² + K² τ/3) (bound terms excluded)."""
        t = np.asarray(taus, dtype=float)
        flat = 0.0 if self.bias_instability_bound else FLICKER_FACTOR * self.bias_instability
        k = self.rate_random_walk or 0.0
        return np.sqrt(self.noise_density**2 / t + flat**2 + k**2 * t / 3.0)

    def scaled(self, factor: float) -> "NoiseParameters":
        """The same parameters with every value multiplied by ``factor`` (a unit change)."""

        def scale_pair(pair: list[float] | None) -> list[float] | None:
            return None if pair is None else [v * factor for v in pair]

        ci = {k: (scale_pair(v) if k in PARAMETERS else v) for k, v in self.ci.items()}
        return NoiseParameters(
            noise_density=self.noise_density * factor,
            bias_instability=self.bias_instability * factor,
            rate_random_walk=None if self.rate_random_walk is None else self.rate_random_walk * factor,
            ci=ci,
            bias_instability_bound=self.bias_instability_bound,
            min_reading=self.min_reading * factor,
            correlation_time_s=self.correlation_time_s,
            notes=list(self.notes),
        )


def rate_random_walk_bound(taus: ArrayLike, adev: ArrayLike) -> tuple[float, float]:
    """The largest rate random walk consistent with the measured Allan curve, and the τ that sets it.

    Every noise term adds to the Allan variance, so the +½ line ``K² τ/3`` (the term of
    :meth:`NoiseParameters.model_adev`) lies below the curve at every τ: ``K ≤ σ(τ) √(3/τ)``, the
    tightest at the τ where that is least (usually the longest).  Returns ``(K_max, τ)``.

    This reads the *estimated* σ(τ) as if it were exact: a point value, not a confidence bound
    (the estimate at the longest τ rests on a few clusters and may lie well below the true
    σ(τ)).  :func:`rate_random_walk_confidence_bound` is the bound at a stated confidence.
    """
    t, a = np.asarray(taus, dtype=float), np.asarray(adev, dtype=float)
    bounds = a * np.sqrt(3.0 / t)
    k = int(np.argmin(bounds))
    return float(bounds[k]), float(t[k])


#: One-sided confidence of :func:`rate_random_walk_confidence_bound` (what ``optcal allan`` reports).
RRW_BOUND_CONFIDENCE: float = 0.95


@dataclass(frozen=True)
class RandomWalkBound:
    """A one-sided confidence bound of the rate random walk from the longest τ of an Allan curve.

    Attributes
    ----------
    value : float
        ``K_up``, input units/√s: ``K ≤ K_up`` at :attr:`confidence`.
    confidence : float
        One-sided confidence level.
    tau_s : float
        The τ it is read at (the curve's longest, chosen before looking at the data).
    edf : float
        Greenhall's equivalent degrees of freedom of σ̂²(τ) there.
    adev_upper : float
        The upper confidence limit of σ(τ) there, input units.
    """

    value: float
    confidence: float
    tau_s: float
    edf: float
    adev_upper: float

    def to_dict(self, factor: float = 1.0) -> dict[str, float]:
        """JSON-safe, values multiplied by ``factor`` (a unit change)."""
        return {"value": self.value * factor, "confidence": self.confidence, "tau_s": self.tau_s,
                "edf": self.edf, "adev_upper": self.adev_upper * factor}


def rate_random_walk_confidence_bound(curve: AllanCurve, confidence: float = RRW_BOUND_CONFIDENCE) -> RandomWalkBound:
    """The rate random walk's upper bound at one-sided ``confidence``, from the curve's longest τ.

    ``edf · σ̂²(τ) / σ²(τ)`` is χ² with ``edf`` degrees of freedom (NIST SP 1065, section 5.3;
    ``edf`` Greenhall's, :attr:`AllanCurve.edf`), so ``σ(τ) ≤ σ̂(τ) √(edf / χ²_{1−p}(edf))`` with
    probability ``p``; every noise term adds to the Allan variance, so ``K² τ/3 ≤ σ²(τ)`` and
    ``K ≤ σ_up(τ) √(3/τ)`` with at least that probability.  The τ is the longest, fixed in advance
    (taking the least over every τ would need a multiple-comparison correction).
    """
    if not 0.0 < confidence < 1.0:
        raise InputError(f"the confidence of the rate random walk bound must lie in (0, 1), got {confidence}")
    tau, adev, edf = float(curve.taus[-1]), float(curve.adev[-1]), float(max(curve.edf[-1], 1.0))
    upper = adev * math.sqrt(edf / chi2_ppf(1.0 - confidence, edf))
    return RandomWalkBound(upper * math.sqrt(3.0 / tau), float(confidence), tau, edf, upper)


def _design(taus: NDArray[np.float64], terms: list[int]) -> NDArray[np.float64]:
    """Columns of σ²(τ) = c_0/τ + c_1 + c_2 τ/3 for the chosen terms (0 = white, 1 = flicker, 2 = RRW)."""
    columns = (1.0 / taus, np.ones_like(taus), taus / 3.0)
    return np.column_stack([columns[t] for t in terms])


def nnls(design: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """Non-negative least squares ``min ‖X c − b‖`` over ``c ≥ 0`` for a few columns, exactly.

    The solution is the unconstrained least squares on its support (the Karush-Kuhn-Tucker conditions, Lawson &
    Hanson 1974, ch. 23), so among the supports whose least-squares coefficients are all non-negative the one of
    least residual is it: ``2^k − 1`` small solves for ``k`` columns (7 for the three noise terms), where
    Lawson and Hanson's active-set iteration would reach the same support step by step.
    """
    columns = design.shape[1]
    best, best_residual = np.zeros(columns), float(np.dot(target, target))
    for size in range(1, columns + 1):
        for support in combinations(range(columns), size):
            sub = design[:, support]
            coef, *_ = np.linalg.lstsq(sub, target, rcond=None)
            if np.any(coef < 0.0):
                continue
            residual = target - sub @ coef
            value = float(np.dot(residual, residual))
            if value < best_residual:
                best = np.zeros(columns)
                best[list(support)] = coef
                best_residual = value
    return best


def _weighted_nnls(
    taus: NDArray[np.float64], avar: NDArray[np.float64], edf: NDArray[np.float64], terms: list[int]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Iteratively reweighted NNLS of the Allan variance; returns coefficients and their covariance."""
    X = _design(taus, terms)
    model = avar.copy()
    for _ in range(8):  # weights 1/sd(σ̂²) with sd = σ²·√(2/edf), evaluated on the current model
        w = 1.0 / (np.maximum(model, 1e-300) * np.sqrt(2.0 / edf))
        coef = nnls(X * w[:, None], avar * w)
        new = X @ coef
        if np.allclose(new, model, rtol=1e-6, atol=0):
            break
        model = np.where(new > 0, new, avar)
    J = X * w[:, None]
    cov = np.linalg.pinv(J.T @ J)
    return coef, cov  # type: ignore[return-value]  # numpy stubs type pinv of float64 as floating[Any]


def _interval(coef: float, se: float, level_sigmas: float) -> list[float]:
    """[low, high] of √coef from coef ± k·se (clipped at zero)."""
    return [math.sqrt(max(coef - level_sigmas * se, 0.0)), math.sqrt(max(coef + level_sigmas * se, 0.0))]


def fit_noise_parameters(curve: AllanCurve, sensor: NoiseSensor = ACCELEROMETER) -> NoiseParameters:
    """Noise density (velocity or angle random walk), bias instability and rate random walk from an Allan curve.

    Fits ``σ²(τ) = N²/τ + (0.664 B)² + K² τ/3`` (Yin 2014, Table 1 / eq. 6, summed over the
    independent terms) by weighted non-negative least squares, drops a term whose coefficient
    is under two standard errors, and reads the lines as the paper does.  The confidence
    intervals are ± one standard error of each fitted coefficient mapped through the square
    root (at the curve's confidence level); they ignore the correlation between neighbouring
    overlapping estimates and are therefore somewhat optimistic, except the rate random walk's,
    which also spans the interval read from the longest τ alone with its equivalent degrees of
    freedom (measured coverage near nominal; see the comment in the code).  ``sensor`` names N in
    the notes.
    """
    taus, avar, edf = curve.taus, curve.adev**2, np.maximum(curve.edf, 1.0)
    notes: list[str] = []
    terms = [0, 1, 2]
    while True:
        coef, cov = _weighted_nnls(taus, avar, edf, terms)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        weak = [t for t, c, s in zip(terms, coef, se) if t != 0 and not c > _PRESENCE_SIGMAS * s]
        if not weak:
            break
        # drop the least significant optional term and refit
        ratios = {t: (c / s if s > 0 else 0.0) for t, c, s in zip(terms, coef, se) if t in weak}
        terms.remove(min(ratios, key=ratios.__getitem__))
    fitted = dict(zip(terms, coef))
    stderr = dict(zip(terms, se))
    k_sigma = NormalDist().inv_cdf(0.5 + curve.confidence / 2.0)
    min_reading = float(np.min(curve.adev) / FLICKER_FACTOR)

    if 0 in fitted and fitted[0] > 0:
        density = math.sqrt(fitted[0])  # the −1/2 line √(N²/τ) read at τ = 1 s is N
        density_ci: list[float] | None = _interval(fitted[0], stderr[0], k_sigma)
    else:
        density = float(curve.adev[0] * math.sqrt(curve.taus[0]))
        density_ci = None
        notes.append(f"no white-noise (−1/2 slope) region was resolved; {sensor.abbreviation('noise_density')} "
                     "is the line through the smallest τ")
    if 1 in fitted:
        bias = math.sqrt(fitted[1]) / FLICKER_FACTOR
        c_lo, c_hi = _interval(fitted[1], stderr[1], k_sigma)
        bias_ci: list[float] | None = [c_lo / FLICKER_FACTOR, c_hi / FLICKER_FACTOR]
        bound = False
    else:
        bias, bias_ci, bound = min_reading, None, True
        notes.append(
            f"no flat (bias-instability) region within τ ≤ {curve.taus[-1]:.4g} s; bias instability is the "
            "upper bound σ_min/0.664 — record a longer static log to resolve it"
        )
    if 2 in fitted:
        rrw: float | None = math.sqrt(fitted[2])
        fit_ci = _interval(fitted[2], stderr[2], k_sigma)
        # the fit treats the octave estimates as independent, but overlapping estimates at long τ share
        # most of their samples: its interval covered the truth in only 37-49 % of simulated logs at a
        # nominal 68 %.  The longest τ alone, with its own (Greenhall) equivalent degrees of freedom
        # and the fitted white and flicker parts taken out, covers 69-80 %; the hull of the two is kept
        # (it holds the estimate).
        other = (fitted.get(0, 0.0) / taus[-1] + fitted.get(1, 0.0)) * 3.0 / taus[-1]
        at_longest = [math.sqrt(max(bound**2 * 3.0 / taus[-1] - other, 0.0))
                      for bound in (curve.ci_low[-1], curve.ci_high[-1])]
        rrw_ci: list[float] | None = [min(fit_ci[0], at_longest[0]), max(fit_ci[1], at_longest[1])]
    else:
        rrw, rrw_ci = None, None
        notes.append(f"no rate random walk (+1/2 slope) within τ ≤ {curve.taus[-1]:.4g} s")

    if rrw is not None and density > 0:
        correlation_time = float(np.clip(math.sqrt(3.0) * density / rrw, curve.taus[0], curve.taus[-1]))
    else:
        correlation_time = float(curve.taus[-1])
    return NoiseParameters(
        noise_density=density,
        bias_instability=bias,
        rate_random_walk=rrw,
        ci={
            "noise_density": density_ci,
            "bias_instability": bias_ci,
            "rate_random_walk": rrw_ci,
            "level": curve.confidence,
        },
        bias_instability_bound=bound,
        min_reading=min_reading,
        correlation_time_s=correlation_time,
        notes=notes,
    )


# --------------------------------------------------------------------------- simulation
def simulate_noise(
    n_samples: int,
    rate_hz: float,
    velocity_random_walk: float,
    bias_instability: float = 0.0,
    rate_random_walk: float = 0.0,
    rng: np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """A zero-mean noise record with the given Allan parameters (same units as the parameters).

    * white noise of standard deviation ``N √f_s`` (two-sided PSD N²: σ(τ) = N/√τ);
    * flicker noise with two-sided PSD ``B² / (2π f)`` from 1/T to f_s/2, made by shaping the
      spectrum of white noise (σ(τ) → 0.664 B for 1/f_s ≪ τ ≪ T);
    * a random walk ``K √Δt Σ w`` (σ(τ) = K √(τ/3)).

    allantools' Kasdin generator is not used because it draws from NumPy's global random
    state; this one takes a seeded :class:`numpy.random.Generator`.
    """
    rng = np.random.default_rng() if rng is None else rng
    dt = 1.0 / rate_hz
    out = rng.standard_normal(n_samples) * (velocity_random_walk * math.sqrt(rate_hz))
    if bias_instability > 0:
        freqs = np.fft.rfftfreq(n_samples, dt)
        gain = np.zeros_like(freqs)
        gain[1:] = np.sqrt(bias_instability**2 / (2.0 * math.pi * freqs[1:]) * rate_hz)
        out += np.fft.irfft(np.fft.rfft(rng.standard_normal(n_samples)) * gain, n_samples)
    if rate_random_walk > 0:
        out += np.cumsum(rng.standard_normal(n_samples)) * (rate_random_walk * math.sqrt(dt))
    return out
