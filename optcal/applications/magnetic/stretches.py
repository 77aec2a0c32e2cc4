"""The search for a local disturbance in the magnetometer's diagnosis (:mod:`optcal.applications.magnetic.diagnosis`,
2): the epidemic change point on the blocks' means, the field the stretch adds, and how far leaving it out moves the
calibration in what a user reads (the heading, the field strength) against their standard errors.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.magnetic.band import BLOCK
from optcal.core.model import AXES
from optcal.families.mag.fit import SYMMETRIC_ENTRIES, norm_residual_jacobian

#: Fewest blocks in a stretch (shorter: a twitch of a hand, not a field).
MIN_STRETCH_BLOCKS: int = 2


def _stretch(b: NDArray[np.float64], sigma_b: float) -> tuple[int, int, float]:
    """The blocks ``[a, z)`` whose mean differs most from the rest's (epidemic change point) and its χ²₁ statistic
    ``n_in n_out / N · (b̄_in − b̄_out)² / σ²_block``; blocks whose mean ``b`` is NaN (the dip channel's blocks with
    too few still samples) count on neither side."""
    B = b.size
    usable = np.isfinite(b)
    cv = np.r_[0, np.cumsum(usable)]
    c = np.r_[0.0, np.cumsum(np.where(usable, b, 0.0))]
    V = int(cv[-1])
    best = (0, 0, 0.0)
    total = c[-1]
    for a in range(B):
        z = np.arange(a + MIN_STRETCH_BLOCKS, B + 1)
        if not z.size or not V:
            break
        ok = (B - (z - a)) >= MIN_STRETCH_BLOCKS  # the stretch leaves blocks outside it
        n_in = cv[z] - cv[a]
        n_out = V - n_in
        ok &= (n_in >= MIN_STRETCH_BLOCKS) & (n_out >= MIN_STRETCH_BLOCKS)
        if not ok.any():
            continue
        s_in = c[z] - c[a]
        mean_in = s_in / np.maximum(n_in, 1)
        mean_out = (total - s_in) / np.maximum(n_out, 1)
        stat = np.where(ok, n_in * n_out / V * (mean_in - mean_out) ** 2 / sigma_b**2, 0.0)
        k = int(np.argmax(stat))
        if stat[k] > best[2]:
            best = (a, int(z[k]), float(stat[k]))
    return best


def _stretch_statistic(b: NDArray[np.float64], sigma_b: float, a: int, z: int) -> tuple[float, float]:
    """:func:`_stretch`'s statistic of the blocks ``[a, z)`` and the difference of the means in and out (NaN: the
    stretch or the rest has no usable block)."""
    usable = np.isfinite(b)
    inside = np.zeros(b.size, dtype=bool)
    inside[a:z] = True
    n_in, n_out = int(np.count_nonzero(usable & inside)), int(np.count_nonzero(usable & ~inside))
    if not n_in or not n_out:
        return 0.0, float("nan")
    diff = float(np.mean(b[usable & inside]) - np.mean(b[usable & ~inside]))
    return n_in * n_out / (n_in + n_out) * diff**2 / sigma_b**2, diff


def _offset_in(m: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The field ``δ`` (data units) added to samples ``m`` of a fitted ``T``, ``o``: least squares of
    ``|T(m − o − δ)| − 1`` by Gauss–Newton; with its standard errors."""
    delta = np.zeros(3)
    for _ in range(20):
        v = (m - o - delta) @ T.T
        n = np.linalg.norm(v, axis=1)
        r = n - 1.0
        J = -(v / n[:, None]) @ T
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        delta = delta + step
        if np.linalg.norm(step) < 1e-12 * (1.0 + np.linalg.norm(delta)):
            break
    v = (m - o - delta) @ T.T
    n = np.linalg.norm(v, axis=1)
    J = -(v / n[:, None]) @ T
    r = n - 1.0
    dof = max(m.shape[0] - 3, 1)
    cov = np.linalg.pinv(J.T @ J) * float(r @ r) / dof
    return delta, np.sqrt(np.clip(np.diag(cov), 0.0, None))


def calibration_covariance(m: NDArray[np.float64], fit: Any, white: float, colour: float) -> NDArray[np.float64]:
    """The covariance of the symmetric ``T``'s six entries and ``o`` (:func:`norm_residual_jacobian`'s order) from
    the coloured noise: a block mean's variance is ``colour · σ²_white / BLOCK``, so ``n`` samples carry the
    information of ``n / colour`` white ones (``σ²_white (JᵀJ)⁻¹ · colour``, in the fitted form's parameters),
    scaled up to meet the fit's batch-means standard errors of ``o`` where larger (batches up to a tenth of the
    session see a correlation longer than a block)."""
    J = norm_residual_jacobian(m, fit.T, fit.o)
    P = np.eye(9)
    if fit.form == "diagonal":
        P = P[:, [0, 3, 5, 6, 7, 8]]
    elif fit.form == "offsets":
        P = np.column_stack([P[:, 0] + P[:, 3] + P[:, 5], P[:, 6:]])
    C = P @ np.linalg.pinv((J @ P).T @ (J @ P)) @ P.T * white**2 * max(colour, 1.0)
    se_bm = np.array([fit.stderr.get(f"o_{a}", 0.0) for a in AXES])
    ratio = np.max(se_bm / np.sqrt(np.maximum(np.diag(C)[6:], 1e-300)))
    return np.asarray(C * max(float(ratio), 1.0) ** 2)


def calibration_change(T: NDArray[np.float64], o: NDArray[np.float64], T1: NDArray[np.float64],
                       o1: NDArray[np.float64], C: NDArray[np.float64]) -> dict[str, float]:
    """How far the calibration ``T1``, ``o1`` is from ``T``, ``o`` in what a user reads, each over its standard
    error from ``C`` (:func:`calibration_covariance`).

    * **The heading**: an offset error ``Δo`` turns the calibrated field by ``|T Δo|`` radians at most (its part
      across the unit field; the horizontal heading's error is that over cos(dip), as is its standard error, so the
      ratio holds at any dip); the standard error ``√tr(T C_o Tᵀ)``.
    * **The field strength** ``F = det(T)^(−1/3)``: ``∂F/∂T_ij = −F/3 · (T⁻¹)_ij`` (twice off the diagonal, both
      entries of the symmetric ``T``), its standard error ``√(gᵀ C g)``.
    """
    F, F1 = float(np.linalg.det(T) ** (-1.0 / 3.0)), float(np.linalg.det(T1) ** (-1.0 / 3.0))
    Ti = np.linalg.inv(T)
    g = np.zeros(9)
    g[:6] = [-F / 3.0 * Ti[i, j] * (1.0 if i == j else 2.0) for i, j in SYMMETRIC_ENTRIES]
    se_heading = math.degrees(math.sqrt(max(float(np.trace(T @ C[6:, 6:] @ T.T)), 0.0)))
    heading = math.degrees(float(np.linalg.norm(T @ (o1 - o))))
    se_field = math.sqrt(max(float(g @ C @ g), 0.0))
    return {"heading_deg": heading, "heading_se_deg": se_heading, "moved_heading_se": heading / max(se_heading, 1e-300),
            "field": F1 - F, "field_se": se_field, "moved_field_se": abs(F1 - F) / max(se_field, 1e-300)}
