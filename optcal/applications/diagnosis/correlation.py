"""Pose noise correlated in time: neighbouring poses share part of their noise, and the tests account for it.

A noise that wanders at the time scale of a pose (a Gauss–Markov component, bias instability)
does not only make each pose mean scatter more than ``σ/√n`` says (:mod:`optcal.applications.diagnosis.noise_model`):
poses recorded a few seconds apart share part of it.  The selection's F tests, the standard
errors and the detection limits assume independent poses; with shared noise a term that varies
smoothly over the recording (a drift, a temperature term) is tested against a noise that is
smoother than assumed, and is found too often.

**Model.**  The noise of pose ``k``'s mean is a 3-vector ``n_k`` whose axes are independent and
correlated between poses as a first-order Gauss–Markov (Ornstein–Uhlenbeck) process of the pose
times, ``corr(n_k, n_j) = ρ₀ exp(−|t_k − t_j|/τ)`` within a session (independent between
sessions).  The norm residual sees it along the pose's normal ``d_k`` (the unit gradient of the
residual with respect to the measurement; Lu 2017, eq. 13-14), so the weighted residuals have the
correlation matrix

``R = (1 − ρ₀) I + ρ₀ (K ∘ D Dᵀ)``,  ``K_kj = exp(−|t_k − t_j|/τ)``,

positive definite for ``0 ≤ ρ₀ < 1`` (a Hadamard product of two positive semi-definite
matrices with unit diagonal).  Two neighbouring poses of random orientation share on average
nothing (``E[d_k·d_j] = 0``), which is why the plain lag correlation of the residuals hides the
effect and the model needs the directions.

**Estimation** (from the baseline fit): ``ρ₀`` and ``τ`` by restricted maximum likelihood (REML,
the nine calibration parameters' degrees of freedom counted: Patterson & Thompson 1971), the
noise scale profiled out, ``τ`` at most :data:`TAU_RANGE` gaps between poses and the smooth
candidate terms (first-order drift and temperature bias) counted among the fixed effects where
the poses leave room, so that a trend over the recording is not taken for correlated noise; the correlation is used only when the likelihood-ratio test against
independent poses is significant at the diagnosis's level (``χ²`` with 2 degrees of freedom), so
white data are diagnosed exactly as before.

**Use** (:class:`~optcal.applications.diagnosis.fitting.Fitter`): every fit is refined to generalised least
squares, ``min (e + Gδ)ᵀ R⁻¹ (e + Gδ)`` by Gauss–Newton steps from the weighted least-squares
solution; its ``rss`` is the generalised sum, so the F tests, the BIC, the standard errors and
the detection limits (``(Gᵀ R⁻¹ G)⁻¹``) hold under the correlation.  Outlier poses stay
mean-shift terms (an indicator column each).

**Computation.**  ``K⁻¹`` of an Ornstein–Uhlenbeck process sampled at sorted times is
tridiagonal (the process is Markov), so ``R⁻¹`` and ``log det R`` need one banded Cholesky
factor (:mod:`optcal.core.chain_covariance`, shared with the random-walk bias): linear in the number of
poses, 10⁴ poses included.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats as sps

from optcal.core.chain_covariance import ChainCovariance, MarkovChain

#: Largest ρ₀ (``R`` must stay positive definite: ``1 − ρ₀`` is its smallest possible eigenvalue).
MAX_RHO: float = 0.95
#: Search range of τ, as multiples of the median gap between consecutive poses: the time scale of a
#: pose and its neighbours.  A longer correlation time would be a bias wandering over the whole
#: recording, which is an effect for the selection to test (a drift, a temperature term), not noise:
#: a correlated-noise model allowed to span the recording absorbs a linear drift and hides it.
TAU_RANGE: tuple[float, float] = (0.1, 2.0)
#: Fewest poses with a neighbour in time the correlation is estimated from.
MIN_POSES: int = 20
#: ``ρ₀`` at or below which an estimate is none, zero to the optimiser's rounding (its lower bound is 0): ``R``
#: departs from ``I`` by at most ``ρ₀`` in any entry, so a test's variance changes by less than ``ρ₀ n`` relatively,
#: below 1e-5 at 10⁴ poses; the report then says the poses were tested as independent, which they were to rounding.
RHO_NONE: float = 1e-9


@dataclass
class CorrelationOperator:
    """``R⁻¹`` of one ``(ρ₀, τ)``, applied in linear time (module docstring, *Computation*).

    ``R = (1 − ρ₀) I + U (K ⊗ I₃) Uᵀ`` with ``u_k = √ρ₀ d_k``: white noise plus the pose noise
    shared along the sampled Ornstein–Uhlenbeck chain (:class:`optcal.core.chain_covariance.ChainCovariance`).
    """

    order: NDArray[np.intp]
    a: float
    covariance: ChainCovariance | None
    #: ``φ_i = exp(−Δt_i/τ)`` between consecutive poses in :attr:`order` (0 across sessions): the
    #: sampled Ornstein–Uhlenbeck process the simulations draw from (:meth:`sample`)
    phi: NDArray[np.float64] | None = None
    #: The ``(ρ₀, τ)`` it was built from (said beside a test that re-estimates them,
    #: :func:`optcal.applications.diagnosis.step_pair.pair_correlation`)
    rho0: float = 0.0
    tau_s: float = 0.0

    @classmethod
    def build(cls, rho0: float, tau_s: float, t: NDArray, session: NDArray, directions: NDArray) -> "CorrelationOperator":
        """The operator of ``R`` for poses at times ``t`` in ``session`` with unit normals ``directions``."""
        n = t.size
        order = np.lexsort((t, session))
        if rho0 <= 0:
            return cls(order, 1.0, None, None, 0.0, tau_s)
        a = 1.0 - rho0
        gap = np.diff(t[order])
        same = np.diff(session[order]) == 0
        phi = np.where(same, np.exp(-np.maximum(gap, 0.0) / tau_s), 0.0)
        phi = np.minimum(phi, 1.0 - 1e-9)
        # the sampled Ornstein–Uhlenbeck process: x_{i+1} = φ_i x_i + √(1 − φ_i²) ε_i, unit variance
        chain = MarkovChain(phi, np.concatenate([[1.0], 1.0 - phi**2]))
        state = np.empty(n, dtype=np.intp)
        state[order] = np.arange(n)
        cov = ChainCovariance(np.full(n, a), np.sqrt(rho0) * np.asarray(directions, dtype=float), state, chain)
        return cls(order, a, cov, phi, rho0, tau_s)

    @property
    def logdet(self) -> float:
        """``log det R`` (0 for independent poses)."""
        return 0.0 if self.covariance is None else self.covariance.logdet

    def sample(self, rng: np.random.Generator, draws: int = 1) -> NDArray[np.float64]:
        """Unit-variance noise of every pose's three axes with this correlation: shape ``(draws, n, 3)``.

        Per axis, ``√(1 − ρ₀) ε_k + √ρ₀ x_k`` with ``x`` the Ornstein–Uhlenbeck process sampled at
        the pose times (``x_{i+1} = φ_i x_i + √(1 − φ_i²) η_i``, restarted in each session), so that
        the noise along the poses' normals has the correlation ``R`` the tests assume; scaled by each
        pose's σ it is the noise the diagnosis's model claims (simulation check, bootstrap).
        """
        n = self.order.size
        white = rng.standard_normal((draws, n, 3))
        if self.phi is None:
            return white
        steps = rng.standard_normal((n, draws, 3))
        x = np.empty((n, draws, 3))
        x[0] = steps[0]
        gain = np.sqrt(1.0 - self.phi**2)
        for i in range(1, n):  # in time order; φ = 0 starts a new session
            x[i] = self.phi[i - 1] * x[i - 1] + gain[i - 1] * steps[i]
        out = np.sqrt(self.a) * white
        out[:, self.order] += np.sqrt(1.0 - self.a) * x.transpose(1, 0, 2)
        return out

    def solve(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """``R⁻¹ X`` (rows of ``X`` in pose order; a vector or a matrix)."""
        if self.covariance is None:
            return np.array(X, dtype=float, copy=True)
        return self.covariance.solve(X)


def restricted_deviance(op: CorrelationOperator, e: NDArray, G: NDArray) -> float:
    """``−2`` × the restricted log-likelihood of residuals ``e`` with Jacobian ``G`` (scale profiled, constants dropped)."""
    n, p = G.shape
    Z = op.solve(np.column_stack([e, G]))
    info = G.T @ Z[:, 1:]
    b = G.T @ Z[:, 0]
    chol = np.linalg.cholesky(info + 1e-12 * np.trace(info) / p * np.eye(p))
    q = float(e @ Z[:, 0]) - float(np.sum(np.linalg.solve(chol, b) ** 2))
    return (n - p) * np.log(max(q, 1e-300)) + op.logdet + 2.0 * float(np.sum(np.log(np.diag(chol))))


@dataclass
class PoseCorrelation:
    """The correlation of the pose noise in time, estimated from the baseline fit (module docstring).

    Attributes
    ----------
    tested : bool
        ``False`` without a usable time column or with too few poses (``reason`` says why).
    rho0 : float
        Correlation of two poses' noise along a shared direction, extrapolated to zero time gap.
    tau_s : float
        Correlation time of the pose noise, s.
    median_gap_s : float
        Median time between consecutive poses, s.
    neighbour_rho : float
        ``ρ₀ exp(−gap/τ)``: the correlation of consecutive poses (same direction) at the median gap.
    p_value : float
        Likelihood-ratio test of the correlation against independent poses.
    used : bool
        The tests, standard errors and limits use it: its own test is significant at the diagnosis's
        level, or other evidence shows noise at the pose time scale (:attr:`reason` says which).
    reason : str or None
        Why it was not tested, or why it is used.
    estimated_with : str or None
        What the REML counted among its fixed effects when the correlation was estimated again after bias steps
        were accepted (:func:`optcal.applications.diagnosis.noise_model.correlation_with_steps`); ``None``: estimated
        from the baseline fit (the nine calibration parameters, and the smooth trends where the poses leave room).
    baseline : PoseCorrelation or None
        The baseline's estimate it replaced (set with :attr:`estimated_with`).
    """

    tested: bool
    rho0: float = 0.0
    tau_s: float = 0.0
    median_gap_s: float = 0.0
    neighbour_rho: float = 0.0
    p_value: float = 1.0
    used: bool = False
    reason: str | None = None
    operator: CorrelationOperator | None = field(default=None, repr=False, compare=False)
    estimated_with: str | None = None
    baseline: "PoseCorrelation | None" = field(default=None, repr=False, compare=False)

    def none(self) -> bool:
        """Whether the estimate is no correlation, ``ρ₀`` zero to rounding (:data:`RHO_NONE`)."""
        return self.rho0 <= RHO_NONE

    def text(self) -> str:
        """The named noise explanation in plain words (never a physical effect)."""
        if not self.tested:
            return f"pose noise correlation not tested: {self.reason}"
        again = "" if self.baseline is None else (
            f"; estimated again with {self.estimated_with} among its fixed effects (the baseline's, without them: "
            f"ρ₀ {self.baseline.rho0:.2f}, correlation time {self.baseline.tau_s:.3g} s)")
        if (self.used or self.baseline is not None) and self.none():
            return (f"the pose noise correlation was estimated (because of {self.reason}{again}): none, ρ₀ "
                    f"{self.rho0:.2f}; the poses were tested as independent")
        if not self.used:
            return (f"the pose noise is not detectably correlated in time (p = {self.p_value:.2g}); "
                    "the tests treat the poses as independent")
        return (f"the pose noise is correlated in time: neighbouring poses ({self.median_gap_s:.3g} s apart) share "
                f"ρ = {self.neighbour_rho:.2f} of their noise along a common direction (correlation time "
                f"{self.tau_s:.3g} s; estimated from the residuals, its own test p = {self.p_value:.2g}; used because of "
                f"{self.reason}{again}); the tests, standard errors and detection limits account for it (generalised least "
                "squares). This is a property of the noise, not a physical effect")

    def to_dict(self) -> dict[str, Any]:
        return {"tested": self.tested, "rho0": self.rho0, "tau_s": self.tau_s, "median_gap_s": self.median_gap_s,
                "neighbour_rho": self.neighbour_rho, "p_value": self.p_value, "used": self.used,
                "reason": self.reason, "text": self.text(),
                **({} if self.baseline is None else {"estimated_with": self.estimated_with,
                                                     "baseline": self.baseline.to_dict()})}


def estimate_correlation(e: NDArray, G: NDArray, t: NDArray | None, session: NDArray, directions: NDArray,
                         alpha: float, evidence: str | None = None) -> PoseCorrelation:
    """Estimate ``ρ₀, τ`` from weighted residuals ``e`` and weighted Jacobian ``G`` of a fit, and test them at ``alpha``.

    ``directions``: unit normal of each pose; ``t``: pose times (s; ``None``: no time column);
    ``evidence``: other evidence of noise at the pose time scale, in words (the correlation is then
    used whatever its own test says, and the reason is kept).
    """
    n = e.size
    if t is None:
        return PoseCorrelation(False, reason="no time column: the order of the poses in time is unknown")
    order = np.lexsort((t, session))
    gaps = np.diff(t[order])[np.diff(session[order]) == 0]
    gaps = gaps[gaps > 0]
    if n < MIN_POSES or gaps.size < MIN_POSES - 1:
        return PoseCorrelation(False, reason=f"{n} poses: at least {MIN_POSES} with distinct times are needed")
    gap = float(np.median(gaps))
    lo, hi = np.log(TAU_RANGE[0] * gap), np.log(TAU_RANGE[1] * gap)

    def deviance(z: NDArray) -> float:
        return restricted_deviance(CorrelationOperator.build(float(z[0]), float(np.exp(z[1])), t, session, directions), e, G)

    white = deviance(np.array([0.0, lo]))
    grid = [np.array([r, lt]) for r in (0.2, 0.5, 0.8) for lt in np.linspace(lo, hi, 5)]
    start = min(grid, key=deviance)
    best = optimize.minimize(deviance, start, method="L-BFGS-B", bounds=[(0.0, MAX_RHO), (lo, hi)])
    rho0, tau = float(best.x[0]), float(np.exp(best.x[1]))
    stat = max(white - float(best.fun), 0.0)
    p = float(sps.chi2.sf(stat, 2))
    used = bool((p < alpha or evidence is not None) and rho0 > 0)
    op = CorrelationOperator.build(rho0, tau, t, session, directions) if used else None
    why = ("its likelihood-ratio test against independent poses" if p < alpha else evidence) if used else None
    return PoseCorrelation(True, rho0, tau, gap, rho0 * float(np.exp(-gap / tau)), p, used, why, operator=op)
