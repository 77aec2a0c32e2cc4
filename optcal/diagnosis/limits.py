"""Detection limits: the smallest effect of each candidate term the selection would have named.

For a candidate added alone to a fitted model, the limit is ``z × SE``: ``SE`` the standard
error of its first-order coefficient (Fisher information, noise scale from the residuals) and
``z`` the two-sided normal quantile of the per-candidate level the selection tests it at.  An
effect this large passes the test about half the time; twice as large, almost always.  When the
pose noise is correlated in time (:mod:`optcal.diagnosis.correlation`) the standard error is the
generalised least-squares one, ``(Gᵀ R⁻¹ G)⁻¹``, the one the selection's test has: a limit computed
as if the poses were independent would overstate the power for terms smooth in time.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy import stats as sps

from optcal.diagnosis.effects import SESSION_BIAS, UNITS, describe_term
from optcal.diagnosis.fitting import MIN_DOF, Fit, Fitter
from optcal.diagnosis.problem import BETA_INDEX, active_mask
from optcal.diagnosis.progress import Loop, plain_loop
from optcal.extended_model import format_value
from optcal.model import AXES


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


def detection_limits(fitter: Fitter, fit: Fit, candidates: list[tuple[str, int]], level: float,
                     loop: Loop = plain_loop) -> list[DetectionLimit]:
    """Limits of the ``candidates`` not in ``fit``, each added alone to ``fit`` (module docstring).

    Candidates the data have no room to test (fewer than ``MIN_DOF`` degrees of freedom left) get none.
    """
    z = float(sps.norm.isf(level / 2))
    out = []
    for effect, axis in loop(candidates, "detection limits", len(candidates)):
        if (effect, axis) in fit.terms or fitter.n - fit.n_params - 1 < MIN_DOF:
            continue
        terms = dict(fit.terms)
        terms[(effect, axis)] = fitter.reg.n_sessions - 1 if effect == SESSION_BIAS else 1  # every session's offset
        bigger = fitter.fit(terms, fit.outliers, fit.x)
        free = np.flatnonzero(active_mask(terms))
        k = 9 + int(np.flatnonzero(free == BETA_INDEX[(effect, axis, 1)])[0])
        se = float(np.sqrt(max(fitter.covariance(bigger)[k, k], 0.0))) / fitter.reg.half_span(effect)
        over = 2 * fitter.reg.t_half * z * se if effect == "bias_drift" else None
        out.append(DetectionLimit(describe_term(effect, axis, 1), effect, AXES[axis], z * se, UNITS[effect], level, over))
    return out
