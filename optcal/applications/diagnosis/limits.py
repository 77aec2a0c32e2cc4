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

from optcal.applications.diagnosis.effects import SESSION_BIAS, UNITS, describe_term
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
    """

    term: str
    effect: str
    axis: str
    limit: float
    units: str
    level: float
    over_recording_g: float | None = None

    def text(self) -> str:
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
