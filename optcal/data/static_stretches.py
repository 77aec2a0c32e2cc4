"""Static stretches of a recording: runs of static samples, split, joined into poses, or rejected.

The static detector (:func:`optcal.data.static.detect_static`) turns its mask of static samples
into runs (:func:`true_runs`), splits them at time gaps (:func:`split_runs`), joins the runs of
one orientation interrupted by a twitch into one pose (:func:`join_interrupted`), and rejects the
groups that turn slowly (:func:`sweep`, :func:`reject_sweeping`) or whose gyro is not at rest
(:func:`reject_turning`).  A group of stretches is a list of sample ranges ``[a, b)``
(:func:`group_positions`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

def true_runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return edges[::2], edges[1::2]


def join_interrupted(
    ranges: list[tuple[int, int]],
    t: NDArray[np.float64],
    acc: NDArray[np.float64],
    window_s: float,
    tolerance: float,
) -> list[list[tuple[int, int]]]:
    """Group static stretches that are one pose interrupted by a twitch.

    Consecutive stretches ``[a, b)`` separated by less than one window in time whose means
    differ by less than ``tolerance`` (the accelerometer gate, raw units) are the same
    orientation held by hand through a brief tremor: one pose, the samples between them
    left out (and counted as moving).
    """
    groups: list[list[tuple[int, int]]] = []
    last_mean: NDArray[np.float64] | None = None
    for a, b in ranges:
        mean = acc[a:b].mean(axis=0)
        if (
            groups
            and last_mean is not None
            and t[a] - t[groups[-1][-1][1] - 1] < window_s
            and float(np.linalg.norm(mean - last_mean)) < tolerance
        ):
            groups[-1].append((a, b))
            n = sum(y - x for x, y in groups[-1])
            last_mean = np.sum([acc[x:y].sum(axis=0) for x, y in groups[-1]], axis=0) / n
        else:
            groups.append([(a, b)])
            last_mean = mean
    return groups


def split_runs(
    starts: NDArray[np.int64], stops: NDArray[np.int64], breaks: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Split runs ``[a, b)`` at the sample indices ``breaks`` (a new run starts there)."""
    out_a, out_b = [], []
    for a, b in zip(starts, stops):
        inner = breaks[(breaks > a) & (breaks < b)]
        edges = [a, *inner.tolist(), b]
        out_a.extend(edges[:-1])
        out_b.extend(edges[1:])
    return np.asarray(out_a, dtype=int), np.asarray(out_b, dtype=int)


def sweep(x: NDArray[np.float64], window: int) -> float:
    """How far the mean of ``x`` (n, 3) moves across it: ‖max − min‖ over the axes of the means of
    consecutive blocks of ``window`` samples (0 for fewer than two blocks).

    A slow turn that keeps ‖a‖ (by hand about an axis near the vertical) moves the axes by less than
    the noise within one window, so neither the moving standard deviation nor the half-window drift
    sees it, but over a stretch of several windows its block means sweep far beyond the noise.
    """
    blocks = x.shape[0] // window
    if blocks < 2:
        return 0.0
    means = np.add.reduce(x[: blocks * window].T.reshape(x.shape[1], blocks, window), axis=2) / window
    return float(np.linalg.norm(means.max(axis=1) - means.min(axis=1)))


def reject_sweeping(
    groups: list[list[tuple[int, int]]], acc: NDArray[np.float64], window: int, limit: float,
    in_pose: NDArray[np.bool_],
) -> tuple[list[list[tuple[int, int]]], int, int]:
    """Drop the groups whose block means sweep by more than ``limit`` (the accelerometer gate, :func:`sweep`).

    At rest the means of one-window blocks scatter by the noise of a mean, far below the gate
    (≤ 0.72 of it over every static pose of the recordings in ../shared/data); ``in_pose`` is cleared
    for the dropped samples; returns the kept groups, the number dropped and their samples.
    """
    kept: list[list[tuple[int, int]]] = []
    n_dropped = n_samples = 0
    for group in groups:
        pos = group_positions(group)
        if sweep(acc[pos], window) <= limit:
            kept.append(group)
            continue
        n_dropped += 1
        n_samples += sum(b - a for a, b in group)
        in_pose[pos] = False
    return kept, n_dropped, n_samples


def reject_turning(
    groups: list[list[tuple[int, int]]], gyro: NDArray[np.float64], limit: float, in_pose: NDArray[np.bool_]
) -> tuple[list[list[tuple[int, int]]], int, int]:
    """Drop the groups whose gyro standard deviation (norm over the axes) exceeds ``limit``.

    Used when a recording's gyro noise floor is above a resting gyro's: its quiet stretches
    are the slowest parts of a motion, not rests.  ``in_pose`` is cleared for the dropped
    samples; returns the kept groups, the number dropped and their samples.
    """
    kept: list[list[tuple[int, int]]] = []
    n_dropped = n_samples = 0
    for group in groups:
        pos = np.concatenate([np.arange(a, b) for a, b in group])
        spread = float(np.sqrt(np.sum(np.var(gyro[pos], axis=0, ddof=1))))
        if spread <= limit:
            kept.append(group)
            continue
        n_dropped += 1
        n_samples += int(pos.size)
        in_pose[pos] = False
    return kept, n_dropped, n_samples


def group_positions(group: list[tuple[int, int]]) -> slice | NDArray[np.int64]:
    """The sample positions of a group of stretches ``[a, b)``: a slice for one stretch (no index array)."""
    if len(group) == 1:
        return slice(int(group[0][0]), int(group[0][1]))
    return np.concatenate([np.arange(a, b) for a, b in group])
