"""Temperature and current in the magnetometer's diagnosis (:mod:`optcal.applications.magnetic.diagnosis`, 3): the
offsets linear in a column of the recording, fitted with the ellipsoid, against the plain model by the likelihood
ratio and on held-out samples.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from optcal.core.norm_residual import norm_residuals
from optcal.families.mag.fit import SYMMETRIC_ENTRIES
from optcal.families.mag.samples import MagSamples

def _column_fit(m: NDArray[np.float64], x: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``T`` (symmetric), ``o`` and ``k`` of ``|T (m − o − k (x − x̄))| = 1`` by Gauss–Newton from ``T``, ``o``
    (all refitted: a column that changed with the session's turns pulled the plain fit's ``T`` and ``o`` too)."""
    xc = x - x.mean()
    p = np.r_[[T[i, j] for i, j in SYMMETRIC_ENTRIES], o, np.zeros(3)]

    def unpack(q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        S = np.zeros((3, 3))
        for (i, j), v in zip(SYMMETRIC_ENTRIES, q[:6]):
            S[i, j] = S[j, i] = v
        return S, q[6:9], q[9:12]

    for _ in range(30):
        S, oo, k = unpack(p)
        d = m - oo - np.outer(xc, k)
        v = d @ S.T
        n = np.linalg.norm(v, axis=1)
        r = n - 1.0
        e = v / n[:, None]
        cols = [e[:, i] * d[:, j] + (e[:, j] * d[:, i] if i != j else 0.0) for i, j in SYMMETRIC_ENTRIES]
        g = -e @ S
        J = np.column_stack(cols + [g, g * xc[:, None]])
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        p = p + step
        if np.linalg.norm(step) < 1e-12 * (1.0 + np.linalg.norm(p)):
            break
    return unpack(p)


def _column_test(samples: MagSamples, x: NDArray[np.float64], keep: NDArray[np.bool_], T: NDArray[np.float64],
                 o: NDArray[np.float64], n_eff: float, halves: NDArray[np.bool_]
                 ) -> tuple[float, float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
    """The column's offsets ``o + k (x − x̄)`` against the plain model: the likelihood ratio at the effective sample
    size, the held-out ratio (each half's fits predicting the other), and the fit (T, o, k, x̄)."""
    m = samples.m
    ok = keep & np.isfinite(x)
    r0 = norm_residuals(T, o, m[ok])
    T1, o1, k1 = _column_fit(m[ok], x[ok], T, o)
    xm = float(x[ok].mean())
    r1 = np.linalg.norm((m[ok] - o1 - np.outer(x[ok] - xm, k1)) @ T1.T, axis=1) - 1.0
    lr = n_eff * math.log(float(r0 @ r0) / max(float(r1 @ r1), 1e-300))
    err0, err1 = [], []
    for train in (halves, ~halves):
        tr, te = ok & train, ok & ~train
        if tr.sum() < 10 or te.sum() < 10:
            continue
        Tt, ot, kt = _column_fit(m[tr], x[tr], T, o)
        T0, o0, _ = _column_fit(m[tr], np.zeros(int(tr.sum())), T, o)  # the plain model on the same half
        err1.append(np.linalg.norm((m[te] - ot - np.outer(x[te] - x[tr].mean(), kt)) @ Tt.T, axis=1) - 1.0)
        err0.append(norm_residuals(T0, o0, m[te]))
    ratio = float(np.sqrt(np.mean(np.concatenate(err0) ** 2) / np.mean(np.concatenate(err1) ** 2))) if err0 else 1.0
    return lr, ratio, T1, o1, k1, xm
