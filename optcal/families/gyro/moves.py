"""The moves of a static-pose recording: the samples between consecutive still intervals.

Tedaldi 2014 (section IV-B) calibrates the gyro by integrating it across each move, from
the end of one static interval to the start of the next.  A :class:`MoveSet` holds what
that needs, flattened for a vectorised integrator: every integration step ``k`` uses the
raw gyro samples at both ends (trapezoid: their mean over ``dt_k``), the raw specific
force at the mid-point (for the g-sensitivity), and a flag marking the first step of each
move; the per-interval raw accelerometer and gyro means give the gravity directions and
the bias; the rests' noise (:func:`rest_noise`) says how much angle the gyro's noise alone
makes over a move.

Holes
-----
A step between two usable samples longer than :data:`HOLE_STEP_FACTOR` sample periods has
lost samples: one excluded by the data layer (a repeated timestamp, a duplicated row, a
non-finite or saturated sample) or never recorded.  The step is integrated like any other,
from the usable sample before the hole to the one after it, over the time between their
stamps (the true step, not a multiple of the period).  Its trapezoid error is
``h³ ω̈ / 12`` for a rate with curvature ``ω̈`` (Davis & Rabinowitz, the trapezoid rule's
remainder), so the bound of a hole of length ``h`` is ``e = h³ |ω̈|max / 12`` with
``|ω̈|max`` the largest second divided difference of the rate over the usable samples
beside the hole (as many on each side as the hole is periods long, at least
:data:`CURVATURE_SAMPLES`).  A move is bridged when the bounds of its holes add up to at most
the angle the gyro's white noise already integrates over that move,
``N √T`` (angle random walk ``N`` from the rests, ``T`` the move's duration): the hole then
adds at most as much as the noise the fit already carries, and the bound enters the noise
model of :mod:`optcal.families.gyro.consistency`.  Otherwise the move is dropped and counted
by reason in :attr:`MoveSet.exclusions`.  The rate's curvature measured beside a hole
includes the noise's own (a white rate noise ``σ`` gives second differences of ``√6 σ/Δt²``),
which caps the holes bridged on a still-ish stretch to about
``(12 N √T Δt² / (√6 σ))^{1/3}``: four periods for a white-noise gyro sampled at 100 Hz
over a 2-s move; during a fast turn a hole of one lost sample is already too long when the
rate bends sharply there.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError

if TYPE_CHECKING:
    from optcal.data.static import Segmentation

#: A step longer than this many sample periods has lost at least one sample (a step of
#: two periods is one lost sample; half a period of slack leaves the clock's jitter alone).
HOLE_STEP_FACTOR: float = 1.5
#: Fewest usable samples on each side of a hole whose second differences measure the rate's
#: curvature there (two give the triples that end at the hole's ends).
CURVATURE_SAMPLES: int = 2
#: Length of the windows whose means the rests' Allan variance compares, seconds: five times the
#: group delay of the slowest output filter MEMS gyros offer (InvenSense's 5 Hz DLPF, 19 ms), so
#: that the filter's correlation between samples is gone and the variance is the white noise's
#: ``N²/τ`` (per-sample variance underestimates a filtered gyro's angle random walk).
ARW_WINDOW_S: float = 0.1
#: Fewest moves accepted (Tedaldi 2014 use about 30; nine parameters need far fewer).
MIN_MOVES: int = 6

#: Reasons a move is dropped (keys of :attr:`MoveSet.exclusions`).
HOLE_MOVES = ("moves dropped: a hole (lost or unusable samples) whose integration error bound exceeds "
              "the angle random walk of the move")
NO_SAMPLES_MOVES = "moves dropped: static intervals that touch or overlap, or without a usable sample"
TIME_MOVES = "moves dropped: time not increasing across the move"
RAIL_MOVES = "moves with the gyro at its rail (--keep-gyro-rail keeps them)"


@dataclass(frozen=True)
class RestNoise:
    """The gyro's noise measured on the rests (raw units).

    Attributes
    ----------
    arw2 : ndarray, shape (3,)
        Angle random walk density ``N²`` per axis, raw² · s (the variance of the angle the
        white noise integrates in one second): ``τ`` times the Allan variance at
        ``τ =`` :data:`ARW_WINDOW_S`, pooled over the rests, at least the quantisation's
        ``q²/12 · Δt``.
    sample_std : ndarray, shape (3,)
        Per-sample standard deviation, pooled over the rests.
    quantum : ndarray, shape (3,)
        The smallest step between distinct readings of each axis (0 when none).
    stamp_jitter_s : float
        Standard deviation of the time stamps about a regular clock, from the spread of the
        steps that are not holes (robust: 1.4826 × their median absolute deviation, over √2
        because a step is the difference of two stamps).
    period_s : float
        Sample period (median step between usable samples).
    """

    arw2: NDArray[np.float64]
    sample_std: NDArray[np.float64]
    quantum: NDArray[np.float64]
    stamp_jitter_s: float
    period_s: float


@dataclass
class MoveSet:
    """Static intervals and the moves between them, ready for integration.

    Attributes
    ----------
    acc_means : ndarray, shape (p, 3)
        Raw accelerometer mean of each static interval.
    acc_sigma : ndarray, shape (p,)
        Standard deviation of each mean (per axis), raw units.
    gyro_means : ndarray, shape (p, 3)
        Raw gyro mean of each static interval.
    n_static : ndarray, shape (p,)
        Samples in each interval.
    gyro_static_std : ndarray, shape (p, 3)
        Per-axis standard deviation of the gyro samples in each interval.
    move_from, move_to : ndarray of int, shape (m,)
        Interval index before and after each move.
    gyro_pairs : ndarray, shape (N, 2, 3)
        Raw gyro at both ends of every integration step.
    acc_mid : ndarray, shape (N, 3)
        Raw specific force at the middle of every step.
    dt : ndarray, shape (N,)
        Step lengths, seconds.
    first_step : ndarray of bool, shape (N,)
        True on the first step of each move.
    last_step : ndarray of int, shape (m,)
        Index of the last step of each move.
    exclusions : dict of str to int
        Moves dropped, by reason.
    noise : RestNoise or None
        The gyro's noise on the rests.
    bridge_bound : ndarray, shape (m,)
        Sum of the integration-error bounds of the holes bridged in each move, raw · s (0 without hole).
    bridged_holes, bridged_samples : int
        Holes bridged inside the moves kept, and the sample periods they lost.
    t_mid : ndarray, shape (N,)
        Time at the middle of every step, seconds (empty when not given).
    rest_t : ndarray, shape (p,)
        Mean time of each static interval, seconds (empty when not given).
    temp_mid, rest_temp : ndarray or None
        Temperature at the middle of every step and each interval's mean (None without a temperature column).
    """

    acc_means: NDArray[np.float64]
    acc_sigma: NDArray[np.float64]
    gyro_means: NDArray[np.float64]
    n_static: NDArray[np.float64]
    gyro_static_std: NDArray[np.float64]
    move_from: NDArray[np.int64]
    move_to: NDArray[np.int64]
    gyro_pairs: NDArray[np.float64]
    acc_mid: NDArray[np.float64]
    dt: NDArray[np.float64]
    first_step: NDArray[np.bool_]
    last_step: NDArray[np.int64]
    exclusions: dict[str, int] = field(default_factory=dict)
    noise: RestNoise | None = None
    bridge_bound: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    bridged_holes: int = 0
    bridged_samples: int = 0
    t_mid: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    rest_t: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    temp_mid: NDArray[np.float64] | None = None
    rest_temp: NDArray[np.float64] | None = None

    @property
    def n_moves(self) -> int:
        return int(self.move_from.size)

    @property
    def n_steps(self) -> int:
        return int(self.dt.size)

    def gyro_mid(self) -> NDArray[np.float64]:
        """Raw gyro averaged over each step (trapezoid rule), shape (N, 3)."""
        return self.gyro_pairs.mean(axis=1)

    def step_bounds(self) -> NDArray[np.int64]:
        """Index of each move's first step, then one past the last step, shape (m + 1,)."""
        return np.concatenate([[0], self.last_step + 1]).astype(np.int64)

    def durations(self) -> NDArray[np.float64]:
        """Length of each move in seconds, shape (m,)."""
        ends = self.step_bounds()
        return np.add.reduceat(self.dt, ends[:-1]) if self.n_moves else np.zeros(0)

    def bridging_note(self) -> str | None:
        """One line on the holes bridged inside the moves (``None`` without any)."""
        if not self.bridged_holes:
            return None
        return (f"{self.bridged_holes} hole(s) inside the moves bridged over the true time step "
                f"({self.bridged_samples} sample period(s) lost or unusable); their integration-error bound is part "
                "of the noise model")


def rest_noise(t: NDArray, gyro: NDArray, ok: NDArray, intervals: list[tuple[int, int]]) -> RestNoise:
    """The gyro's noise on the rests: angle random walk, per-sample spread, quantum and stamp jitter."""
    steps = np.diff(t[ok])
    period = float(np.median(steps)) if steps.size else 1.0
    regular = steps[steps <= HOLE_STEP_FACTOR * period]
    jitter = float(1.4826 * np.median(np.abs(regular - np.median(regular))) / np.sqrt(2)) if regular.size else 0.0
    width = max(1, int(round(ARW_WINDOW_S / period)))
    differences, centred = [], []
    for a, b in intervals:
        g = gyro[a:b][ok[a:b]]
        if g.shape[0] > 1:
            centred.append(g - g.mean(axis=0))
        k = g.shape[0] // width
        if k >= 2:
            means = g[: k * width].reshape(k, width, 3).mean(axis=1)
            differences.append(np.diff(means, axis=0))
    sample_std = np.sqrt(np.mean(np.concatenate(centred) ** 2, axis=0)) if centred else np.zeros(3)
    if differences:
        arw2 = 0.5 * np.mean(np.concatenate(differences) ** 2, axis=0) * width * period
    else:  # rests shorter than two windows: the per-sample variance, as if white
        arw2 = sample_std**2 * period
    quantum = np.zeros(3)
    for axis in range(3):
        steps_axis = np.diff(np.unique(gyro[ok, axis]))
        quantum[axis] = float(steps_axis.min()) if steps_axis.size else 0.0
    arw2 = np.maximum(arw2, quantum**2 / 12.0 * period)
    return RestNoise(arw2, sample_std, quantum, jitter, period)


def hole_bound(t: NDArray, gyro: NDArray, usable_idx: NDArray, position: int, period: float) -> float:
    """Bound of the trapezoid's error over the hole after ``usable_idx[position]``, raw · s.

    ``h³ |ω̈|max / 12``: ``h`` the time across the hole, ``|ω̈|max`` the largest norm of the
    second divided differences of the rate over the usable samples beside it (as many on each
    side as the hole is sample periods long, at least :data:`CURVATURE_SAMPLES`).
    """
    h = float(t[usable_idx[position + 1]] - t[usable_idx[position]])
    side = max(CURVATURE_SAMPLES, int(np.ceil(h / period)) if period > 0 else CURVATURE_SAMPLES)
    near = usable_idx[max(0, position - side): position + 2 + side]
    if near.size < 3:
        return float("inf")
    tn, gn = t[near], gyro[near]
    slope = np.diff(gn, axis=0) / np.diff(tn)[:, None]
    curvature = 2.0 * np.diff(slope, axis=0) / (tn[2:] - tn[:-2])[:, None]
    return h**3 / 12.0 * float(np.max(np.linalg.norm(curvature, axis=1)))


def moves_from_arrays(
    t: ArrayLike,
    acc: ArrayLike,
    gyro: ArrayLike,
    intervals: list[tuple[int, int]],
    usable: ArrayLike | None = None,
    acc_sigma: ArrayLike | None = None,
    temp: ArrayLike | None = None,
    rail: ArrayLike | None = None,
) -> MoveSet:
    """Build a :class:`MoveSet` from samples and static intervals.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times, seconds.
    acc, gyro : array_like, shape (n, 3)
        Raw accelerometer and gyro samples.
    intervals : list of (start, stop)
        Static intervals as sample ranges (``stop`` exclusive), in time order.
    usable : array_like of bool, shape (n,), optional
        Samples that may be integrated (all finite ones when omitted); the others are holes,
        bridged when short enough (module docstring).
    acc_sigma : array_like, shape (p,), optional
        Standard deviation of each interval's accelerometer mean (default: white noise,
        ``std/√n``).
    temp : array_like, shape (n,), optional
        Temperature of each sample (kept at the steps and the intervals, for the diagnosis).
    rail : array_like of bool, shape (n,), optional
        Samples with the gyro at a saturation rail (:func:`optcal.data.rails.gyro_rail`): a move holding one
        integrates less than its turn by the rate beyond the rail, whatever the calibration, and is left out
        (counted as :data:`RAIL_MOVES`).

    Raises
    ------
    InputError
        Fewer than :data:`MIN_MOVES` usable moves.
    """
    t = np.asarray(t, dtype=float)
    acc = np.asarray(acc, dtype=float).reshape(-1, 3)
    gyro = np.asarray(gyro, dtype=float).reshape(-1, 3)
    if not (t.size == acc.shape[0] == gyro.shape[0]):
        raise InputError(f"t, acc and gyro must have the same number of samples ({t.size}, {acc.shape[0]}, {gyro.shape[0]})")
    ok = np.ones(t.size, bool) if usable is None else np.asarray(usable, bool).copy()
    ok &= np.isfinite(t) & np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(gyro), axis=1)
    at_rail = None if rail is None else np.asarray(rail, bool).reshape(t.size)
    ivs = sorted((int(a), int(b)) for a, b in intervals)
    if len(ivs) < 2:
        raise InputError(f"found {len(ivs)} static interval(s); a gyro calibration needs the moves between several")
    sl = [slice(a, b) for a, b in ivs]
    acc_means = np.array([acc[s][ok[s]].mean(axis=0) for s in sl])
    gyro_means = np.array([gyro[s][ok[s]].mean(axis=0) for s in sl])
    n_static = np.array([float(np.sum(ok[s])) for s in sl])
    rest_t = np.array([float(t[s][ok[s]].mean()) for s in sl])
    temperature = None if temp is None else np.asarray(temp, dtype=float).reshape(-1)
    rest_temp = None if temperature is None else np.array([float(np.nanmean(temperature[s][ok[s]])) for s in sl])
    gstd = np.array([gyro[s][ok[s]].std(axis=0, ddof=1) if np.sum(ok[s]) > 1 else np.zeros(3) for s in sl])
    if acc_sigma is None:
        sig = np.array([np.sqrt(np.mean(acc[s][ok[s]].var(axis=0, ddof=1))) / np.sqrt(max(n, 1)) if n > 1 else 0.0
                        for s, n in zip(sl, n_static)])
    else:
        sig = np.asarray(acc_sigma, float).reshape(len(ivs))
    noise = rest_noise(t, gyro, ok, ivs)
    usable_idx = np.flatnonzero(ok)
    pairs, mids, dts, first, last, frm, to, bounds, t_mids, temp_mids = [], [], [], [], [], [], [], [], [], []
    dropped: dict[str, int] = {}
    n_steps = holes = lost = 0
    for i in range(len(ivs) - 1):
        before = usable_idx[np.searchsorted(usable_idx, ivs[i][0]): np.searchsorted(usable_idx, ivs[i][1])]
        after = usable_idx[np.searchsorted(usable_idx, ivs[i + 1][0]): np.searchsorted(usable_idx, ivs[i + 1][1])]
        if before.size == 0 or after.size == 0 or after[0] <= before[-1]:
            dropped[NO_SAMPLES_MOVES] = dropped.get(NO_SAMPLES_MOVES, 0) + 1
            continue
        if at_rail is not None and at_rail[before[-1]: after[0] + 1].any():
            dropped[RAIL_MOVES] = dropped.get(RAIL_MOVES, 0) + 1
            continue
        lo, hi = np.searchsorted(usable_idx, [before[-1], after[0]])
        idx = usable_idx[lo: hi + 1]
        step = np.diff(t[idx])
        if np.any(step <= 0):
            dropped[TIME_MOVES] = dropped.get(TIME_MOVES, 0) + 1
            continue
        gaps = np.flatnonzero(step > HOLE_STEP_FACTOR * noise.period_s)
        bound = sum(hole_bound(t, gyro, usable_idx, lo + int(k), noise.period_s) for k in gaps)
        if gaps.size and bound > np.sqrt(np.sum(noise.arw2) * (t[idx[-1]] - t[idx[0]])):
            dropped[HOLE_MOVES] = dropped.get(HOLE_MOVES, 0) + 1
            continue
        holes += int(gaps.size)
        lost += int(np.sum(np.round(step[gaps] / noise.period_s) - 1)) if gaps.size else 0
        g = gyro[idx]
        pairs.append(np.stack([g[:-1], g[1:]], axis=1))
        mids.append(0.5 * (acc[idx[:-1]] + acc[idx[1:]]))
        t_mids.append(0.5 * (t[idx[:-1]] + t[idx[1:]]))
        if temperature is not None:
            temp_mids.append(0.5 * (temperature[idx[:-1]] + temperature[idx[1:]]))
        dts.append(step)
        f = np.zeros(step.size, bool)
        f[0] = True
        first.append(f)
        n_steps += step.size
        last.append(n_steps - 1)
        frm.append(i)
        to.append(i + 1)
        bounds.append(float(bound))
    if len(frm) < MIN_MOVES:
        reasons = "; ".join(f"{k}: {v}" for k, v in dropped.items()) or "none dropped"
        raise InputError(
            f"only {len(frm)} usable move(s) between {len(ivs)} static intervals ({reasons}); a gyro calibration "
            f"needs at least {MIN_MOVES}: record more rotations between still poses"
        )
    return MoveSet(
        acc_means=acc_means,
        acc_sigma=sig,
        gyro_means=gyro_means,
        n_static=n_static,
        gyro_static_std=gstd,
        move_from=np.array(frm),
        move_to=np.array(to),
        gyro_pairs=np.concatenate(pairs),
        acc_mid=np.concatenate(mids),
        dt=np.concatenate(dts),
        first_step=np.concatenate(first),
        last_step=np.array(last),
        exclusions=dropped,
        noise=noise,
        bridge_bound=np.array(bounds),
        bridged_holes=holes,
        bridged_samples=lost,
        t_mid=np.concatenate(t_mids),
        rest_t=rest_t,
        temp_mid=np.concatenate(temp_mids) if temperature is not None else None,
        rest_temp=rest_temp,
    )


def moves_from_segmentation(seg: "Segmentation") -> MoveSet:
    """Build a :class:`MoveSet` from a static detection of a recording with gyro channels."""
    rec = seg.recording
    if rec.gyro is None:
        raise InputError(
            f"{rec.path}: no gyro columns; a gyro calibration needs gx, gy, gz (map them with columns=, "
            "e.g. gx=gyro_x,gy=gyro_y,gz=gyro_z)"
        )
    ivs = [(iv.start, iv.stop) for iv in seg.intervals]
    sigma = np.array([iv.sigma for iv in seg.intervals])
    rail = None if rec.gyro_rail is None or rec.gyro_rail_kept else rec.gyro_rail.samples
    moves = moves_from_arrays(rec.t, rec.acc, rec.gyro, ivs, rec.gyro_usable, sigma, rec.temp, rail)
    return moves
