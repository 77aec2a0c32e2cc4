"""Allan-deviation noise analysis of a static accelerometer log (Yin 2014, section 2.2).

What the paper does (its equations 5-6 were lost in the text extraction; reconstructed here)
------------------------------------------------------------------------------------------
A long static log (12 h in the paper) ``y_1 … y_N`` sampled at ``f_s = 1/τ_0`` is cut into
clusters of ``m`` samples, ``τ = m τ_0``.  With ``ȳ_k(τ)`` the mean of cluster ``k``, the
Allan variance is (Yin 2014, eq. 5)::

    σ²(τ) = 1 / (2 (K − 1)) · Σ_{k=1}^{K−1} (ȳ_{k+1}(τ) − ȳ_k(τ))²

"take the difference of the means of two consecutive clusters, square, sum, divide by a
scaling factor, take the square root".  τ grows until only 9 clusters remain (K ≥ 9,
:data:`MIN_CLUSTERS`).  optcal uses the *overlapping* estimator of the same quantity
(NIST SP 1065, eq. 11), computed by ``allantools.oadev`` on octave-spaced τ = 2^j τ_0, with
confidence intervals from allantools' lag-1 autocorrelation noise identification and
Greenhall's equivalent degrees of freedom.

Table 1 (eq. 6) relates the Allan deviation to the noise terms (IEEE Std 952, Annex C)::

    velocity random walk  N :  σ(τ) = N / √τ                  log-log slope −1/2, read at τ = 1 s
    bias instability      B :  σ(τ) = √(2 ln 2 / π) · B ≈ 0.664 B   slope 0, the flat minimum
    rate random walk      K :  σ(τ) = K √(τ / 3)              slope +1/2, read at τ = 3 s

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
``σ_min / 0.664`` (the paper's reading), with a note saying so.

Units: parameters are kept in the log's units ``u`` (g, m/s² or counts): N in u·√s
(= u/√Hz), B in u, K in u/√s.  :func:`si_per_unit` converts to SI (N in m/s/√s, B in m/s²,
K in m/s²/√s); :data:`DISPLAY_UNITS` lists the conventional units for a report
(m/s/√h and µg/√Hz for N, µg for B).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import allantools
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import nnls
from scipy.stats import norm

from optcal.errors import InputError
from optcal.core.model import AXES, STANDARD_GRAVITY

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Yin 2014, section 2.2: grow τ only while at least 9 clusters remain.
MIN_CLUSTERS: int = 9
#: The flat level of flicker noise: σ = √(2 ln 2 / π) B (IEEE Std 952, Table C.1).
FLICKER_FACTOR: float = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: τ at which the velocity random walk is read on the −1/2 line (Yin 2014, section 3).
VRW_TAU_S: float = 1.0
#: τ at which the rate random walk is read on the +1/2 line (IEEE Std 952).
RRW_TAU_S: float = 3.0
#: One-sigma confidence level, as allantools defines it.
ONE_SIGMA: float = float(allantools.ci.ONE_SIGMA_CI)
#: Minimum cluster count for lag-1 autocorrelation noise identification (allantools' limit).
_NOISE_ID_MIN_POINTS: int = 30
#: Clusters used for noise identification at each τ.  allantools' lag-1 ACF is a Python loop;
#: 2048 points give r1 to about ±0.02, ample to tell α apart, and keep a 12 h log fast.
_NOISE_ID_MAX_POINTS: int = 2048
#: A fitted term counts as present when its coefficient exceeds this many standard errors.
_PRESENCE_SIGMAS: float = 2.0
#: Noise-type exponents α (S_y ∝ f^α) accepted for the EDF: the three accelerometer terms
#: (α = 0, −1, −2) plus flicker phase noise (α = 1) from an anti-aliasing filter.
_ALPHA_RANGE: tuple[int, int] = (-2, 1)

#: SI units of the three parameters (what ``optcal allan --json`` prints).
SI_UNITS: dict[str, str] = {
    "velocity_random_walk": "m/s/√s",
    "bias_instability": "m/s^2",
    "rate_random_walk": "m/s^2/√s",
}
#: Conventional report units and the factor from the SI unit.
DISPLAY_UNITS: dict[str, list[tuple[str, float]]] = {
    "velocity_random_walk": [("m/s/√h", 60.0), ("µg/√Hz", 1e6 / STANDARD_GRAVITY)],
    "bias_instability": [("µg", 1e6 / STANDARD_GRAVITY), ("mg", 1e3 / STANDARD_GRAVITY)],
    "rate_random_walk": [("m/s/h^1.5", 3600.0**1.5), ("µg/√s", 1e6 / STANDARD_GRAVITY)],
}
PARAMETERS: tuple[str, str, str] = ("velocity_random_walk", "bias_instability", "rate_random_walk")


def si_per_unit(units: str, counts_per_g: float | None = None) -> float:
    """Metres per second squared per input unit.

    Parameters
    ----------
    units : {"g", "m/s^2", "counts"}
    counts_per_g : float, optional
        Required for ``counts`` (e.g. 16384 for an MPU-6050 at ±2 g).
    """
    if units == "m/s^2":
        return 1.0
    if units == "g":
        return STANDARD_GRAVITY
    if units == "counts":
        if counts_per_g is None or not np.isfinite(counts_per_g) or counts_per_g <= 0:
            raise InputError(
                "raw counts need a positive counts-per-g scale to report noise in physical units "
                "(--counts-per-g; 16384 for an MPU-6050 at ±2 g)"
            )
        return STANDARD_GRAVITY / float(counts_per_g)
    raise InputError(f"unknown units {units!r}; use one of g, m/s^2, counts")


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
        Number of second differences in each estimate (allantools' ``ns``).
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
        If the log is too short for τ = 1 s (where the velocity random walk is read) or for
        the ``max_tau_s`` asked.
    """
    duration = n_samples / rate_hz
    m_max = n_samples // MIN_CLUSTERS
    if m_max < round(VRW_TAU_S * rate_hz):
        raise InputError(
            f"the log is {duration:.3g} s long ({n_samples} samples at {rate_hz:g} Hz): reading the velocity "
            f"random walk at τ = {VRW_TAU_S:g} s needs at least {MIN_CLUSTERS} clusters of that length, "
            f"i.e. {MIN_CLUSTERS * VRW_TAU_S:g} s of static data; record a longer static log"
        )
    if max_tau_s is not None:
        if not max_tau_s > 0:
            raise InputError(f"the largest τ must be positive, got {max_tau_s}")
        m_ask = int(round(max_tau_s * rate_hz))
        if m_ask > m_max:
            raise InputError(
                f"the log is {duration:.4g} s long: τ = {max_tau_s:g} s needs at least {MIN_CLUSTERS} clusters, "
                f"i.e. {MIN_CLUSTERS * max_tau_s:.4g} s of static data; record a longer log or ask for "
                f"τ ≤ {m_max / rate_hz:.4g} s"
            )
        m_max = max(m_ask, 1)
    exponents = np.arange(int(np.floor(np.log2(m_max))) + 1)
    return (2.0**exponents) / rate_hz


def _noise_alpha(phase: NDArray[np.float64], m: int) -> int | None:
    """allantools' lag-1 autocorrelation noise identification, or None when too few points.

    Uses the first :data:`_NOISE_ID_MAX_POINTS` clusters of length ``m`` (enough to identify
    the noise type of a stationary record).
    """
    if (phase.size - 1) // m < _NOISE_ID_MIN_POINTS:
        return None
    head = phase[: _NOISE_ID_MAX_POINTS * m + 1]
    alpha_int = allantools.ci.autocorr_noise_id(head, m, data_type="phase", dmin=0, dmax=2)[0]
    return int(np.clip(alpha_int, *_ALPHA_RANGE))


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
    taus, adev, _, n_terms = allantools.oadev(y, rate=rate_hz, data_type="freq", taus=taus)
    phase = allantools.frequency2phase(y, rate_hz)
    ms = np.rint(taus * rate_hz).astype(int)
    alpha = np.zeros(ms.size, dtype=int)
    last: int | None = None
    for i, m in enumerate(ms):
        found = _noise_alpha(phase, int(m))
        last = found if found is not None else last
        # beyond the noise-ID limit, keep the exponent identified at the largest τ that allowed it
        alpha[i] = 0 if last is None else last
    edf = np.array(
        [
            allantools.ci.edf_greenhall(alpha=int(a), d=2, m=int(m), N=phase.size, overlapping=True, modified=False)
            for a, m in zip(alpha, ms)
        ]
    )
    bounds = np.array([allantools.ci.confidence_interval(dev, e, confidence) for dev, e in zip(adev, edf)])
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
    """Velocity random walk, bias instability and rate random walk of one axis.

    Attributes
    ----------
    velocity_random_walk : float
        N, input units·√s (the −1/2 line at τ = 1 s).
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

    velocity_random_walk: float
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
        return np.sqrt(self.velocity_random_walk**2 / t + flat**2 + k**2 * t / 3.0)

    def scaled(self, factor: float) -> "NoiseParameters":
        """The same parameters with every value multiplied by ``factor`` (a unit change)."""

        def scale_pair(pair: list[float] | None) -> list[float] | None:
            return None if pair is None else [v * factor for v in pair]

        ci = {k: (scale_pair(v) if k in PARAMETERS else v) for k, v in self.ci.items()}
        return NoiseParameters(
            velocity_random_walk=self.velocity_random_walk * factor,
            bias_instability=self.bias_instability * factor,
            rate_random_walk=None if self.rate_random_walk is None else self.rate_random_walk * factor,
            ci=ci,
            bias_instability_bound=self.bias_instability_bound,
            min_reading=self.min_reading * factor,
            correlation_time_s=self.correlation_time_s,
            notes=list(self.notes),
        )


def rate_random_walk_bound(taus: ArrayLike, adev: ArrayLike) -> tuple[float, float]:
    """The largest rate random walk an Allan curve allows, and the τ that sets it.

    Every noise term adds to the Allan variance, so the +½ line ``K² τ/3`` (the term of
    :meth:`NoiseParameters.model_adev`) lies below the curve at every τ: ``K ≤ σ(τ) √(3/τ)``, the
    tightest at the τ where that is least (usually the longest).  Returns ``(K_max, τ)``.
    """
    t, a = np.asarray(taus, dtype=float), np.asarray(adev, dtype=float)
    bounds = a * np.sqrt(3.0 / t)
    k = int(np.argmin(bounds))
    return float(bounds[k]), float(t[k])


def _design(taus: NDArray[np.float64], terms: list[int]) -> NDArray[np.float64]:
    """Columns of σ²(τ) = c_0/τ + c_1 + c_2 τ/3 for the chosen terms (0 = white, 1 = flicker, 2 = RRW)."""
    columns = (1.0 / taus, np.ones_like(taus), taus / 3.0)
    return np.column_stack([columns[t] for t in terms])


def _weighted_nnls(
    taus: NDArray[np.float64], avar: NDArray[np.float64], edf: NDArray[np.float64], terms: list[int]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Iteratively reweighted NNLS of the Allan variance; returns coefficients and their covariance."""
    X = _design(taus, terms)
    model = avar.copy()
    for _ in range(8):  # weights 1/sd(σ̂²) with sd = σ²·√(2/edf), evaluated on the current model
        w = 1.0 / (np.maximum(model, 1e-300) * np.sqrt(2.0 / edf))
        coef, _ = nnls(X * w[:, None], avar * w)
        new = X @ coef
        if np.allclose(new, model, rtol=1e-6, atol=0):
            break
        model = np.where(new > 0, new, avar)
    J = X * w[:, None]
    cov = np.linalg.pinv(J.T @ J)
    return coef, cov


def _interval(coef: float, se: float, level_sigmas: float) -> list[float]:
    """[low, high] of √coef from coef ± k·se (clipped at zero)."""
    return [math.sqrt(max(coef - level_sigmas * se, 0.0)), math.sqrt(max(coef + level_sigmas * se, 0.0))]


def fit_noise_parameters(curve: AllanCurve) -> NoiseParameters:
    """Velocity random walk, bias instability and rate random walk from an Allan curve.

    Fits ``σ²(τ) = N²/τ + (0.664 B)² + K² τ/3`` (Yin 2014, Table 1 / eq. 6, summed over the
    independent terms) by weighted non-negative least squares, drops a term whose coefficient
    is under two standard errors, and reads the lines as the paper does.  The confidence
    intervals are ± one standard error of each fitted coefficient mapped through the square
    root (at the curve's confidence level); they ignore the correlation between neighbouring
    overlapping estimates and are therefore somewhat optimistic, except the rate random walk's,
    which also spans the interval read from the longest τ alone with its equivalent degrees of
    freedom (measured coverage near nominal; see the comment in the code).
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
        terms.remove(min(ratios, key=ratios.get))
    fitted = dict(zip(terms, coef))
    stderr = dict(zip(terms, se))
    k_sigma = float(norm.ppf(0.5 + curve.confidence / 2.0))
    min_reading = float(np.min(curve.adev) / FLICKER_FACTOR)

    if 0 in fitted and fitted[0] > 0:
        vrw = math.sqrt(fitted[0])  # the −1/2 line √(N²/τ) read at τ = 1 s is N
        vrw_ci: list[float] | None = _interval(fitted[0], stderr[0], k_sigma)
    else:
        vrw = float(curve.adev[0] * math.sqrt(curve.taus[0]))
        vrw_ci = None
        notes.append("no white-noise (−1/2 slope) region was resolved; VRW is the line through the smallest τ")
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
        rrw_ci: list[float] | None = _interval(fitted[2], stderr[2], k_sigma)
        # the fit treats the octave estimates as independent, but overlapping estimates at long τ share
        # most of their samples: its interval covered the truth in only 37-49 % of simulated logs at a
        # nominal 68 %.  The longest τ alone, with its own (Greenhall) equivalent degrees of freedom
        # and the fitted white and flicker parts taken out, covers 69-80 %; the hull of the two is kept
        # (it holds the estimate).
        other = (fitted.get(0, 0.0) / taus[-1] + fitted.get(1, 0.0)) * 3.0 / taus[-1]
        at_longest = [math.sqrt(max(bound**2 * 3.0 / taus[-1] - other, 0.0))
                      for bound in (curve.ci_low[-1], curve.ci_high[-1])]
        rrw_ci = [min(rrw_ci[0], at_longest[0]), max(rrw_ci[1], at_longest[1])]
    else:
        rrw, rrw_ci = None, None
        notes.append(f"no rate random walk (+1/2 slope) within τ ≤ {curve.taus[-1]:.4g} s")

    if rrw is not None and vrw > 0:
        correlation_time = float(np.clip(math.sqrt(3.0) * vrw / rrw, curve.taus[0], curve.taus[-1]))
    else:
        correlation_time = float(curve.taus[-1])
    return NoiseParameters(
        velocity_random_walk=vrw,
        bias_instability=bias,
        rate_random_walk=rrw,
        ci={
            "velocity_random_walk": vrw_ci,
            "bias_instability": bias_ci,
            "rate_random_walk": rrw_ci,
            "level": curve.confidence,
        },
        bias_instability_bound=bound,
        min_reading=min_reading,
        correlation_time_s=correlation_time,
        notes=notes,
    )


# --------------------------------------------------------------------------- whole-log analysis
@dataclass
class AllanAnalysis:
    """Allan analysis of a three-axis static log.

    Attributes
    ----------
    curves, parameters : dict
        Per axis (``x``, ``y``, ``z``): :class:`AllanCurve` and :class:`NoiseParameters`,
        both in the input units.
    units : str
        Input units (``g``, ``m/s^2`` or ``counts``).
    si_per_unit : float
        m/s² per input unit.
    rate_hz : float
    n_samples : int
    """

    curves: dict[str, AllanCurve]
    parameters: dict[str, NoiseParameters]
    units: str
    si_per_unit: float
    rate_hz: float
    n_samples: int

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.rate_hz

    def si_parameters(self) -> dict[str, NoiseParameters]:
        """The parameters converted to SI (N in m/s/√s, B in m/s², K in m/s²/√s)."""
        return {axis: p.scaled(self.si_per_unit) for axis, p in self.parameters.items()}

    def summary(self) -> dict[str, Any]:
        """JSON-safe summary in SI units (what ``optcal allan --json`` prints).

        One object ``{"units": {...}, "log": {...}, "x": {...}, "y": {...}, "z": {...}}``;
        each axis has ``velocity_random_walk``, ``bias_instability``, ``rate_random_walk`` (or
        None), ``ci`` and ``notes``; ``log`` gives the rate, sample count and duration.
        ``rate_random_walk_upper_bound`` (with ``rate_random_walk_bound_tau_s``) is the largest
        K the measured curve allows: every term of σ²(τ) is non-negative, so K²τ/3 ≤ σ²(τ) at
        every τ and K ≤ min_τ σ(τ)·√(3/τ), reached near the longest τ.
        """
        out: dict[str, Any] = {
            "units": {**SI_UNITS, "input": self.units, "si_per_input_unit": self.si_per_unit},
            "log": {"rate_hz": self.rate_hz, "n_samples": self.n_samples, "duration_s": self.duration_s},
        }
        for axis, p in self.si_parameters().items():
            curve = self.curves[axis]
            k_bound, at_tau = rate_random_walk_bound(curve.taus, curve.adev)  # K²τ/3 ≤ σ²(τ) (Yin 2014, Table 1)
            out[axis] = {
                "velocity_random_walk": p.velocity_random_walk,
                "bias_instability": p.bias_instability,
                "rate_random_walk": p.rate_random_walk,
                "rate_random_walk_upper_bound": k_bound * self.si_per_unit,
                "rate_random_walk_bound_tau_s": at_tau,
                "ci": {**p.ci, "bias_instability_is_upper_bound": p.bias_instability_bound},
                "notes": p.notes,
            }
        return out

    def report(self) -> str:
        """Readable table of the parameters in conventional units."""
        lines = [
            f"Allan deviation of a {self.duration_s:.1f} s static log ({self.n_samples} samples at "
            f"{self.rate_hz:g} Hz, input in {self.units})",
        ]
        for axis, p in self.si_parameters().items():
            lines.append(f"[{axis}]")
            values = {
                "velocity_random_walk": p.velocity_random_walk,
                "bias_instability": p.bias_instability,
                "rate_random_walk": p.rate_random_walk,
            }
            for name, value in values.items():
                label = name.replace("_", " ")
                if value is None:
                    lines.append(f"    {label:<22s} not present")
                    continue
                shown = ", ".join(f"{value * f:.4g} {u}" for u, f in DISPLAY_UNITS[name])
                bound = " (upper bound)" if name == "bias_instability" and p.bias_instability_bound else ""
                lines.append(f"    {label:<22s} {value:.4g} {SI_UNITS[name]} = {shown}{bound}")
            lines.extend(f"    note: {n}" for n in p.notes)
        return "\n".join(lines)


def analyse_static_log(
    samples: ArrayLike,
    rate_hz: float,
    units: str,
    counts_per_g: float | None = None,
    max_tau_s: float | None = None,
) -> AllanAnalysis:
    """Allan deviation and noise parameters of every axis of a static log.

    Parameters
    ----------
    samples : array_like, shape (n, 3)
        Static samples, one column per axis, in ``units``.
    rate_hz : float
        Sample rate.
    units : {"g", "m/s^2", "counts"}
    counts_per_g : float, optional
        Scale of ``counts`` (required for counts).
    max_tau_s : float, optional
        Largest τ analysed (must leave at least 9 clusters).
    """
    data = np.asarray(samples, dtype=float)
    if data.ndim != 2 or data.shape[1] != 3:
        raise InputError(f"a static log needs three columns (x, y, z), got shape {data.shape}")
    factor = si_per_unit(units, counts_per_g)
    curves = {axis: allan_deviation(data[:, i], rate_hz, max_tau_s) for i, axis in enumerate(AXES)}
    return AllanAnalysis(
        curves=curves,
        parameters={axis: fit_noise_parameters(c) for axis, c in curves.items()},
        units=units,
        si_per_unit=factor,
        rate_hz=float(rate_hz),
        n_samples=int(data.shape[0]),
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


# --------------------------------------------------------------------------- plot
def allan_figure(analysis: AllanAnalysis, title: str | None = None) -> "Figure":
    """Log-log Allan deviation of each axis with confidence intervals and the fitted lines.

    Values are drawn in the input units; the legend gives the parameters in conventional units.
    Drawn on a :class:`matplotlib.figure.Figure` of its own (no pyplot state, the backend untouched).
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 4.8))
    axes = fig.subplots(1, 3)
    for ax, (axis, curve) in zip(axes, analysis.curves.items()):
        p = analysis.parameters[axis]
        si = p.scaled(analysis.si_per_unit)
        err = np.vstack([curve.adev - curve.ci_low, curve.ci_high - curve.adev])
        ax.errorbar(curve.taus, curve.adev, yerr=err, fmt="o", ms=4, capsize=2, color="k", label="overlapping ADEV")
        dense = np.geomspace(curve.taus[0], curve.taus[-1], 200)
        ax.loglog(dense, p.model_adev(dense), "-", color="0.5", lw=2, alpha=0.6, label="fitted sum")
        vrw_label = f"VRW {si.velocity_random_walk * 60:.3g} m/s/√h ({si.velocity_random_walk * 1e6 / STANDARD_GRAVITY:.3g} µg/√Hz)"
        ax.loglog(dense, p.velocity_random_walk / np.sqrt(dense), "--", color="tab:blue", label=vrw_label)
        ax.plot([VRW_TAU_S], [p.velocity_random_walk], "s", color="tab:blue", ms=7, mfc="none")
        bi_ug = si.bias_instability * 1e6 / STANDARD_GRAVITY
        flat_label = f"BI {'≤ ' if p.bias_instability_bound else ''}{bi_ug:.3g} µg (flat = 0.664 B)"
        ax.axhline(FLICKER_FACTOR * p.bias_instability, ls=":", color="tab:green", label=flat_label)
        if p.rate_random_walk is not None:
            rrw_label = f"RRW {si.rate_random_walk * 1e6 / STANDARD_GRAVITY:.3g} µg/√s"
            ax.loglog(dense, p.rate_random_walk * np.sqrt(dense / 3.0), "-.", color="tab:red", label=rrw_label)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("τ (s)")
        ax.set_title(f"{axis} axis")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
        ax.set_ylim(bottom=min(curve.ci_low.min(), FLICKER_FACTOR * p.bias_instability) * 0.5)
    axes[0].set_ylabel(f"Allan deviation σ(τ) ({analysis.units})")
    fig.suptitle(title or f"Allan deviation, {analysis.duration_s / 3600:.3g} h at {analysis.rate_hz:g} Hz")
    fig.tight_layout()
    return fig


def plot_allan(analysis: AllanAnalysis, path: str | Path, title: str | None = None) -> Path:
    """Save :func:`allan_figure` to ``path`` (parent folders created); returns the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    allan_figure(analysis, title).savefig(out, dpi=120)
    return out
