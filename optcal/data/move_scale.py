"""The gyro's scale measured on the moves: the rate integral across each move between two rests, composed as
rotations, against the turn of gravity's direction that the accelerometer sees (:func:`scale_from_moves`, which
:func:`optcal.data.gyro_unit.decide_gyro_scale` weighs against a stated unit).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.data.quantiles import np_median


#: Fewest moves (between rests, turning the accelerometer's gravity by at least :data:`MIN_MOVE_TURN_RAD`) on which
#: the gyro's scale is measured: a scale from one or two moves rests on their axes being across gravity.
MIN_SCALE_MOVES: int = 3
#: Most moves the scale is measured on (spread over the session): each move's misfit is a few tenths of a degree
#: of tens of degrees, so 24 of them measure the scale far finer than any unit's decision or test needs.
MAX_SCALE_MOVES: int = 24
#: Least turn of gravity's direction, rad (5°), a move needs to weigh in the gyro's scale: far above the direction
#: noise of two rests' means, and the gyro's bias integrated over a move of a few seconds.
MIN_MOVE_TURN_RAD: float = float(np.radians(5.0))
#: Largest share of the moves' turn (rms misfit of gravity's direction over the rms turn) a measured scale may leave
#: unexplained, as a gyro calibration may (:mod:`optcal.families.gyro.consistency`): beyond it the moves do not carry
#: the gyro's turn (a logger that stores only holds, columns that are not the moves' rates) and no scale is measured.
MAX_UNEXPLAINED_TURN: float = 0.2
#: The scales searched, rad/s per gyro unit, on a log grid: from a 24-bit converter at ±125 °/s (1.3e-7) to 1 rad/s.
SCALE_GRID: NDArray[np.float64] = np.logspace(-7.5, 0.5, 801)
#: The grid's step, natural log (1 %: fine enough that a revolution's alias and the true scale are told apart).
GRID_STEP_LOG: float = float(np.log(SCALE_GRID[1] / SCALE_GRID[0]))
#: Local minima of the grid refined when a turn's aliases are sorted out.
ALIAS_CANDIDATES: int = 8


@dataclass(frozen=True)
class ScaleEvidence:
    """The gyro's scale measured on the moves (:func:`scale_from_moves`).

    Attributes
    ----------
    rad_per_unit : float
        Radians per second per gyro unit.
    moves : int
        Moves it was measured on.
    rms_deg : float
        RMS misfit of gravity's direction after each move predicted by the scaled gyro, degrees.
    """

    rad_per_unit: float
    moves: int
    rms_deg: float


#: Longest move, seconds, whose turn is integrated: a calibration's moves last seconds, and over longer the bias'
#: error (0.1 °/s before the fit) integrates to a degree, while a stretch that long between two rests is seldom one
#: clean move (a rest the first pass missed, a pause of a hand).
MAX_MOVE_S: float = 10.0
#: Longest step, seconds, over which a move's rates are summed before its turn is composed (a hand's 200 °/s turns
#: 8° in a step: the error of composing such steps as fixed-axis rotations is far below a degree).
MOVE_STEP_S: float = 0.04


def _turn_about_axis(theta: NDArray[np.float64], u0: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each move's whole turn ``theta`` (moves, 3) as its angle per unit scale and the squared cosine between its
    axis and gravity before it, ``u0`` (moves, 3) (the parts of :func:`_predicted_cosines` that do not depend on the
    scale)."""
    norm = np.linalg.norm(theta, axis=1)
    n = theta / np.maximum(norm, np.finfo(float).tiny)[:, None]
    return norm, np.sum(n * u0, axis=1) ** 2


def _predicted_cosines(norm: NDArray[np.float64], along2: NDArray[np.float64], scales: NDArray[np.float64]
                       ) -> NDArray[np.float64]:
    """``cos`` of the angle between gravity before and after each move turned by ``scales × theta`` about the fixed
    axis ``theta``/|theta| (Rodrigues: ``cos α = cos φ + (1 − cos φ)(n·u₀)²``; ``norm`` and ``along2`` from
    :func:`_turn_about_axis`) (scales, moves)."""
    phi = np.outer(scales, norm)
    cos = np.cos(phi)
    return np.asarray(cos + (1.0 - cos) * along2)


#: Points per evaluation of the refinement: a bracket sampled at this many scales in one call (one composition of
#: the moves for all of them), twice, the second over the first's best point and its neighbours, then
#: a parabola through the best three: from ±4 grid steps (±10 %) to far below the 0.1 % a unit's decision or a
#: relevance test could see.
REFINE_POINTS: int = 9


def _move_increments(t: NDArray[np.float64], gyro: NDArray[np.float64], bias: NDArray[np.float64],
                     spans: list[tuple[int, int]]) -> NDArray[np.float64]:
    """Each move's rotation increments (moves, steps, 3; gyro units × s): the rates less ``bias`` integrated by the
    trapezoid rule and summed over steps of :data:`MOVE_STEP_S`, zero-padded to the longest move."""
    pieces = []
    for a, z in spans:
        w = gyro[a:z] - bias
        dt = np.diff(t[a:z])
        inc = 0.5 * (w[1:] + w[:-1]) * dt[:, None]
        step = max(1, int(round(MOVE_STEP_S / max(float(np_median(dt)) if dt.size else 1.0, 1e-12))))
        edges = np.arange(0, inc.shape[0], step)
        pieces.append(np.add.reduceat(inc, edges, axis=0) if inc.shape[0] else np.zeros((1, 3)))
    length = max(p.shape[0] for p in pieces)
    out = np.zeros((len(pieces), length, 3))
    for i, p in enumerate(pieces):
        out[i, :p.shape[0]] = p
    return out


def _turned(increments: NDArray[np.float64], u0: NDArray[np.float64], scales: NDArray[np.float64]) -> NDArray[np.float64]:
    """Gravity's direction after each move, in the sensor frame, for each scale (scales, moves, 3).

    The sensor's orientation composes the moves' increments scaled by ``s`` (quaternions, body-frame increments:
    ``q ← q ⊗ exp(s φ / 2)``); a direction fixed in the world, ``u₀`` in the sensor before the move, is ``R(q)ᵀ u₀``
    after it.  Quaternion components as separate arrays, not :func:`optcal.core.rotations.exponential_map` and
    matrix products, and the steps composed pairwise (associative, order kept): ⌈log₂ n⌉ array products in place of one
    per step.
    """
    # zero steps (exact identities) appended to a multiple of 8: the first three halvings need no identity appended,
    # and the real steps keep their positions, so the pairs, and the result, are the same
    steps = increments.shape[1]
    if steps > 8 and steps % 8:
        increments = np.concatenate([increments, np.zeros((increments.shape[0], 8 - steps % 8, 3))], axis=1)
    # each step's increment as a quaternion (scales, moves, steps), in place: the operations and their order of
    # angle = √(rx² + ry² + rz²), k = sin(angle/2)/angle (½ below 1e-12), w = cos(angle/2), (x, y, z) = k r
    rx, ry, rz = (scales[:, None, None] * increments[None, :, :, c] for c in range(3))
    angle = rx * rx
    tmp = ry * ry
    angle += tmp
    np.multiply(rz, rz, out=tmp)
    angle += tmp
    np.sqrt(angle, out=angle)
    half = np.multiply(angle, 0.5, out=tmp)
    k = np.sin(half)
    k /= np.maximum(angle, 1e-300)
    np.copyto(k, 0.5, where=~(angle > 1e-12))
    w = np.cos(half, out=angle)
    x, y, z = np.multiply(rx, k, out=rx), np.multiply(ry, k, out=ry), np.multiply(rz, k, out=rz)
    while w.shape[-1] > 1:
        if w.shape[-1] % 2:  # an identity appended: the last step pairs with it
            one = np.ones(w.shape[:-1] + (1,))
            zero = np.zeros_like(one)
            w = np.concatenate([w, one], axis=-1)
            x, y, z = (np.concatenate([a, zero], axis=-1) for a in (x, y, z))
        w, x, y, z = _pair_products(w, x, y, z)
    w, x, y, z = w[..., 0], x[..., 0], y[..., 0], z[..., 0]
    w, v = w[..., None], np.stack([x, y, z], axis=-1)
    u = np.broadcast_to(u0, v.shape)
    # R(q)ᵀ u = u − 2w (v × u) + 2 v × (v × u)
    c = np.cross(v, u)
    return np.asarray(u - 2.0 * w * c + 2.0 * np.cross(v, c))


def _pair_products(w: NDArray[np.float64], x: NDArray[np.float64], y: NDArray[np.float64], z: NDArray[np.float64]
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The quaternion products ``a ⊗ b`` of each even step ``a`` with the odd step ``b`` after it (last axis), each
    component accumulated in place in the order of ``aw bw − ax bx − ay by − az bz``, ``aw bx + bw ax + ay bz − az by``,
    ``aw by + bw ay + az bx − ax bz``, ``aw bz + bw az + ax by − ay bx``."""
    a = (w[..., 0::2], x[..., 0::2], y[..., 0::2], z[..., 0::2])
    b = (w[..., 1::2], x[..., 1::2], y[..., 1::2], z[..., 1::2])
    t = np.empty_like(a[0])
    out = []
    # (first product, then (sign, left factor, right factor) of the terms added in order), per component
    for (i0, j0), terms in (((0, 0), ((-1, 1, 1), (-1, 2, 2), (-1, 3, 3))),
                            ((0, 1), ((+1, 1, 0), (+1, 2, 3), (-1, 3, 2))),
                            ((0, 2), ((+1, 2, 0), (+1, 3, 1), (-1, 1, 3))),
                            ((0, 3), ((+1, 3, 0), (+1, 1, 2), (-1, 2, 1)))):
        acc = a[i0] * b[j0]
        for sign, i, j in terms:
            # bw ax is written b-first in the formula; multiplication commutes exactly
            np.multiply(a[i], b[j], out=t)
            if sign > 0:
                acc += t
            else:
                acc -= t
        out.append(acc)
    return out[0], out[1], out[2], out[3]


def _refine_logs(cost: Callable[[NDArray[np.float64]], NDArray[np.float64]], lo: NDArray[np.float64],
                 hi: NDArray[np.float64]) -> NDArray[np.float64]:
    """For each bracket ``[lo[i], hi[i]]`` (logs of scales), the log of the scale minimising ``cost`` (of an array
    of scales, each scale's cost its own) within it: :data:`REFINE_POINTS` points evaluated at once (all brackets in
    one call), again between the best one's neighbours, and the vertex of the parabola through the best point and
    its neighbours (kept within them)."""
    lo, hi = np.atleast_1d(np.asarray(lo, dtype=float)), np.atleast_1d(np.asarray(hi, dtype=float))
    rows = np.arange(lo.size)
    for _ in range(2):
        x = np.linspace(lo, hi, REFINE_POINTS, axis=-1)  # (brackets, points)
        c = np.asarray(cost(np.exp(x).ravel())).reshape(x.shape)
        i = np.argmin(c, axis=1)
        lo, hi = x[rows, np.maximum(i - 1, 0)], x[rows, np.minimum(i + 1, REFINE_POINTS - 1)]
    best = x[rows, i]
    inner = (i > 0) & (i < REFINE_POINTS - 1)
    c0 = c[rows, np.maximum(i - 1, 0)]
    c1 = c[rows, i]
    c2 = c[rows, np.minimum(i + 1, REFINE_POINTS - 1)]
    curvature = c0 - 2.0 * c1 + c2
    vertex = inner & (curvature > 0.0)
    step = x[:, 1] - x[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):  # the brackets without a vertex keep their best point
        moved = np.clip(best + 0.5 * step * (c0 - c2) / curvature, lo, hi)
    return np.where(vertex, moved, best)


def scale_from_moves(t: NDArray[np.float64], gyro: NDArray[np.float64], bias: NDArray[np.float64],
                     spans: list[tuple[int, int]], before: NDArray[np.float64], after: NDArray[np.float64]
                     ) -> ScaleEvidence | None:
    """Radians per gyro unit from the moves: the rate integral across each move against the turn of gravity.

    Each move (samples ``spans[i]``, between two rests whose specific force directions are ``before[i]`` and
    ``after[i]``) is integrated (rates less ``bias``) and composed as rotations (:func:`_turned`); the scale is the
    one whose turned ``before`` best meets ``after`` over the moves (least squares on a log grid, then refined
    between the grid's neighbours).  None with fewer than :data:`MIN_SCALE_MOVES` moves turning gravity by
    :data:`MIN_MOVE_TURN_RAD`, or when the best scale leaves more than :data:`MAX_UNEXPLAINED_TURN` of their turn
    unexplained.
    """
    turns = np.arccos(np.clip(np.sum(before * after, axis=1), -1.0, 1.0))
    keep = [i for i, (a, z) in enumerate(spans)
            if z - a >= 2 and t[z - 1] - t[a] <= MAX_MOVE_S and turns[i] >= MIN_MOVE_TURN_RAD]
    if len(keep) < MIN_SCALE_MOVES:
        return None
    if len(keep) > MAX_SCALE_MOVES:  # spread over the session: enough moves to measure a scale to a fraction of 1 %
        keep = [keep[i] for i in np.linspace(0, len(keep) - 1, MAX_SCALE_MOVES).round().astype(int)]
    increments = _move_increments(t, gyro, bias, [spans[i] for i in keep])
    start, end = before[keep], after[keep]

    def cost(scales: NDArray[np.float64]) -> NDArray[np.float64]:
        d = _turned(increments, start, scales) - end
        return np.asarray(np.sum(d * d, axis=(1, 2)))

    # the grid on each move's whole turn about its mean axis (closed form), then the composed turns between the
    # grid point's neighbours: a hand's axis changes within a move, which only the composition follows
    theta = increments.sum(axis=1)
    measured = np.sum(start * end, axis=1)
    norm, along2 = _turn_about_axis(theta, start)

    def approximate(scales: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(np.sum((_predicted_cosines(norm, along2, scales) - measured) ** 2, axis=1))

    grid = approximate(SCALE_GRID)
    # a turn fits as well with whole revolutions added (a table's turns by multiples of 45° alias at larger scales):
    # each of the grid's lowest local minima refined, and of those within twice the best cost the smallest scale,
    # the one without extra revolutions
    interior = np.r_[True, grid[1:] <= grid[:-1]] & np.r_[grid[:-1] <= grid[1:], True]
    candidates = np.flatnonzero(interior)
    candidates = candidates[np.argsort(grid[candidates])[:ALIAS_CANDIDATES]]
    logs = _refine_logs(approximate, np.log(SCALE_GRID[np.maximum(candidates - 1, 0)]),
                        np.log(SCALE_GRID[np.minimum(candidates + 1, SCALE_GRID.size - 1)]))
    costs = approximate(np.exp(logs))
    x = float(logs[costs <= 2.0 * float(costs.min()) + 1e-9 * increments.shape[0]].min())
    # the composed turns' best lies within ±10 % of the fixed axis' (a hand's axis changes within a move)
    best = float(np.exp(_refine_logs(cost, np.array([x - 4.0 * GRID_STEP_LOG]), np.array([x + 4.0 * GRID_STEP_LOG]))[0]))
    fitted = _turned(increments, start, np.array([best]))[0]
    misfit = np.degrees(np.arccos(np.clip(np.sum(fitted * end, axis=1), -1.0, 1.0)))
    angles = np.degrees(np.arccos(np.clip(np.sum(start * end, axis=1), -1.0, 1.0)))
    rms = float(np.sqrt(np.mean(misfit**2)))
    if rms > MAX_UNEXPLAINED_TURN * float(np.sqrt(np.mean(angles**2))):
        return None
    return ScaleEvidence(best, len(keep), rms)
