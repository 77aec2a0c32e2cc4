"""Outlier poses as mean-shift terms: a robust fit marks suspects, a deleted-residual test keeps them.

A Cauchy-loss fit of the current model (in CasADi) marks suspects (standardised residual >
:data:`SUSPECT_Z`); each suspect is kept only if its deleted residual, tested against the fit
without the suspects (t distribution, Bonferroni over the n poses), is significant.  A kept
outlier gets a free offset, i.e. zero weight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from optcal.diagnosis.fitting import Fit, Fitter
from optcal.diagnosis.problem import ExtendedProblem, active_mask

#: Standardised residual (Cauchy fit) above which a pose is a suspected outlier.
SUSPECT_Z: float = 3.0
#: Scale of the Cauchy loss, in standard deviations (95 % efficiency at the Gaussian).
CAUCHY_SCALE: float = 2.385


@dataclass
class OutlierTest:
    """New outlier poses found under a fit, the smallest (Bonferroni) p value, and the refit."""

    poses: frozenset[int]
    p_value: float
    fit: Fit


def robust_scale(e: np.ndarray) -> float:
    """Normalised median absolute value (σ of a Gaussian)."""
    return max(1.4826 * float(np.median(np.abs(e))), 1e-12)


def detect_outliers(fitter: Fitter, fit: Fit, alpha: float) -> OutlierTest | None:
    """New outlier poses under ``fit`` at family-wise level ``alpha`` (module docstring)."""
    n = fitter.n
    kept = fit.kept(n)
    scale = robust_scale((np.sqrt(fitter.w) * fit.residuals)[kept])
    cauchy = ExtendedProblem.get(n, "cauchy")
    mask = active_mask(fit.terms)
    w = fitter.weights(fit)
    x = fit.x
    e = np.zeros(n)
    for _ in range(2):
        p = fitter.data.parameters(w / scale**2, CAUCHY_SCALE)
        x, _ = cauchy.solve(x, p, mask)
        e = np.sqrt(fitter.w) * cauchy.residual_values(x, p)
        scale = robust_scale(e[kept])
    suspects = frozenset(int(k) for k in np.flatnonzero(kept & (np.abs(e) / scale > SUSPECT_Z)))
    if not suspects:
        return None
    inner = fitter.fit(fit.terms, fit.outliers | suspects, x)
    dof = n - inner.n_params
    if dof <= 0:
        return None
    s2 = inner.rss / dof
    G, _ = fitter.jacobians(inner, fitter.weights(inner))
    M = np.linalg.pinv(G.T @ G, rcond=1e-13, hermitian=True)
    J = fitter.problem.jacobian_values(inner.x, fitter.params(fitter.weights(inner)))
    free = np.concatenate([np.ones(9, dtype=bool), mask])
    flagged: dict[int, float] = {}
    for k in suspects:
        jk = J[k, free]
        v = s2 * (1.0 / fitter.w[k] + float(jk @ M @ jk))
        tk = inner.residuals[k] / np.sqrt(v)
        pk = min(1.0, n * 2 * float(sps.t.sf(abs(tk), dof)))
        if pk < alpha:
            flagged[k] = pk
    if not flagged:
        return None
    refit = fitter.fit(fit.terms, fit.outliers | frozenset(flagged), inner.x)
    return OutlierTest(frozenset(flagged), min(flagged.values()), refit)
