"""The noise model as a candidate explanation: pose means that scatter more than ``σ/√n`` says.

The per-pose σ of a raw recording is the standard deviation of an interval's mean (batch
means, :func:`optcal.data.static_poses.sigma_of_mean`).  When the sensor's noise is correlated at
the time scale of a pose (bias instability, flicker, a Gauss–Markov component with a
correlation time of seconds), the mean of a dwell wanders more than its samples say, and the
residuals of every model are larger than the simulation predicts.  The honest diagnosis is
then "the simulation's noise model is wrong", never a physical effect.

The explanation is tested *after* the effect selection, on the final model, so it cannot hide
an effect (the selection's F tests estimate the noise scale from the residuals and never
depend on the σ claim):

* **test** — the weighted residual sum of squares with the given σ against χ²(n − p)
  (Lu 2017, eq. 14 weights); the explanation is named when it is significant at ``alpha``;
* **extension** — every pose gets an extra pose-to-pose noise ``τ`` (raw units):
  ``σ_k'² = σ_k² + τ²``, with ``τ`` solving ``Σ r_k² / var_k(τ) = n − p`` (the moment
  equation of the χ² law, ``var_k = g_k²(σ_k² + τ²)``, ``g_k = ‖Tᵀ ā_k‖``), refitted twice;
* **gain** — the reduced χ² before and after, and the coverage of the nominal 95 % intervals
  of the calibration parameters in a parametric bootstrap of the extended noise model, with
  the standard errors the given σ implies and with those of ``σ'``.

The **measured route** (:mod:`optcal.applications.diagnosis.still_noise`): for a raw recording the noise of
each pose mean is also measured on the recording's longest still stretch (its Allan deviation
at the pose's dwell); the model is refitted with those per-pose σ and both understatement
factors are reported, measured and residual-estimated, with the reduced χ² and the bootstrap
coverage of each.  A pose table has no samples to measure: only the residual route is
available, and the check says so.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats as sps

from optcal.applications.diagnosis.random_walk import RandomWalkCheck
from optcal.applications.diagnosis.correlation import PoseCorrelation, estimate_correlation
from optcal.applications.diagnosis.fitting import MIN_DOF, Fit, Fitter
from optcal.applications.diagnosis.problem import BETA_INDEX, PoseData
from optcal.applications.diagnosis.progress import Loop, plain_loop
from optcal.applications.diagnosis.simulation import pose_noise
from optcal.applications.diagnosis.still_noise import MeasuredPoseNoise
from optcal.core.poses import PoseTable

#: The named cause, in plain words.
NOISE_CAUSE = (
    "the simulation's noise model is wrong: the pose means scatter more than the noise of their samples "
    "(σ/√n) says, as noise correlated at the time scale of a pose does (bias instability, flicker); "
    "this is not a physical effect of the calibration model"
)
#: Terms smooth in time that the correlation's restricted likelihood counts as fixed effects.
SMOOTH_TERMS: tuple[str, ...] = ("bias_drift", "temperature_bias")
#: Measured noise of the pose means (still parts) over σ/√n from which the pose noise counts as
#: correlated between neighbouring poses (more than half its variance is not white).
CORRELATED_RATIO: float = 1.5
#: Nominal coverage of the intervals checked in the bootstrap.
NOMINAL: float = 0.95


@dataclass
class NoiseModelCheck:
    """Whether the given per-pose σ describes the pose-to-pose scatter, and the extended noise model.

    Attributes
    ----------
    tested : bool
        ``False`` when the data carry no per-pose σ (the noise scale is then estimated from the
        residuals and cannot be checked); ``reason`` says why.
    reduced_chi2 : float
        ``Σ w_k r_k² / (n − p)`` with the given σ (1 when σ describes the scatter).
    p_value : float
        Upper tail of χ²(n − p) at the measured sum.
    named : bool
        Significant at ``alpha``: the noise model is named as the cause of the excess.
    extra_noise : float
        ``τ``, the extra pose-to-pose noise (raw units); ``extra_noise_g`` in g.
    understated_by : float
        Median over the poses of ``σ'_k / σ_k``: how much ``σ/√n`` understated the pose noise.
    reduced_chi2_after : float
        With ``σ'``.
    coverage_given_sigma, coverage_extended : float or None
        Fraction of the nominal 95 % intervals of the nine calibration parameters that cover the
        truth in the parametric bootstrap (``None`` when no simulation was run).
    simulations : int
    reason : str or None
    cause : str
    measured_route : str or None
        Where the noise of each pose mean was measured (the recording's still parts), or why only
        the residual route is available (``None``: not asked).
    measured_understated_by : float or None
        Median over the poses of measured ``σ_k`` / given ``σ_k``.
    reduced_chi2_measured : float or None
        Reduced χ² refitted with the measured per-pose σ.
    coverage_measured : float or None
        Bootstrap coverage (simulated with the measured σ) of the intervals of the measured σ.
    correlation : PoseCorrelation or None
        The pose noise correlated in time (:mod:`optcal.applications.diagnosis.correlation`).
    random_walk : RandomWalkCheck or None
        The bias wandering as a random walk (:mod:`optcal.applications.diagnosis.random_walk`).
    """

    tested: bool
    reduced_chi2: float = float("nan")
    p_value: float = 1.0
    named: bool = False
    extra_noise: float = 0.0
    extra_noise_g: float = 0.0
    understated_by: float = 1.0
    reduced_chi2_after: float = float("nan")
    coverage_given_sigma: float | None = None
    coverage_extended: float | None = None
    nominal_coverage: float = NOMINAL
    simulations: int = 0
    reason: str | None = None
    cause: str = NOISE_CAUSE
    measured_route: str | None = None
    measured_understated_by: float | None = None
    reduced_chi2_measured: float | None = None
    coverage_measured: float | None = None
    correlation: PoseCorrelation | None = None
    random_walk: RandomWalkCheck | None = None

    def to_dict(self) -> dict[str, Any]:
        out = asdict(replace(self, correlation=None, random_walk=None))
        out["correlation"] = None if self.correlation is None else self.correlation.to_dict()
        out["random_walk"] = None if self.random_walk is None else self.random_walk.to_dict()
        return out


def reduced_chi2(fitter: Fitter, fit: Fit) -> float:
    """``Σ w_k r_k² / (n − p)`` with the absolute weights of the given σ."""
    return fit.rss * fitter.w_mean / max(fitter.n - fit.n_params, 1)


def extra_noise(r: NDArray, w_abs: NDArray, gain2: NDArray, dof: int) -> float:
    """``τ²`` solving ``Σ r_k² / (1/w_k + g_k² τ²) = dof`` (zero when the given σ already suffices)."""
    def excess(tau2: float) -> float:
        return float(np.sum(r**2 / (1.0 / w_abs + gain2 * tau2))) - dof

    if excess(0.0) <= 0:
        return 0.0
    hi = float(np.max(r**2 / gain2)) * len(r) + 1e-300
    return float(optimize.brentq(excess, 0.0, hi, xtol=1e-30, rtol=1e-12))


def pose_correlation(fitter: Fitter, fit: Fit, alpha: float, measured: MeasuredPoseNoise | None = None,
                     use: str = "auto") -> PoseCorrelation:
    """The correlation of the pose noise in time under ``fit`` (:mod:`optcal.applications.diagnosis.correlation`).

    It is used (``used``) when the likelihood-ratio test against independent poses is significant
    at ``alpha``, or when the noise of the pose means measured on the recording's still parts
    (``measured``, :mod:`optcal.applications.diagnosis.still_noise`) is at least :data:`CORRELATED_RATIO` times
    σ/√n: noise that does not average down within a pose is noise at the pose's time scale or
    longer, which neighbouring poses share, so the correlation is then estimated even where the
    residuals alone cannot establish it (a few dozen poses).  The residuals' own excess over σ/√n
    is no such evidence: an effect not yet in the model (a drift) makes it too.  ``use``: ``auto``
    (as said), ``off`` (poses independent) or ``on`` (the estimate used whatever the evidence).
    """
    if use == "off":
        return PoseCorrelation(False, reason="switched off (pose_correlation='off'): the poses are treated as independent")
    G, J = fitter.jacobians(fit, fitter.w)
    trends = [9 + BETA_INDEX[(effect, axis, 1)] for effect in SMOOTH_TERMS if fitter.reg.supports(effect)
              for axis in range(3)]
    if trends and fitter.n - G.shape[1] - len(trends) >= MIN_DOF:  # a trend is not taken for correlated noise
        G = np.column_stack([G, J[:, trends]])
    e = np.sqrt(fitter.w) * fit.residuals
    t = fitter.poses.t if fitter.reg.has_time else None
    evidence = "the request pose_correlation='on'" if use == "on" else None
    if evidence is None and measured is not None and measured.sigma is not None and fitter.poses.sigma is not None:
        ratio = float(np.median(measured.sigma / np.asarray(fitter.poses.sigma, float)))
        if ratio >= CORRELATED_RATIO:
            evidence = (f"the noise of the pose means measured on the still parts, {ratio:.3g}× σ/√n "
                        f"(from {CORRELATED_RATIO:g}×: noise that does not average down within a pose)")
    return estimate_correlation(e, G, t, fitter.reg.session, fitter.pose_normals(fit), alpha, evidence)


def correlation_with_steps(fitter: Fitter, fit: Fit, alpha: float, baseline: PoseCorrelation) -> PoseCorrelation:
    """The pose-noise correlation estimated again under ``fit``, whose bias steps were just accepted (or one of whose
    knocks was just dropped, :meth:`~optcal.applications.diagnosis.selection.ForwardSelection.backward_check`): the same REML and
    bounds as the baseline's (:func:`pose_correlation`, ``use="on"``), with ``fit``'s terms, its steps included, among
    its fixed effects.  Knocks not yet in the model read as noise shared by neighbouring poses and inflate the
    baseline's estimate (mikoff imu0 with x 6 + y 4 mg written in: ρ₀ 0.95, τ 14 s; with the steps 0.8, 0.70 s);
    the selection carries this one for its later tests, the standard errors and the limits.  It is used whatever
    its own test says, as the baseline's was; ``ρ₀ = 0`` leaves the poses independent (``operator`` ``None``).
    """
    again = pose_correlation(fitter, fit, alpha, use="on")
    return replace(again, reason=baseline.reason, estimated_with=fit.describe(),
                   baseline=baseline if baseline.baseline is None else baseline.baseline)


def covariance_absolute(fitter: Fitter, fit: Fit, data: PoseData | None = None) -> NDArray[np.float64]:
    """Covariance of the free normalised parameters with the absolute weights (σ taken as known);
    ``(Gᵀ R⁻¹ G)⁻¹`` under the fitter's pose-noise correlation when it has one."""
    G, _ = fitter.jacobians(fit, fitter.weights(fit), data)
    info = G.T @ (G if fitter.correlation is None else fitter.correlation.solve(G))
    return np.linalg.pinv(info, rcond=1e-13, hermitian=True) / fitter.w_mean


def check_noise_model(fitter: Fitter, final: Fit, alpha: float, simulations: int, seed: int,
                      refit: Callable[[PoseTable], tuple[Fitter, Fit]], loop: Loop = plain_loop,
                      measured: MeasuredPoseNoise | None = None) -> NoiseModelCheck:
    """Test, extend and check the noise model of ``final`` (module docstring).

    ``refit(poses) -> (Fitter, Fit)`` refits the final model's terms to a pose table with other
    σ (the diagnoser's own fitting, so the terms and the start are the same); ``measured`` is
    the noise of each pose mean measured on the recording's still parts (the measured route).
    """
    poses = fitter.poses
    if poses.sigma is None:
        return NoiseModelCheck(False, reason="no per-pose σ given: the noise scale is estimated from the residuals")
    kept = final.kept(fitter.n)
    dof = fitter.n - final.n_params
    if dof < 1:
        return NoiseModelCheck(False, reason="no residual degrees of freedom")
    chi2 = reduced_chi2(fitter, final)
    p = float(sps.chi2.sf(chi2 * dof, dof))
    check = NoiseModelCheck(True, chi2, p, bool(p < alpha), reduced_chi2_after=chi2)
    if measured is not None:
        check.measured_route = measured.source
        if measured.sigma is not None:
            check.measured_understated_by = float(np.median(measured.sigma / np.asarray(poses.sigma, float)))
            fitter_m, fit_m = refit(replace(poses, sigma=measured.sigma))
            check.reduced_chi2_measured = reduced_chi2(fitter_m, fit_m)
            if simulations and check.named:
                _, check.coverage_measured = bootstrap_coverage(fitter, fitter_m, fit_m, simulations, seed, loop)
    if not check.named:
        return check
    sigma = np.asarray(poses.sigma, float)
    fitter2, fit2 = fitter, final
    tau2 = 0.0
    gain2 = np.ones(fitter.n)
    for _ in range(2):  # τ from the residuals, refit with σ', τ again from the refit's residuals
        w_abs = fitter2.w * fitter2.w_mean
        gain2 = 1.0 / (w_abs * np.asarray(fitter2.poses.sigma, float) ** 2)
        # the residual variance of pose k under σ' is g_k²(σ_k² + τ²) = 1/w_k(σ) + g_k² τ²
        w_given = 1.0 / (gain2 * sigma**2)
        tau2 = extra_noise(fit2.residuals[kept], w_given[kept], gain2[kept], dof)
        fitter2, fit2 = refit(replace(poses, sigma=np.sqrt(sigma**2 + tau2)))
    check.extra_noise = float(np.sqrt(tau2))
    check.extra_noise_g = float(np.sqrt(tau2) * np.median(np.sqrt(gain2)))
    check.understated_by = float(np.median(np.sqrt(sigma**2 + tau2) / sigma))
    check.reduced_chi2_after = reduced_chi2(fitter2, fit2)
    if simulations:
        check.simulations = simulations
        check.coverage_given_sigma, check.coverage_extended = bootstrap_coverage(
            fitter, fitter2, fit2, simulations, seed, loop)
    return check


def bootstrap_coverage(given: Fitter, extended: Fitter, fit: Fit, simulations: int, seed: int,
                       loop: Loop = plain_loop) -> tuple[float, float]:
    """Coverage of nominal 95 % intervals of θ, simulated with ``σ'`` and judged with σ and with ``σ'``."""
    rng = np.random.default_rng(seed)
    n = extended.n
    clean = extended.noise_free(fit)
    truth = fit.x[:9]
    z = float(sps.norm.isf((1 - NOMINAL) / 2))
    sigma = np.asarray(extended.poses.sigma, float)
    hits = {"given": 0, "extended": 0}
    count = 0
    for _ in loop(range(simulations), "noise-model coverage", simulations):
        acc = clean + pose_noise(extended, rng) * sigma[:, None]
        data = PoseData.of(extended.norm.forward(acc), extended.reg, extended.data.step)
        sim = extended.fit(fit.terms, fit.outliers, fit.x, data)
        error = np.abs(sim.x[:9] - truth)
        for name, fitter in (("given", given), ("extended", extended)):
            se = np.sqrt(np.maximum(np.diag(covariance_absolute(fitter, sim, data))[:9], 0.0))
            # both fitters normalise the same measurements identically (same centre and scale)
            hits[name] += int(np.sum(error < z * se))
        count += 9
    return hits["given"] / count, hits["extended"] / count

