"""The moves of a static-pose recording: the samples between consecutive still intervals.

Tedaldi 2014 (section IV-B) calibrates the gyro by integrating it across each move, from
the end of one static interval to the start of the next.  A :class:`MoveSet` holds what
that needs, flattened for a vectorised integrator: every integration step ``k`` uses the
raw gyro samples at both ends (trapezoid: their mean over ``dt_k``), the raw specific
force at the mid-point (for the g-sensitivity), and a flag marking the first step of each
move; the per-interval raw accelerometer and gyro means give the gravity directions and
the bias.  A move that crosses an unusable sample (non-finite, duplicated, saturated) or a
gap in time cannot be integrated: it is dropped and counted in :attr:`MoveSet.exclusions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError

if TYPE_CHECKING:
    from optcal.data.static import Segmentation

#: A step longer than this many median steps is a gap: the move across it is dropped.
MAX_GAP_STEPS: float = 5.0
GAP_MOVES = "moves dropped: a gap in time or an unusable sample between two static intervals"
#: Fewest moves accepted (Tedaldi 2014 use about 30; nine parameters need far fewer).
MIN_MOVES: int = 6


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

    @property
    def n_moves(self) -> int:
        return int(self.move_from.size)

    @property
    def n_steps(self) -> int:
        return int(self.dt.size)

    def gyro_mid(self) -> NDArray[np.float64]:
        """Raw gyro averaged over each step (trapezoid rule), shape (N, 3)."""
        return self.gyro_pairs.mean(axis=1)


def moves_from_arrays(
    t: ArrayLike,
    acc: ArrayLike,
    gyro: ArrayLike,
    intervals: list[tuple[int, int]],
    usable: ArrayLike | None = None,
    acc_sigma: ArrayLike | None = None,
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
        Samples that may be integrated (all when omitted).
    acc_sigma : array_like, shape (p,), optional
        Standard deviation of each interval's accelerometer mean (default: white noise,
        ``std/√n``).

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
    ok = np.ones(t.size, bool) if usable is None else np.asarray(usable, bool)
    ivs = sorted((int(a), int(b)) for a, b in intervals)
    if len(ivs) < 2:
        raise InputError(f"found {len(ivs)} static interval(s); a gyro calibration needs the moves between several")
    sl = [slice(a, b) for a, b in ivs]
    acc_means = np.array([acc[s][ok[s]].mean(axis=0) for s in sl])
    gyro_means = np.array([gyro[s][ok[s]].mean(axis=0) for s in sl])
    n_static = np.array([float(np.sum(ok[s])) for s in sl])
    gstd = np.array([gyro[s][ok[s]].std(axis=0, ddof=1) if np.sum(ok[s]) > 1 else np.zeros(3) for s in sl])
    if acc_sigma is None:
        sig = np.array([np.sqrt(np.mean(acc[s][ok[s]].var(axis=0, ddof=1))) / np.sqrt(max(n, 1)) if n > 1 else 0.0
                        for s, n in zip(sl, n_static)])
    else:
        sig = np.asarray(acc_sigma, float).reshape(len(ivs))
    median_dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    pairs, mids, dts, first, last, frm, to = [], [], [], [], [], [], []
    dropped = 0
    n_steps = 0
    for i in range(len(ivs) - 1):
        a = ivs[i][1] - 1  # last sample of interval i
        b = ivs[i + 1][0]  # first sample of interval i + 1
        if b <= a:
            dropped += 1
            continue
        idx = np.arange(a, b + 1)
        step = np.diff(t[idx])
        if not np.all(ok[idx]) or np.any(step <= 0) or np.any(step > MAX_GAP_STEPS * median_dt):
            dropped += 1
            continue
        g = gyro[idx]
        pairs.append(np.stack([g[:-1], g[1:]], axis=1))
        mids.append(0.5 * (acc[idx[:-1]] + acc[idx[1:]]))
        dts.append(step)
        f = np.zeros(step.size, bool)
        f[0] = True
        first.append(f)
        n_steps += step.size
        last.append(n_steps - 1)
        frm.append(i)
        to.append(i + 1)
    exclusions = {GAP_MOVES: dropped} if dropped else {}
    if len(frm) < MIN_MOVES:
        raise InputError(
            f"only {len(frm)} usable move(s) between static intervals ({dropped} dropped for gaps or unusable "
            f"samples); a gyro calibration needs at least {MIN_MOVES}: record more rotations between still poses"
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
        exclusions=exclusions,
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
    moves = moves_from_arrays(rec.t, rec.acc, rec.gyro, ivs, rec.usable, sigma)
    return moves
