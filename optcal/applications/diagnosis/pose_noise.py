"""Whether the per-pose σ ranks the poses' noise: a pose-to-pose noise that does not average down.

The diagnosis weighs each pose by ``1/σ_k²`` (Lu 2017, eq. 14), ``σ_k`` the noise of the pose's mean measured on
its own samples (:func:`optcal.data.static_poses.sigma_of_mean`).  The F tests estimate the noise *scale* from the
residuals, so a σ that is off by a common factor does no harm; a σ whose *ratios* are wrong does: the poses with
a small σ carry the fit, and a pose that is ordinary by the scatter of the others is "an outlier", a curve through
the heaviest poses "a drift".  On strangers' recordings the pose means scatter by about the same amount whatever
their own σ (mgiurato's MPU-6050 held by hand: σ_k 0.25-2.7 mg, the residuals 1.4 mg rms with no relation to it;
docs/diagnosis.md "On strangers' recordings"): part of the error of a pose mean is made once per pose (a hand's
hold, a rig's ringing, the placement, a small unmodelled effect) and no number of samples averages it down.

Model: the norm residual of pose ``k`` has variance ``g_k² (λ σ_k² + τ²)``, ``g_k`` the norm's gain along the pose
(the Fitter's ``w_k`` holds ``1/(g_k σ_k)²``), ``λ`` a common factor on the logger's σ, ``τ`` a pose-to-pose noise
in raw units.  ``λ`` and ``τ²`` are estimated by maximum likelihood on the baseline's residuals, each residual's
variance reduced by its leverage ``(1 − h_k)`` (the fit absorbs part of a heavy pose's error; without it the
heaviest poses' small residuals would vouch for their own weight), on the σ-weighted baseline without refitting
(refitting with the estimated weights first made the test its own evidence: 21 of 200 generated sessions with an
exact σ rejected at 0.02, against 3 of 200 without).  ``τ² = 0``
(σ alone) is tested by the likelihood ratio, ``τ² ≥ 0`` on its boundary: ``p = ½ P(χ²₁ > LR)`` (Self & Liang
1987).  Used when ``p < alpha`` (the diagnosis' level) **and** the weights it gives change the fit (relevance):
the ratio of the largest to the smallest pose weight changes by more than :data:`RELEVANT_RATIO`.  Each pose's
σ is then the fitted noise of its mean, ``√(λ σ_k² + τ²)`` (what the simulations draw, and what the noise-model
check then reads); ``pose_noise="given"`` keeps the σ as logged, ``"floor"`` uses the estimate whatever its test
says.

Under ``given`` (the default) a pose-to-pose noise found significant and relevant (:func:`misweighs`) puts each
named effect to its test again with σ widened (:func:`effects_under_pose_noise`), printed beside it: whether the
finding stands without the σ's ratios.  The widening is the one estimated on the final model *without* the effect,
as ``auto`` estimates it on the baseline: on generated sessions whose σ spreads 60× and misses a pose noise of
0.3-1 mg, a quadratic drift's F test (15-80 poses, no drift) rejected 6-65 of 200 at 0.02 with σ alone, 0-3 of 200
with that widening, but 5-15 of 200 with τ re-estimated with the drift in the model, and the likelihood ratio of
the two profiled likelihoods (λ, τ² and the fit estimated jointly under each model, a mixed model's test, in its
F form ``(e^(LR/n) − 1)(n − p)/q``) 5-18 of 200: the candidate's own fit lowers τ and so vouches for itself
(docs/diagnosis.md, "On strangers' recordings").  With σ exact (τ = 0) all of them held (0-3 of 200).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats as sps

from optcal.applications.diagnosis.effects import BIAS_STEP, describe_term
from optcal.applications.diagnosis.fitting import Fit, Fitter
from optcal.applications.diagnosis.outliers import detect_outliers
from optcal.core.poses import PoseTable

#: The choices of ``pose_noise`` (``optcal diagnose --pose-noise``).
POSE_NOISE_CHOICES: tuple[str, ...] = ("auto", "given", "floor")
#: Relevance: the floor is used only when it changes the spread of the pose weights (largest over smallest) by
#: more than this factor; below it the weights, and so every test and estimate, stay within a few per cent of
#: the σ-only fit's and the σ as logged is kept.
RELEVANT_RATIO: float = 1.5


@dataclass(frozen=True)
class UnderPoseNoise:
    """A named effect tested again with each pose's σ widened by the pose-to-pose noise estimated without it.

    Attributes
    ----------
    term : str
        The term (``bias_drift(z, order 2)``) or the outlier set (``outliers(8 poses)``).
    tau_without_g, tau_with_g : float
        ``τ`` estimated on the final model without the effect and with it (g, by the norm's median gain): a real
        effect the model lacks inflates the first; the second is the pose noise the effect leaves.
    p_given : float or None
        A term's F test given the other effects with σ as logged (``None`` for outliers: the set entered along the
        selection's path, and its evidence is the finding's).
    p_value : float
        The same test with σ widened; for outliers the smallest Bonferroni p of the poses the outlier search sets
        aside from the model without them (1 when it sets none aside).
    threshold : float
        The level the effect entered at.
    stands : bool
        ``p_value < threshold`` (and for outliers every pose of the set is set aside again).
    outliers_again : int or None
        For outliers: how many poses of the set the search sets aside again under the widened σ.
    """

    term: str
    tau_without_g: float
    tau_with_g: float
    p_given: float | None
    p_value: float
    threshold: float
    stands: bool
    outliers_again: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the check."""
        out = {"term": self.term, "tau_without_g": self.tau_without_g, "tau_with_g": self.tau_with_g,
               "p_given": self.p_given, "p_value": self.p_value, "threshold": self.threshold, "stands": self.stands}
        return out if self.outliers_again is None else {**out, "outliers_again": self.outliers_again}


@dataclass(frozen=True)
class PoseNoiseFloor:
    """The pose-to-pose noise added to each pose's σ, and its test.

    Attributes
    ----------
    tested : bool
        ``False`` without a per-pose σ or without residual degrees of freedom (``reason`` says why).
    used : bool
        The σ of the diagnosis is ``√(σ_k² + τ²/λ)``.
    tau : float
        ``τ``, raw units; ``tau_g`` in g.
    scale : float
        ``λ``, the common factor on ``σ_k²``.
    lr, p_value : float
        Likelihood ratio against ``τ = 0`` and its boundary p value.
    weight_spread_given, weight_spread_floor : float
        Largest over smallest pose weight with the σ as logged and with the floor.
    share : float
        Median over the poses of ``τ² / (λ σ_k² + τ²)``: the part of a pose's noise the floor carries.
    reason : str
        Why it is used or not, in words.
    effects : tuple of UnderPoseNoise
        The named effects tested again with σ widened (:func:`effects_under_pose_noise`; empty unless the floor
        :func:`misweighs` the poses and is not used).
    """

    tested: bool
    used: bool = False
    tau: float = 0.0
    tau_g: float = 0.0
    scale: float = 1.0
    lr: float = 0.0
    p_value: float = 1.0
    weight_spread_given: float = 1.0
    weight_spread_floor: float = 1.0
    share: float = 0.0
    reason: str = ""
    effects: tuple[UnderPoseNoise, ...] = field(default=(), compare=False)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the check (``effects`` only when some were tested again)."""
        out: dict[str, Any] = {
            "tested": self.tested, "used": self.used, "tau": self.tau, "tau_g": self.tau_g, "scale": self.scale,
            "lr": self.lr, "p_value": self.p_value, "weight_spread_given": self.weight_spread_given,
            "weight_spread_floor": self.weight_spread_floor, "share": self.share, "reason": self.reason}
        if self.effects:
            out["effects"] = [e.to_dict() for e in self.effects]
        return out


def leverage(fitter: Fitter, fit: Fit) -> NDArray[np.float64]:
    """``h_k``, the diagonal of the weighted hat matrix of ``fit``'s free parameters (independent poses; ``fit``'s
    outlier poses, each fitted by its own mean shift, weigh nothing and get 0)."""
    G, _ = fitter.jacobians(fit, fitter.weights(fit))
    info = np.linalg.pinv(G.T @ G, rcond=1e-13, hermitian=True)
    return np.clip(np.einsum("ij,jk,ik->i", G, info, G), 0.0, 1.0 - 1e-9)


def _estimate(r2: NDArray, sigma2: NDArray, gain2: NDArray, tau_free: bool) -> tuple[float, float, float]:
    """``(λ, τ², −log L)`` maximising the Gaussian likelihood of ``r²`` (each divided by ``1 − h``)."""
    def nll(p: NDArray) -> float:
        v = gain2 * (np.exp(p[0]) * sigma2 + (np.exp(p[1]) if tau_free else 0.0))
        return float(0.5 * np.sum(np.log(v) + r2 / v))

    lam0 = float(np.mean(r2 / (gain2 * sigma2)))
    start = [np.log(lam0)] + ([np.log(lam0 * float(np.median(sigma2)))] if tau_free else [])
    best = optimize.minimize(nll, start, method="Nelder-Mead",
                             options={"xatol": 1e-8, "fatol": 1e-10, "maxiter": 4000})
    lam = float(np.exp(best.x[0]))
    tau2 = float(np.exp(best.x[1])) if tau_free else 0.0
    return lam, tau2, float(best.fun)


def _relevant(spread_given: float, spread_floor: float) -> bool:
    """Whether the floor changes the pose weights' spread by more than :data:`RELEVANT_RATIO`."""
    return spread_given > RELEVANT_RATIO * spread_floor


def misweighs(floor: PoseNoiseFloor, alpha: float) -> bool:
    """Whether the test found a pose-to-pose noise significant at ``alpha`` that changes the weights (relevant)."""
    return floor.tested and floor.p_value < alpha and _relevant(floor.weight_spread_given, floor.weight_spread_floor)


def pose_noise_floor(fitter: Fitter, base: Fit, alpha: float, use: str = "auto") -> PoseNoiseFloor:
    """Test a pose-to-pose noise beside the per-pose σ on the baseline ``base`` (module docstring)."""
    poses = fitter.poses
    if poses.sigma is None:
        return PoseNoiseFloor(False, reason="no per-pose σ: the poses are weighted equally")
    if fitter.n - base.n_params < 3:
        return PoseNoiseFloor(False, reason="too few residual degrees of freedom to estimate a pose-to-pose noise")
    sigma2 = np.asarray(poses.sigma, float) ** 2
    if not np.all(np.isfinite(sigma2) & (sigma2 > 0)):  # a σ of zero would be a pose of infinite weight
        return PoseNoiseFloor(False, reason="a per-pose σ is zero or not finite: the pose-to-pose noise is not tested")
    gain2 = 1.0 / (fitter.w * fitter.w_mean * sigma2)  # g_k², the norm's gain along pose k
    kept = base.kept(fitter.n)  # an outlier pose's residual is its own mean shift's: it says nothing of the noise
    r2 = (base.residuals**2 / (1.0 - leverage(fitter, base)))[kept]
    lam, tau2, nll1 = _estimate(r2, sigma2[kept], gain2[kept], True)
    _, _, nll0 = _estimate(r2, sigma2[kept], gain2[kept], False)
    lr = max(2.0 * (nll0 - nll1), 0.0)
    p = float(0.5 * sps.chi2.sf(lr, 1)) if lr > 0 else 1.0
    floor = sigma2 + tau2 / lam
    spread_given = float(np.max(1 / sigma2) / np.min(1 / sigma2))
    spread_floor = float(np.max(1 / floor) / np.min(1 / floor))
    share = float(np.median(tau2 / (lam * sigma2 + tau2)))
    relevant = _relevant(spread_given, spread_floor)
    tau = float(np.sqrt(tau2))
    tau_g = tau * float(np.sqrt(np.median(gain2)))  # in the residuals' unit (g), by the norm's median gain
    used = use == "floor" or (use == "auto" and p < alpha and relevant)
    why = (f"a pose-to-pose noise of {tau_g * 1e3:.3g} mg beside each pose's σ/√n (median {share * 100:.0f} % "
           f"of a pose's noise), likelihood ratio {lr:.3g}, p = {p:.2g} against σ alone; the pose weights' spread "
           f"{spread_given:.3g}× → {spread_floor:.3g}×")
    if use == "floor":
        reason = f"used (pose_noise='floor'): {why}"
    elif use == "given" and p < alpha and relevant:
        reason = (f"not used (pose_noise='given', the default): {why}; significant at {alpha:g}, so the σ's ratios "
                  "misweigh the poses: pose_noise='auto' weighs them by the fitted noise")
    elif used:
        reason = f"used: {why} (significant at {alpha:g} and it changes the weights' spread by more than {RELEVANT_RATIO:g}×)"
    elif p < alpha:
        reason = f"not used: {why} (it changes the weights' spread by under {RELEVANT_RATIO:g}×)"
    else:
        reason = f"not used: {why} (not significant at {alpha:g}: the σ's ratios describe the poses' scatter)"
    return PoseNoiseFloor(True, used, tau, tau_g, lam, lr, p, spread_given, spread_floor, share, reason)


def with_floor(poses: PoseTable, floor: PoseNoiseFloor) -> PoseTable:
    """``poses`` with each σ the fitted noise of its mean, ``√(λ σ_k² + τ²)`` (unchanged when the floor is not used)."""
    if not floor.used or poses.sigma is None:
        return poses
    sigma = np.asarray(poses.sigma, float)
    return replace(poses, sigma=np.sqrt(floor.scale * sigma**2 + floor.tau**2))


def effects_under_pose_noise(fitter: Fitter, final: Fit, levels: Mapping[tuple[str, int], float],
                             outlier_level: float | None, alpha: float,
                             widened: Callable[[PoseTable], Fitter]) -> tuple[UnderPoseNoise, ...]:
    """Each named term (and the outlier set) of ``final`` tested again with σ widened (module docstring).

    For each term: the model without it is fitted with σ as logged, the floor estimated on its residuals
    (:func:`pose_noise_floor`, used whatever its own test says), and the term's F test repeated under the widened
    σ (``widened`` builds the fitter of a pose table, the bias steps placed).  The outlier set: the model without
    it is searched for outliers again under σ widened by the floor estimated on it, at ``outlier_level``.
    Bias steps (their position was searched under the σ as logged) and ``levels`` missing a term are not tested.
    """
    out: list[UnderPoseNoise] = []
    tau_with = pose_noise_floor(fitter, final, alpha, "floor").tau_g  # the pose noise the effects leave: once

    def again(small: Fit) -> tuple[PoseNoiseFloor, Fitter, Fit]:
        floor = pose_noise_floor(fitter, small, alpha, "floor")
        wide = widened(with_floor(fitter.poses, floor))
        return floor, wide, wide.fit(small.terms, small.outliers, small.x)

    for key, order in final.terms.items():
        if key[0] == BIAS_STEP or key not in levels:
            continue
        small = fitter.fit({k: v for k, v in final.terms.items() if k != key}, final.outliers, final.x)
        floor, wide, small_w = again(small)
        p = wide.f_test(small_w, wide.fit(final.terms, final.outliers, final.x))
        level = levels[key]
        out.append(UnderPoseNoise(describe_term(key[0], key[1], order), floor.tau_g, tau_with,
                                  fitter.f_test(small, final), p, level, p < level))
    if final.outliers and outlier_level is not None:
        small = fitter.fit(final.terms, frozenset(), final.x)
        floor, wide, small_w = again(small)
        found = detect_outliers(wide, small_w, outlier_level)
        kept = 0 if found is None else len(found.poses & final.outliers)
        n_out = len(final.outliers)
        out.append(UnderPoseNoise(f"outliers({n_out} poses)", floor.tau_g, tau_with,
                                  None, 1.0 if found is None else found.p_value, outlier_level, kept == n_out, kept))
    return tuple(out)
