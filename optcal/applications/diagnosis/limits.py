"""Detection limits: the smallest effect of each candidate term the selection would have named.

For a candidate added alone to a fitted model, the limit is ``z × SE``: ``SE`` the standard
error of its first-order coefficient (Fisher information, noise scale from the residuals) and
``z`` the two-sided normal quantile of the per-candidate level the selection tests it at.  An
effect this large passes the test about half the time; twice as large, almost always.  When the
pose noise is correlated in time (:mod:`optcal.applications.diagnosis.correlation`) the standard error is the
generalised least-squares one, ``(Gᵀ R⁻¹ G)⁻¹``, the one the selection's test has: a limit computed
as if the poses were independent would overstate the power for terms smooth in time.

For outlier poses (:func:`outlier_limit`) the limit is the shift of one pose along its own direction
(the only part the norm residual sees) at which its deleted-residual test is at its critical value:
``t × s × √var_k``, with ``t`` the Student quantile of the Bonferroni level over the poses and
``var_k`` the variance of pose ``k``'s mean shift in the fit without it,
``1 / (R⁻¹_kk − zₖᵀ (Hᵀ R⁻¹ H)⁻¹ zₖ)``, ``zₖ = Hᵀ R⁻¹ eₖ`` (``R = I``: ``1/(1 − h_kk)``, the
leverage).  It depends on where the pose lies: a pose in a direction few others share is largely
absorbed by the fit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats as sps

from optcal.applications.diagnosis.bias_step import null_largest, scan_step, uses_minp_positions
from optcal.applications.diagnosis.effects import BIAS_STEP, SESSION_BIAS, UNITS, describe_term
from optcal.applications.diagnosis.familywise import NullDraws, null_draws
from optcal.applications.diagnosis.fitting import MIN_DOF, Fit, Fitter
from optcal.applications.diagnosis.problem import BETA_INDEX, active_mask
from optcal.applications.diagnosis.progress import Loop, plain_loop
from optcal.core.extended_model import format_value
from optcal.core.model import AXES


@dataclass
class DetectionLimit:
    """The detection limit of one candidate term.

    Attributes
    ----------
    term : str
    effect, axis : str
    limit : float
        Smallest first-order coefficient the test would find (units :attr:`units`).
    units : str
    level : float
        Per-candidate test level.
    over_recording_g : float or None
        For ``bias_drift``: the limit as a bias change over the whole recording (g).
    low, high : float or None
        For ``bias_step``: the smallest and largest limit over the positions searched (:attr:`limit` is their
        median; g).
    adjusted : str or None
        For ``bias_step``: how its p value pays for the positions (``"minP"`` or ``"Bonferroni"``).
    """

    term: str
    effect: str
    axis: str
    limit: float
    units: str
    level: float
    over_recording_g: float | None = None
    low: float | None = None
    high: float | None = None
    adjusted: str | None = None

    def text(self) -> str:
        if self.effect == BIAS_STEP:
            return (f"{self.term}: {self.limit * 1e3:.3g} mg after minus before (median over where it could be; "
                    f"{(self.low or 0.0) * 1e3:.2g}-{(self.high or 0.0) * 1e3:.2g} mg; its own level {self.level:.2g}, "
                    f"{self.adjusted} over the positions)")
        words = f"{self.term}: {format_value(self.effect, self.limit).lstrip('+')}"
        if self.over_recording_g is not None:
            words += f" (= {self.over_recording_g * 1e3:.2g} mg over the recording)"
        return words

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class OutlierLimit:
    """The smallest outlier pose the outlier test would name, about half the time.

    Attributes
    ----------
    median_g : float
        Shift of one pose along its own direction (g), median over the poses.
    smallest_g, largest_g : float
        The same for the best- and the worst-placed pose.
    level : float
        The outlier test's family-wise level (Bonferroni over the poses).
    poses : int
        Poses the limit was computed for (every kept pose, or an evenly spaced sample of a large session).
    """

    median_g: float
    smallest_g: float
    largest_g: float
    level: float
    poses: int

    def text(self) -> str:
        return (f"{self.median_g * 1e3:.2g} mg along the pose's own direction (median over the poses; "
                f"{self.smallest_g * 1e3:.2g}-{self.largest_g * 1e3:.2g} mg by where the pose lies)")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


#: Poses an outlier limit is computed for at most (an evenly spaced sample of a larger session).
OUTLIER_LIMIT_POSES: int = 500


def pose_outlier_limits(fitter: Fitter, fit: Fit, level: float, rows: NDArray[np.intp]) -> NDArray[np.float64]:
    """The outlier test's limit (g, along the pose's direction) for each of ``rows`` under ``fit`` (module docstring).

    A pose ``fit`` already sets aside gets the limit its deleted-residual test has: its mean shift's
    variance is its diagonal entry of ``(Hᵀ R⁻¹ H)⁻¹``, and the noise scale is the fit's, which is
    without it.  A kept pose is tested as if set aside, with the fit's noise scale (with it: a clean
    pose changes that scale little).
    """
    H, inverse = fitter.generalised_system(fit)
    shifted = sorted(fit.outliers)
    aside = np.isin(rows, shifted)
    var = np.empty(rows.size)
    first_shift = H.shape[1] - len(shifted)
    var[aside] = [inverse[first_shift + shifted.index(int(k)), first_shift + shifted.index(int(k))] for k in rows[aside]]
    kept_rows = rows[~aside]
    if kept_rows.size:
        E = np.zeros((fitter.n, kept_rows.size))
        E[kept_rows, np.arange(kept_rows.size)] = 1.0
        Z = fitter.correlated_solve(E)  # R⁻¹ eₖ
        z = H.T @ Z
        diagonal = Z[kept_rows, np.arange(kept_rows.size)] - np.einsum("ik,ij,jk->k", z, inverse, z)
        var[~aside] = 1.0 / np.maximum(diagonal, 1e-12)
    dof = fitter.n - fit.n_params
    t = sps.t.isf(level / (2 * fitter.n), np.where(aside, dof, dof - 1))
    return t * np.sqrt(fit.rss / dof * var / fitter.w[rows])


def outlier_limit(fitter: Fitter, fit: Fit, level: float) -> OutlierLimit | None:
    """The outlier test's detection limit under ``fit`` (module docstring); ``None`` without the room to test."""
    if fitter.n - fit.n_params - 1 < MIN_DOF:  # the test's degrees of freedom with the pose set aside (selection)
        return None
    kept = np.flatnonzero(fit.kept(fitter.n))
    rows = kept[np.unique(np.linspace(0, kept.size - 1, min(kept.size, OUTLIER_LIMIT_POSES)).round().astype(int))]
    shift = pose_outlier_limits(fitter, fit, level, rows)
    return OutlierLimit(float(np.median(shift)), float(shift.min()), float(shift.max()), level, int(rows.size))


def detection_limits(fitter: Fitter, fit: Fit, candidates: list[tuple[str, int]], level: float,
                     loop: Loop = plain_loop) -> list[DetectionLimit]:
    """Limits of the ``candidates`` not in ``fit``, each added alone to ``fit`` (module docstring).

    Candidates the data have no room to test (fewer than the fitter's :attr:`~Fitter.min_dof` degrees of
    freedom left) get none.  A small session's scale estimated from its few residual degrees of freedom
    (:meth:`~Fitter.test_scale2`) takes Student's quantile instead of the normal one.
    """
    out = []
    for effect, axis in loop(candidates, "detection limits", len(candidates)):
        if (effect, axis) in fit.terms or fitter.n - fit.n_params - 1 < fitter.min_dof:
            continue
        terms = dict(fit.terms)
        terms[(effect, axis)] = fitter.reg.n_sessions - 1 if effect == SESSION_BIAS else 1  # every session's offset
        bigger = fitter.fit(terms, fit.outliers, fit.x)
        free = np.flatnonzero(active_mask(terms))
        k = 9 + int(np.flatnonzero(free == BETA_INDEX[(effect, axis, 1)])[0])
        # the scale and degrees of freedom of the selection's own test of the candidate (Fitter.test_scale2)
        dof = fitter.test_scale2(fit, bigger)[1]
        variance = fitter.covariance(bigger)[k, k]  # on the same scale (Fitter.noise_scale2)
        se = float(np.sqrt(max(variance, 0.0))) / fitter.reg.half_span(effect)
        z = float(sps.norm.isf(level / 2)) if dof >= MIN_DOF else float(sps.t.isf(level / 2, dof))
        over = 2 * fitter.reg.t_half * z * se if effect == "bias_drift" else None
        out.append(DetectionLimit(describe_term(effect, axis, 1), effect, AXES[axis], z * se, UNITS[effect], level, over))
    return out


#: Null draws behind a bias step's detection limit (minP).  At the step's level (about 0.0017) 17 of 10,000 draws
#: lie above the critical statistic: its tail probability is known to ±25 % (binomial), which moves the critical F
#: of a 15-position search by about ±4 % and the limit by half that, well inside the factor between a limit's
#: positions (0.46-0.58 mg on the Xsens cut's y, 1.4-48 mg on x).  The p values keep bias_step.DRAWS (40,000).
STEP_LIMIT_DRAWS: int = 10_000


def step_limits(fitter: Fitter, fit: Fit, axes: list[int], level: float) -> list[DetectionLimit]:
    """:func:`step_limit` of each of ``axes``, their minP null draws made once (the same for every axis)."""
    null = null_draws(fitter, fit, STEP_LIMIT_DRAWS) if axes and uses_minp_positions(fitter, fit) else None
    out = [step_limit(fitter, fit, axis, level, null) for axis in axes]
    return [lim for lim in out if lim is not None]


def step_limit(fitter: Fitter, fit: Fit, axis: int, level: float, null: NullDraws | None = None) -> DetectionLimit | None:
    """The detection limit of a bias step of ``axis`` added to ``fit`` (after the steps placed): the step size its
    position-adjusted test at ``level`` would name about half the time, at each position searched.

    The step's standard error at one position (the split of median information) is that of the exact fit there
    (:meth:`Fitter.covariance`, the tests' scale); at the other positions it scales as ``1/√information``
    (:attr:`~optcal.applications.diagnosis.bias_step.StepScan.information`, the linearised scan's).  The critical
    statistic is the position-adjusted test's (:func:`~optcal.applications.diagnosis.bias_step.adjusted_p`): the
    ``1 − level`` quantile of the null draws' largest F over the positions (minP), or F(1, n − p)'s at
    ``level / positions`` (Bonferroni); ``null``: the minP draws, made once for several axes.  ``None`` when no
    position can be searched.
    """
    scan = scan_step(fitter, fit, axis)
    dof = fitter.n - fit.n_params - 1
    if scan is None or not scan.splits or dof <= 0:
        return None
    info = np.asarray(scan.information)
    k0 = int(np.argsort(info)[info.size // 2])
    terms = dict(fit.terms)
    previous = fitter.steps_at
    order = len(previous) + 1  # the next step placed (its "order", effects.MAX_STEPS)
    terms[(BIAS_STEP, axis)] = order
    fitter.set_steps((*previous, scan.splits[k0]))
    try:
        bigger = fitter.fit(terms, fit.outliers, fit.x)
        free = np.flatnonzero(active_mask(terms))
        k = 9 + int(np.flatnonzero(free == BETA_INDEX[(BIAS_STEP, axis, order)])[0])
        se0 = float(np.sqrt(max(fitter.covariance(bigger)[k, k], 0.0))) / fitter.reg.half_span(BIAS_STEP)
    finally:
        fitter.set_steps(previous)
    se = se0 * np.sqrt(info[k0] / np.maximum(info, 1e-300))
    largest = null_largest(fitter, fit, scan, null=null) if uses_minp_positions(fitter, fit) else None
    if largest is not None:
        critical, adjusted = float(np.quantile(largest, 1.0 - level)), "minP"
    else:
        critical, adjusted = float(sps.f.isf(level / scan.positions, 1, dof)), "Bonferroni"
    limits = np.sqrt(critical) * se
    return DetectionLimit(describe_term(BIAS_STEP, axis, order), BIAS_STEP, AXES[axis], float(np.median(limits)),
                          UNITS[BIAS_STEP], level, None, float(limits.min()), float(limits.max()), adjusted)
