"""The rests that are one pose interrupted, joined (:func:`join_twitches`): the same mean, and the sensor did
not turn between them by the gyro (:func:`no_net_turn`) or, without it, by the accelerometer
(:func:`stays_in_pose`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.data import rest_model as rm
from optcal.data.quantiles import grouped_column_medians
from optcal.data.rest_model import SAME_POSE_SAMPLE_SIGMAS, WOBBLE_SHRINK

if TYPE_CHECKING:
    from optcal.data.rest_tests import RestModel


def no_net_turn(gyro: NDArray[np.float64], t: NDArray[np.float64], before: tuple[int, int], after: tuple[int, int],
                model: RestModel, block: int, gyro_scale: float | None) -> bool:
    """Whether the gyro shows no net turn between the rests ``before`` and ``after`` (sample ranges): a twitch that
    came back.

    The rates less the bias integrated over the interruption, against the noise of that integral: the larger of
    the model's (the per-sample noise of the next rest's blocks times the noise colour, as a random walk, and the
    bias' wander over the interruption; χ²₃ at the false-alarm probability) and the integrals over windows of the
    interruption's length inside the two rests themselves, which carry the gyro's noise over that time whatever
    its colour (a filter's, or the rounding of a filtered rate; ``3 F(3, windows)``, from
    :data:`~optcal.data.rest_model.TREND_MIN_BATCHES` windows).  A significant net turn smaller than a pose's
    wobble tolerance (gyro in known units) is no turn either.
    """
    if model.bias is None or model.gvar_ref is None:
        return False
    end, start = before[1], after[0]
    if start <= end:
        return True
    dt = np.diff(t[end - 1:start + 1])
    bias = model.track[block]  # the bias where the sensor rests again
    rates = gyro[end:start] - bias
    net = (rates * dt[: rates.shape[0], None]).sum(axis=0)
    span = float(dt.sum())
    var = model.gkappa2 * (model.gvar_ref[block] * float(np.sum(dt * dt)) + model.gfloor * span * span) + model.wander2 * span * span
    tiny = np.finfo(float).tiny
    if float(np.sum(net * net / np.maximum(var, tiny))) <= rm.chi2_limit(model.s.false_alarm, 3) * model.s.gyro_threshold:
        return True  # within the model's noise, and so within the larger one measured below (its limit is larger too)
    windows = [_window_integrals(gyro, t, piece, start - end, bias) for piece in (before, after)]
    measured = np.concatenate(windows)
    if measured.shape[0] >= rm.TREND_MIN_BATCHES:
        var = np.maximum(var, (measured * measured).mean(axis=0))
        limit = rm.step_limit_one(model.s.false_alarm, float(measured.shape[0]))
        if float(np.sum(net * net / np.maximum(var, tiny))) <= limit * model.s.gyro_threshold:
            return True
    return gyro_scale is not None and float(np.linalg.norm(net)) * gyro_scale < np.sqrt(2.0 * WOBBLE_SHRINK) * model.s.gyro_threshold


def _window_integrals(gyro: NDArray[np.float64], t: NDArray[np.float64], piece: tuple[int, int], length: int,
                      bias: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rates less ``bias`` integrated over consecutive windows of ``length`` samples inside ``piece`` (k, 3)."""
    a, z = piece
    count = (z - a - 1) // length
    if count < 1:
        return np.zeros((0, 3))
    stop = a + 1 + count * length
    increments = (gyro[a + 1:stop] - bias) * np.diff(t[a:stop])[:, None]
    return np.asarray(np.add.reduceat(increments, np.arange(0, count * length, length), axis=0))


def stays_in_pose(model: RestModel, k_from: int, k_to: int, mean: NDArray[np.float64],
                  per_sample_var: NDArray[np.float64]) -> bool:
    """Whether the accelerometer's block means ``[k_from, k_to)`` (an interruption between two pieces of a rest)
    all stay within a pose's wobble tolerance of the pieces' common ``mean``.

    A block mean may lie off ``mean`` by the critical value of its noise (the pieces' per-sample variance times
    the noise colour over the block's samples; χ²₃ at the false-alarm probability shared over the blocks) plus
    the orientation a rest is allowed to wobble through, ``√(2 WOBBLE_SHRINK)`` rad of the mean's norm: the
    sensor never left the pose.  A move away and back to the same orientation (a pose revisited) leaves it.
    """
    b = model.b
    if k_to <= k_from:
        return True
    d = b.mean[k_from:k_to] - mean
    distance = np.sqrt((d * d).sum(axis=1))
    noise2 = (model.kappa2 * per_sample_var).sum() / b.n[k_from:k_to] + (model.kappa2 * model.floor).sum()
    limit = rm.chi2_limit(model.s.false_alarm / (k_to - k_from), 3) * model.s.threshold
    allowed = np.sqrt(2.0 * WOBBLE_SHRINK) * float(np.linalg.norm(mean)) + np.sqrt(limit * noise2)
    return bool(np.all(distance <= allowed))


def join_twitches(kept: list[tuple[int, int, int, int]], t: NDArray[np.float64], model: RestModel,
                   dwell_s: float, gyro: NDArray[np.float64] | None,
                   gyro_scale: float | None, max_gap: float) -> list[list[tuple[int, int]]]:
    """Group consecutive rests that are one pose interrupted (a twitch, a test's false alarm).

    Two consecutive rests are one pose when their means do not differ -- by less than the noise of the
    difference (each mean's variance from the scatter of its block means, at least ``κ² v / n``), or by
    less than :data:`SAME_POSE_SAMPLE_SIGMAS` per-sample σ (a flicker noise's wander between two pieces
    of one rest) -- and the sensor did not turn between them: by the gyro, no net turn
    (:func:`no_net_turn`; a turn that comes back to the same orientation, a full turn of a table, is a
    move), or when the interruption is shorter than the dwell (the dwell as a prior: no pose is left and
    regained in less time than one is held); without the gyro as evidence, when the accelerometer shows that
    the sensor never left the pose between them (:func:`stays_in_pose`: a filter's smoothing or a knock cut one
    rest in two).  Never across a time gap.
    """
    groups: list[list[tuple[int, int]]] = []
    last: tuple[NDArray[np.float64], NDArray[np.float64], float, NDArray[np.float64]] | None = None  # the group's first piece
    previous_end = 0  # the block after the previous piece
    means, se2s, _ = _piece_means(model, [p[2] for p in kept], [p[3] for p in kept]) if kept else (None, None, None)
    for i, (a, z, j0, j1) in enumerate(kept):
        assert means is not None and se2s is not None
        mean, se2 = means[i], se2s[i]
        sd = model.spread(j0, j1)  # the samples' spread about the piece's mean, its wander included
        if groups and last is not None:
            d = mean - last[0]
            stat = float(np.sum(d * d / np.maximum(se2 + last[1], np.finfo(float).tiny)))
            same = stat <= rm.step_limit_one(model.s.false_alarm, 1e6) * model.s.threshold \
                or float(np.linalg.norm(d)) < SAME_POSE_SAMPLE_SIGMAS * min(sd, last[2])
            if same and _still_between(groups[-1][-1], (a, z), previous_end, j0, t, model, dwell_s, gyro, gyro_scale,
                                       max_gap, 0.5 * (mean + last[0]),
                                       0.5 * (model.pooled_variance(j0, j1) + last[3])):
                groups[-1].append((a, z))
                previous_end = j1
                continue
        groups.append([(a, z)])
        last = (mean, se2, sd, model.pooled_variance(j0, j1))
        previous_end = j1
    return groups


def _piece_mean(model: RestModel, j0: int, j1: int) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """The mean of the blocks ``[j0, j1)``, its variance (the scatter of its block means, at least ``κ² v / n``),
    and its samples (:func:`_piece_means` of one piece)."""
    mean, se2, n = _piece_means(model, [j0], [j1])
    return mean[0], se2[0], float(n[0])


def _piece_means(model: RestModel, j0: list[int], j1: list[int]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """For the pieces of blocks ``[j0[i], j1[i])`` (none empty) at once: their means (k, 3), each mean's variance (the
    scatter of its block means over their number, at least ``κ² v / n`` of the median block variance ``v``), and
    their samples (k,)."""
    b = model.b
    r = rm.Ranges.of(list(j0), list(j1))
    w = b.n[r.rows, None]
    n = r.sums(w)
    mean = r.sums(b.mean[r.rows] * w) / n
    count = r.length.astype(float)[:, None]
    white = model.kappa2 * (grouped_column_medians(b.var[r.rows], r.length) / n + model.floor)
    plain = r.sums(b.mean[r.rows]) / count
    d = b.mean[r.rows] - plain[r.owner]
    with np.errstate(divide="ignore", invalid="ignore"):  # one block: its white noise instead
        scatter = r.sums(d * d) / (count - 1.0) / count
    scatter = np.where(count >= 2, scatter, white)
    return mean, np.maximum(white, scatter), n[:, 0]



def _still_between(before: tuple[int, int], after: tuple[int, int], k_from: int, k_to: int, t: NDArray[np.float64],
                   model: RestModel, dwell_s: float, gyro: NDArray[np.float64] | None, gyro_scale: float | None,
                   max_gap: float, mean: NDArray[np.float64], per_sample_var: NDArray[np.float64]) -> bool:
    """Whether the sensor stayed in its pose between the rests ``before`` and ``after`` (sample ranges; blocks
    ``[k_from, k_to)`` between them): see :func:`join_twitches`."""
    end, a = before[1], after[0]
    if float(np.max(np.diff(t[end - 1:a + 1]))) > max_gap:
        return False  # nothing is known of what the sensor did in a gap of the recording
    block_s = model.block / model.rate  # both pieces' ends fall on block edges: the interruption is known to two blocks
    if t[a] - t[end - 1] < dwell_s + 2.0 * block_s:
        return True
    if gyro is not None:
        return no_net_turn(gyro, t, before, after, model, k_to, gyro_scale)
    return stays_in_pose(model, k_from, k_to, mean, per_sample_var)
