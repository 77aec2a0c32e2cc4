"""Standard errors of a fit to correlated samples: by batch means, and the lag-1 inflation of the constrained fits.

A magnetometer's samples are not independent (its filter, a slow turn through a misfit, a drift), so the white
standard errors of a least-squares fit understate the uncertainty; :func:`batch_means_stderr` counts the correlation
within batches of consecutive samples (the forms' fits, the planar fits, the dip, the diagnosis).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

def correlation_inflation(residuals: NDArray) -> float:
    """``√((1 + ρ)/(1 − ρ))``, ρ the lag-1 autocorrelation of the residuals in sample order.

    Samples of a turned sensor are not independent (filters, slow turns, a model error that
    changes smoothly with orientation): the variance of a mean of AR(1) samples is that of
    independent ones times ``(1 + ρ)/(1 − ρ)``, so the standard errors are inflated by its root.
    Kept for the fits the user constrains (``--fix``/``--bound``); the forms' own standard errors
    are by batch means (:func:`batch_means_stderr`).
    """
    r = residuals - residuals.mean()
    den = float(r @ r)
    rho = float(r[1:] @ r[:-1]) / den if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.999)  # 0.999: at most a 45-fold inflation (an effective sample every 2000)
    return float(np.sqrt((1 + rho) / (1 - rho)))


#: The shortest batch of :func:`batch_means_stderr`, samples (a magnetometer's filter and a hand's
#: slow turn correlate at least this many samples of a 10-100 Hz sensor).
BATCH_START: int = 25
#: Fewest batches of :func:`batch_means_stderr`: a variance from k batch scores is itself
#: uncertain by about √(2/(k − 1)), a standard error by half that, 24 % at 10.
MIN_BATCHES: int = 10


def batch_means_stderr(J: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard errors of least-squares parameters with Jacobian ``J`` (n, p) and residuals ``r`` (n,)
    in sample order, by batch means: the sandwich ``(JᵀJ)⁻¹ (Σ_b g_b g_bᵀ) (JᵀJ)⁻¹`` with the
    score ``g_b = J_bᵀ r_b`` of each batch of consecutive samples (correlation within a batch
    counted, none assumed between batches), for batch lengths :data:`BATCH_START` · 2^j with at
    least :data:`MIN_BATCHES` batches, each parameter's largest (a standard error grows with the
    batches' length until they are longer than the residuals' correlation: a filter, a slow turn
    through a misfit, a drift; the largest is the conservative choice), and never below the white
    one ``√(diag (JᵀJ)⁻¹ · rᵀr/(n − p))``.
    """
    n, k = J.shape
    # columns scaled to unit norm first: in counts T's entries are ~1e-4 and o's ~1e3, so JᵀJ's condition number
    # (~1e15) put o's directions below pinv's cut-off and their standard errors at ~1e-14 (ybabs's counts)
    col = np.sqrt(np.einsum("ij,ij->j", J, J))
    col = np.where(col > 0, col, 1.0)
    J = J / col
    H = np.linalg.pinv(J.T @ J)
    se2 = np.diag(H) * float(r @ r) / max(n - k, 1)
    b = n // BATCH_START
    g = np.einsum("bli,bl->bi", J[: b * BATCH_START].reshape(b, BATCH_START, k), r[: b * BATCH_START].reshape(b, BATCH_START))
    while g.shape[0] >= MIN_BATCHES:
        se2 = np.maximum(se2, np.einsum("ij,jk,ki->i", H, g.T @ g, H))
        half = g.shape[0] // 2
        g = g[0 : 2 * half : 2] + g[1 : 2 * half : 2]  # the scores of batches twice as long (n // 2L of them)
    return np.asarray(np.sqrt(np.clip(se2, 0.0, None)) / col)
