"""The time offset between the gyro's and the accelerometer's streams, shown inside the moves: each move's
least-squares shift with a constant and a lever arm's acceleration fitted beside it, combined and tested by
Student's t, and held out by move (step 3 of :mod:`~optcal.applications.diagnosis.gyro_diagnosis`, whose module
docstring derives it)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.gyro_heldout import MIN_DIAGNOSIS_MOVES, paired_gain
from optcal.applications.diagnosis.gyro_problem import GYRO_EFFECTS, GyroData, GyroParams, corrected_rates
from optcal.core import quantiles
from optcal.core.model import STANDARD_GRAVITY
from optcal.core.rotations import exponential_map, skew
from optcal.core.stats import mean_and_se
from optcal.families.gyro.propagation import unit_rows

#: What the time offset's estimate is: the shift between the two streams as the file holds them, whatever put it
#: there (a driver's or a logger's own offset, a filter's group delay, a shift written into the file); a shift added
#: to a file adds to the one it had (the Xsens log's gyro is 2.3 ms early: 3.5 ms made late reads +1.4 ms).
TIME_OFFSET_MEASURES: str = ("the gyro's samples against the accelerometer's as the file holds them (positive: the "
                             "gyro's late), the recording's own offset included: a shift added to the file adds to it")

#: The angular acceleration of the lever arm's term ``α × r`` is the derivative of the rates averaged over this
#: span (s; its running mean passes a hand's turn, whose power is below a few Hz, and its first zero is at 10 Hz):
#: the rates' white noise differentiated sample by sample grows with the sampling rate, and a noisy regressor fits
#: less than the lever arm's acceleration, leaving the rest in δ (a 0.3 m lever arm written into imu0's file moved
#: its offset 15.2 -> 12.1 ms with the raw derivative; imu0 and the Xsens log keep theirs named).
LEVER_SMOOTHING_S: float = 0.1

#: Standard errors by which the time offset's paired gain on the held-out moves must exceed zero: the held-out
#: moves' own noise gives a gain within one standard error.  The offset's significance is its own t on the moves
#: (the family-wise level); this asks that its correction generalise beyond noise.  Under white misfit the held-out
#: t is about half the estimate's (a held-out move gains δ²|u̇|² against noise 2δ n·u̇; measured 0.39-0.50 on the
#: Xsens log, imu0 and mgiurato's log), so a real offset that passes its t passes this; a lever arm's unfollowed
#: motion, which scatters the moves, does not (0.3 m planted in imu0: t 3.8 past 3.25, held-out 0.77 SE).
OFFSET_HELDOUT_SE: float = 1.0


def _smoothed(omega: NDArray[np.float64], dt: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rates' running mean over :data:`LEVER_SMOOTHING_S` (centred; shorter at the move's ends)."""
    k = int(round(LEVER_SMOOTHING_S / float(np.median(dt))))
    if k < 2:
        return omega
    kernel = np.ones(k) / k
    ones = np.convolve(np.ones(omega.shape[0]), kernel, mode="same")
    return np.column_stack([np.convolve(omega[:, j], kernel, mode="same") / ones for j in range(3)])


def time_offset_test(data: GyroData, p: GyroParams, alpha: float, folds: list[NDArray[np.bool_]],
                     heldout_se: float = OFFSET_HELDOUT_SE) -> dict[str, Any]:
    """The time offset between the gyro's and the accelerometer's samples (module docstring, 3): named when its t
    passes the family-wise level ``alpha`` and its paired gain on the held-out moves exceeds ``heldout_se`` of its
    standard errors."""
    omega, _ = corrected_rates(data, p, data.raw, data.f_mid, data.t_mid, data.temp_mid, False)
    E = exponential_map(omega * data.dt[:, None])
    starts = data.starts
    ends = np.r_[starts[1:], omega.shape[0]]
    per_move: list[float] = []
    weights: list[float] = []
    pieces: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
    for i, (a, z) in enumerate(zip(starts, ends)):
        R = np.eye(3)
        after = np.empty((z - a, 3))
        for k in range(a, z):  # û after each step: (P_k)ᵀ u₀
            R = R @ E[k]
            after[k - a] = R.T @ data.u0[i]
        # at each step's middle, where its specific force is: half a step earlier than after it (the midpoint's
        # direction; compared after the step, a half step would read as a time offset)
        u = unit_rows(0.5 * (np.vstack([data.u0[i][None, :], after[:-1]]) + after))
        udot = -np.cross(omega[a:z], u)
        e = (unit_rows(data.f_mid[a:z]) - u).ravel()
        # what is not a shift in time, fitted on the move and projected out of both: a constant misfit (the
        # end-to-end residual's share), and the accelerometer's linear acceleration of a turn about a centre off
        # the sensor (the hand's wrist or elbow, r from it to the sensor, per move): a = α × r + ω × (ω × r),
        # its share across gravity P_u a / g (a rigid body's point acceleration; the moves' largest linear
        # acceleration, which scattered the moves' δ)
        alpha_dot = (np.gradient(_smoothed(omega[a:z], data.dt[a:z]), np.cumsum(data.dt[a:z]), axis=0)
                     if z - a > 2 else np.zeros((z - a, 3)))
        across = np.eye(3)[None] - u[:, :, None] * u[:, None, :]
        lever = across @ (skew(alpha_dot) + skew(omega[a:z]) @ skew(omega[a:z])) / STANDARD_GRAVITY
        nuisance = np.column_stack([np.tile(np.eye(3), (z - a, 1)), lever.reshape(-1, 3)])
        e = e - nuisance @ np.linalg.lstsq(nuisance, e, rcond=None)[0]
        q = udot.ravel()
        q = q - nuisance @ np.linalg.lstsq(nuisance, q, rcond=None)[0]
        wi = float(q @ q)
        per_move.append(float(e @ q) / wi if wi > 0 else 0.0)
        weights.append(wi)
        pieces.append((e, q))
    d = np.asarray(per_move)
    w = np.asarray(weights)
    m = d.size
    if m < MIN_DIAGNOSIS_MOVES or w.sum() <= 0:
        return {"tested": False, "reason": f"{m} moves (fewer than {MIN_DIAGNOSIS_MOVES})"}
    delta, se = mean_and_se(d, w)
    t = delta / se if se > 0 else 0.0
    critical = quantiles.t_isf(0.5 * alpha / len(GYRO_EFFECTS), m - 1)
    # held out: δ from the other folds' moves, the inside-move residual of each held-out move with and without it
    before: list[float] = []
    after_shift: list[float] = []
    gains: list[float] = []
    for test in folds:
        train = ~test
        dtrain = mean_and_se(d[train], w[train])[0] if w[train].sum() > 0 else 0.0
        for j in np.flatnonzero(test).tolist():
            e, udot_c = pieces[j]
            before.append(float(np.sum(e * e)))
            after_shift.append(float(np.sum((e - dtrain * udot_c) ** 2)))
            # the move's rms misfit across gravity (e holds three components per step), degrees: paired on the
            # rms, not the squares, as the terms' held-out moves are on their angles (a move's squared misfit is
            # ruled by its fastest turns, so a few moves would decide)
            steps = max(e.size // 3, 1)
            gains.append(math.degrees(math.sqrt(before[-1] / steps) - math.sqrt(after_shift[-1] / steps)))
    ratio = float(np.sqrt(np.sum(before) / np.sum(after_shift))) if np.sum(after_shift) > 0 else 1.0
    gain, gain_se, gain_t = paired_gain(np.asarray(gains))
    # named when the estimate passes its family-wise t and the held-out moves gain beyond their own noise
    # (OFFSET_HELDOUT_SE; the ratio of the summed misfits above 1 alone passed on a 0.1 % change: mgiurato's log
    # 1.0012, imu_tk's data3 1.0008, and on a lever arm's scatter)
    return {"tested": True, "dt_s": delta, "se_s": se, "t": t, "critical_t": critical, "moves": m,
            "heldout_ratio": ratio, "heldout_gain_deg": gain, "heldout_se_deg": gain_se, "heldout_moves_t": gain_t,
            "heldout_moves_critical_t": heldout_se,
            "significant": bool(abs(t) > critical and gain_t > heldout_se),
            "measures": TIME_OFFSET_MEASURES, "per_move_dt_s": d.tolist()}
