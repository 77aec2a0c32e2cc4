"""The bias wandering in time as a random walk: a stochastic explanation the diagnosis tests and names.

Issue 13, item 2: a bias that rises and falls over a recording (bias instability at the scale
of minutes, warm-up then cooling) has almost no linear component, so the polynomial time terms
of the selection may miss it.  :class:`~optcal.families.accel.random_walk_bias.RandomWalkBias` fits
``T``, ``o`` and the walk's intensity ``K`` jointly by maximum likelihood; here that fit is run
on the session's poses — about the diagnosis's final model, the named effects' share of each
pose taken out first (:meth:`optcal.applications.diagnosis.diagnoser.Diagnoser.random_walk`) — and judged as a *noise* explanation ("the bias wanders"), never as a
deterministic effect: it is reported in the noise section, it does not enter the forward
selection, and it cannot remove a finding.  It is named when the boundary likelihood-ratio test
of ``K = 0`` is significant at the diagnosis's level *and* the walk predicts held-out poses
better than the white-noise calibration (k-fold, every k-th pose in time held out, its bias
predicted from the training poses around it).

The white noise of a pose mean is taken as what is known of it, not estimated together with
the walk (with a few dozen poses a walk explains white noise too, and the joint estimate drifts
toward a walk without white noise): the noise measured on the recording's still parts when
there is one (:mod:`optcal.applications.diagnosis.still_noise`), else the table's ``σ`` as given.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.still_noise import MeasuredPoseNoise
from optcal.errors import InputError
from optcal.families.accel.random_walk_bias import RandomWalkBias
from optcal.core.model import theta_from, unpack_theta
from optcal.core.norm_residual import norm_residuals
from optcal.core.poses import PoseTable
from optcal.core.stats import rms

#: Folds of the held-out comparison (every k-th pose in time order held out).
FOLDS: int = 5
#: Fewest poses the walk is tested on.
MIN_POSES: int = 15
CAUSE = "the bias wanders in time (a random walk: bias instability), not a deterministic effect"


@dataclass
class AllanComparison:
    """The walk's ``K`` from the poses against the rate random walk the still parts' Allan deviation shows.

    The Allan deviation of a bias random walk rises as ``K √(τ/3)`` (``optcal allan``'s rate random
    walk, Yin 2014, Table 1).  Where the still parts resolve that +½ slope on every axis, their
    ``K`` (rms over the axes) and its interval are compared with the poses'; where they do not
    (still stretches shorter than the τ at which the walk rises above the curve's floor), the
    curve still bounds ``K`` from above (:func:`optcal.families.noise.allan.rate_random_walk_bound`) and
    the τ a still recording would have to reach is stated.

    Attributes
    ----------
    source : str
        The still parts the Allan deviation comes from.
    tau_max_s : float
        Longest averaging time of the curve, s.
    K_bound_g, K_bound_tau_s : float
        The largest ``K`` the curve allows (g/√s) and the τ that sets it.
    K_allan_g : float or None
        The rate random walk resolved on the still parts (rms over the axes), g/√s.
    K_allan_interval_g : tuple of float or None
        Its interval (rms over the axes of each axis's bounds) at :attr:`allan_level`.
    allan_level : float or None
        Confidence level of that interval (``optcal allan``'s, one sigma).
    tau_needed_s : float or None
        The τ from which a walk of the poses' ``K`` rises above the curve's lowest value
        (``K² τ/3 = σ_min²``): the still recording needs several times that.
    consistent : bool
        The two agree: the intervals overlap, or (not resolved) the poses' interval reaches below the bound.
    """

    source: str
    tau_max_s: float
    K_bound_g: float
    K_bound_tau_s: float
    K_allan_g: float | None = None
    K_allan_interval_g: tuple[float, float] | None = None
    allan_level: float | None = None
    tau_needed_s: float | None = None
    consistent: bool = True

    def text(self, K_g: float) -> str:
        """One sentence, the poses' ``K_g`` in it."""
        mg = 1e3
        if self.K_allan_g is not None and self.K_allan_interval_g is not None:
            lo, hi = self.K_allan_interval_g
            verdict = "they agree" if self.consistent else "they disagree"
            return (f"the still parts' Allan deviation resolves a rate random walk K = {self.K_allan_g * mg:.3g} mg/√s "
                    f"({self.allan_level:.0%} {lo * mg:.3g}–{hi * mg:.3g}): {verdict} with the poses' "
                    f"{K_g * mg:.3g} mg/√s")
        need = ""
        if self.tau_needed_s is not None and self.tau_needed_s > self.tau_max_s:
            need = (f"; a walk of {K_g * mg:.3g} mg/√s would rise above the curve's floor only from τ ≈ "
                    f"{self.tau_needed_s:.3g} s, so a still recording several times that long would measure it")
        elif self.tau_needed_s is not None:
            need = f"; a walk of {K_g * mg:.3g} mg/√s would show in it from τ ≈ {self.tau_needed_s:.3g} s"
        verdict = ("consistent with the poses' K" if self.consistent
                   else f"below the poses' K = {K_g * mg:.3g} mg/√s: what wanders between the poses is not the "
                        "sensor's noise at those time scales")
        return (f"the still parts' Allan deviation reaches τ = {self.tau_max_s:.3g} s without a rate-random-walk "
                f"slope and bounds it at K ≤ {self.K_bound_g * mg:.3g} mg/√s (at τ = {self.K_bound_tau_s:.3g} s), "
                f"{verdict}{need}")

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["K_allan_interval_g"] = None if self.K_allan_interval_g is None else list(self.K_allan_interval_g)
        return out


def compare_with_allan(still: MeasuredPoseNoise, K_g: float, K_interval_g: tuple[float, float],
                       g_per_raw: float) -> AllanComparison | None:
    """The poses' walk (``K_g`` and its interval, g/√s) against the still parts' Allan deviation (raw units),
    or ``None`` when no Allan deviation was measured (:class:`AllanComparison`)."""
    from optcal.families.noise.allan import fit_noise_parameters, rate_random_walk_bound

    if still.taus_s is None or still.adev is None or still.taus_s.size == 0:
        return None
    bound, at = rate_random_walk_bound(still.taus_s, still.adev)
    out = AllanComparison(still.source, float(still.taus_s[-1]), bound * g_per_raw, at)
    if still.curves is not None:
        fitted = [fit_noise_parameters(curve) for curve in still.curves]
        ks = [f.rate_random_walk for f in fitted if f.rate_random_walk is not None]
        cis = [f.ci["rate_random_walk"] for f in fitted if f.ci.get("rate_random_walk") is not None]
        if len(ks) == len(fitted) and len(cis) == len(fitted):  # every axis has its walk and interval
            out.K_allan_g = rms(ks) * g_per_raw
            out.K_allan_interval_g = (rms([ci[0] for ci in cis]) * g_per_raw,
                                      rms([ci[1] for ci in cis]) * g_per_raw)
            out.allan_level = float(still.curves[0].confidence)
            out.consistent = bool(out.K_allan_interval_g[0] <= K_interval_g[1] and K_interval_g[0] <= out.K_allan_interval_g[1])
            return out
    if K_g > 0:
        out.tau_needed_s = float(3.0 * (np.min(still.adev) * g_per_raw) ** 2 / K_g**2)
    out.consistent = bool(K_interval_g[0] <= out.K_bound_g)
    return out


@dataclass
class RandomWalkCheck:
    """The random-walk bias tested on one diagnosis's poses.

    Attributes
    ----------
    tested : bool
        Whether the walk was fitted (``reason`` says why not).
    named : bool
        Significant at the diagnosis's level and better on held-out poses: named as a cause.
    K_g, K_interval_g : float, tuple of float
        The walk's intensity ``K`` (its increments' standard deviation over one second) and its
        95 % profile-likelihood interval, in g/√s.
    p_value : float
        Boundary likelihood-ratio test of ``K = 0`` (Self & Liang 1987).
    noise_scale, noise_scale_source : float, str
        The white pose noise used, relative to the table's σ, and where it comes from.
    wander_rms_g : float
        RMS of the smoothed bias about its mean over the session(s), g.
    heldout_rms_white_g, heldout_rms_walk_g : float
        RMS of the held-out norm residuals of the white-noise calibration and of the walk's
        prediction (:data:`FOLDS`-fold), g.
    """

    tested: bool
    reason: str | None = None
    named: bool = False
    K_g: float = 0.0
    K_interval_g: tuple[float, float] = (0.0, 0.0)
    p_value: float = 1.0
    noise_scale: float = 1.0
    noise_scale_source: str = ""
    wander_rms_g: float = 0.0
    heldout_rms_white_g: float = float("nan")
    heldout_rms_walk_g: float = float("nan")
    folds: int = FOLDS
    cause: str = CAUSE
    allan: AllanComparison | None = None

    def text(self) -> str:
        """One line for the report's noise section."""
        if not self.tested:
            return f"random-walk bias: not tested ({self.reason})"
        mg = 1e3
        head = (f"random-walk bias: K = {self.K_g * mg:.3g} mg/√s (95 % {self.K_interval_g[0] * mg:.3g}–"
                f"{self.K_interval_g[1] * mg:.3g}), p = {self.p_value:.2g}; the bias wanders {self.wander_rms_g * mg:.3g} mg "
                f"rms; held-out rms {self.heldout_rms_white_g * mg:.3g} → {self.heldout_rms_walk_g * mg:.3g} mg "
                f"({self.folds}-fold); white pose noise {self.noise_scale:.3g}× σ ({self.noise_scale_source})")
        tail = "" if self.allan is None else f"; {self.allan.text(self.K_g)}"
        return (f"named cause: {self.cause}. " if self.named else "not named: ") + head + tail

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["K_interval_g"] = list(self.K_interval_g)
        out["allan"] = None if self.allan is None else self.allan.to_dict()
        return out


def check_random_walk(poses: PoseTable, T: NDArray, o: NDArray, session: NDArray | None, alpha: float,
                      measured_ratio: float | None, still: MeasuredPoseNoise | None = None) -> RandomWalkCheck:
    """Fit and judge the random-walk bias on ``poses`` about the white-noise calibration ``(T, o)``.

    Parameters
    ----------
    poses : PoseTable
        The diagnosed poses (times ``t`` in seconds, per-pose ``σ``).
    T, o : ndarray
        The baseline calibration (the start of the fit).
    session : ndarray of int or None
        Session of each pose (the walk restarts in each).
    alpha : float
        The diagnosis's significance level.
    measured_ratio : float or None
        The noise of the pose means measured on the still parts over σ/√n (median), if measured.
    still : MeasuredPoseNoise, optional
        The still parts' Allan deviation, which the walk's ``K`` is compared with (:class:`AllanComparison`).
    """
    n = poses.n
    if poses.t is None:
        return RandomWalkCheck(False, reason="the poses have no times")
    if poses.sigma is None:
        return RandomWalkCheck(False, reason="the poses have no per-pose σ, so the white noise is not known")
    if n < MIN_POSES:
        return RandomWalkCheck(False, reason=f"{n} poses are fewer than the {MIN_POSES} it is tested on")
    scale, source = ((measured_ratio, "measured on the still parts") if measured_ratio is not None
                     else (1.0, "the given σ, trusted: no still parts were measured"))
    session = np.zeros(n, dtype=int) if session is None else np.asarray(session, dtype=int)
    estimator = RandomWalkBias(noise_scale=scale)
    theta0 = theta_from(T, o)
    try:
        fit = estimator.fit(poses, theta0, session)
        order = np.lexsort((poses.t, session))
        fold_of = np.empty(n, dtype=int)
        fold_of[order] = np.arange(n) % FOLDS
        white, walk = [], []
        for k in range(FOLDS):
            test, train = fold_of == k, fold_of != k
            tr, te = poses.subset(np.flatnonzero(train)), poses.subset(np.flatnonzero(test))
            # a fold's profile is the session's with a fifth of the poses out: its search starts at the
            # session's lowest λ (RandomWalkBias.fit, near), and it needs no interval
            fold = estimator.fit(tr, theta0, session[train], interval=False, near=fit.lam_lowest)
            walk.append(estimator.predict_heldout(tr, te, fold, session[train], session[test]))
            white.append(norm_residuals(*unpack_theta(fold.theta_white), te.acc))
    except (np.linalg.LinAlgError, InputError, ValueError) as err:  # ValueError: a profile interval not bracketed
        return RandomWalkCheck(False, reason=f"the fit failed: {err}")
    g_per_raw = float(np.mean(np.abs(np.diag(T))))  # raw units → g (T maps raw to g)
    rms_white = rms(np.concatenate(white))
    rms_walk = rms(np.concatenate(walk))
    K_g = fit.K * g_per_raw
    K_interval_g = (fit.K_interval[0] * g_per_raw, fit.K_interval[1] * g_per_raw)
    return RandomWalkCheck(
        True, named=bool(fit.p_value < alpha and rms_walk < rms_white), K_g=K_g, K_interval_g=K_interval_g,
        p_value=fit.p_value, noise_scale=scale, noise_scale_source=source, wander_rms_g=fit.wander_rms * g_per_raw,
        heldout_rms_white_g=rms_white, heldout_rms_walk_g=rms_walk,
        allan=None if still is None else compare_with_allan(still, K_g, K_interval_g, g_per_raw),
    )
