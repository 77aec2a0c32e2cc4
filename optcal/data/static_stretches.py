"""Still stretches of a recording: runs, the gyro's unit and wobble, and the pieces of one pose joined.

The rest model (:mod:`optcal.data.rest_tests`) finds runs of still blocks (:func:`true_runs`); these helpers
read the gyro in radians (:func:`gyro_rad_per_unit`), measure how a stretch's orientation wobbles
(:func:`wobble`), join the rests that are one pose interrupted (:func:`join_twitches`, :func:`no_net_turn`),
and give a pose's sample positions (:func:`group_positions`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.core.units import RAD_PER_UNIT
from optcal.data import rest_model as rm
from optcal.data.quantiles import column_medians, grouped_column_medians, np_column_medians, np_median, np_quantile
from optcal.data.recording import Recording
from optcal.data.rest_model import SAME_POSE_SAMPLE_SIGMAS, UNIT_RATE_QUANTILE, WOBBLE_SHRINK

if TYPE_CHECKING:
    from optcal.data.rest_tests import RestModel


def true_runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return edges[::2], edges[1::2]


#: A measured scale names a unit when it lies within this factor of the unit's (rad/s, deg/s): the fixed-axis
#: approximation of a hand's move and the bias err by tens of percent, the two units differ 57-fold.
UNIT_MATCH_FACTOR: float = 2.0


def decide_gyro_scale(rec: Recording, measured: ScaleEvidence | None, fallback: float | None) -> tuple[float | None, str]:
    """The gyro's radians per second per unit, and the decision in words (printed by ``optcal segment``).

    A unit the file or the user states (``--gyro-units``) is taken, and the moves' scale said beside it when it
    disagrees by more than :data:`UNIT_MATCH_FACTOR`; a unit the names do not say is the one whose scale the moves'
    (:func:`scale_from_moves`) lies within :data:`UNIT_MATCH_FACTOR` of, else the moves' scale itself (counts, or
    a unit of its own); without moves, ``fallback`` (the convention of the accelerometer's unit, or None for counts).
    """
    flag = "--gyro-units to override"
    if rec.gyro_units in RAD_PER_UNIT:
        stated = RAD_PER_UNIT[rec.gyro_units]
        note = ""
        if measured is not None and abs(np.log(measured.rad_per_unit / stated)) > np.log(UNIT_MATCH_FACTOR):
            note = (f"; the moves say {measured.rad_per_unit:.4g} rad/s per unit ({measured.moves} moves): check the "
                    "columns' unit")
        return stated, f"{rec.gyro_units} as stated{note}"
    if measured is None:
        none = (f"no moves measure its scale (fewer than {MIN_SCALE_MOVES} turning gravity by "
                f"{np.degrees(MIN_MOVE_TURN_RAD):g}° within {MAX_MOVE_S:g} s, or their turn left more than "
                f"{MAX_UNEXPLAINED_TURN:.0%} unexplained)")
        if fallback is None:
            return None, f"{rec.gyro_units or 'unit unstated'}: {none}; {flag}"
        unit = "rad/s" if fallback == RAD_PER_UNIT["rad/s"] else "deg/s"
        return fallback, f"{unit} by the convention beside {rec.units}: {none}; {flag}"
    evidence = (f"the rate integral across {measured.moves} moves against the accelerometer's turn: "
                f"{measured.rad_per_unit:.4g} rad/s per unit, {measured.rms_deg:.2g}° rms")
    if rec.gyro_units is None:
        for unit in ("rad/s", "deg/s"):
            if abs(np.log(measured.rad_per_unit / RAD_PER_UNIT[unit])) <= np.log(UNIT_MATCH_FACTOR):
                return RAD_PER_UNIT[unit], f"{unit} from {evidence} ({flag})"
    per_dps = RAD_PER_UNIT["deg/s"] / measured.rad_per_unit
    unit = rec.gyro_units or ("counts" if rec.units == "counts" else "a unit of its own")
    return measured.rad_per_unit, f"{unit}, {per_dps:.4g} per °/s from {evidence} ({flag})"


def gyro_rad_per_unit(rec: Recording, gyro: NDArray[np.float64] | None, bias: NDArray[np.float64] | None,
                       blocks: rm.Blocks) -> float | None:
    """Radians per second per gyro unit, for a gyro whose unit the file does not state.

    The moves say it: gravity's direction in the sensor turns no faster than the sensor, so between
    consecutive blocks the accelerometer's turn rate |Δĝ|/Δt is at most the gyro's rate; at the fast moves
    (the :data:`UNIT_RATE_QUANTILE` quantile of both) the gyro reads 1-3 times the accelerometer's turn rate
    in rad/s and 57 times more in °/s.  A ratio above √57.3 (half-way on the log scale) says °/s.  A recording
    that never turns (its accelerometer's fast quantile within its noise) keeps the convention of the
    accelerometer's units: rad/s beside m/s² (ROS's ``sensor_msgs/Imu``), °/s beside g (datasheets).
    ``None`` for counts (their scale is the sensor's).
    """
    if gyro is None:
        return None
    if rec.gyro_units in RAD_PER_UNIT:
        return RAD_PER_UNIT[rec.gyro_units]
    if rec.gyro_units is not None or bias is None or blocks.gmean is None or rec.units == "counts":
        return None  # counts, or beside an accelerometer in counts: the scale is the sensor's
    u = blocks.mean / np.linalg.norm(blocks.mean, axis=1, keepdims=True)
    dt = np.diff(blocks.t_mid)
    ok = blocks.joined[1:] & (dt > 0)
    if ok.sum() >= 2:
        turn = np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0))[ok] / dt[ok]
        # the accelerometer's turn rate that its noise alone gives: two block means' noise over the block step
        noise = np.sqrt(2.0 * np_median(blocks.var.sum(axis=1) / blocks.n)) / np_median(np.linalg.norm(blocks.mean, axis=1))
        acc_fast = np_quantile(turn, UNIT_RATE_QUANTILE)
        if acc_fast > 3.0 * noise / float(np_median(dt)):
            gyro_fast = np_quantile(np.linalg.norm(blocks.gmean - bias, axis=1), UNIT_RATE_QUANTILE)
            ratio = gyro_fast / acc_fast
            return RAD_PER_UNIT["deg/s"] if ratio > np.sqrt(1.0 / RAD_PER_UNIT["deg/s"]) else RAD_PER_UNIT["rad/s"]
    return RAD_PER_UNIT["rad/s"] if rec.units == "m/s^2" else RAD_PER_UNIT["deg/s"]


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


#: Largest share of the wobble tolerance (``√(2 WOBBLE_SHRINK)``) the gyro's own angle random walk over a window may
#: reach for the gyro to be evidence of a wobble: a mean square of a random walk over one window scatters by about
#: its own size, so a noisier gyro's wobble is its noise, and the tolerance is left to the accelerometer's tests.
RESOLVED_WOBBLE_SHARE: float = 0.5


#: Samples × axes of gathered windows held at once by :func:`wobbles` (a bound on its scratch memory: about 8 MB per
#: array of them, a handful of arrays).
WOBBLE_CHUNK_VALUES: int = 1 << 20


def wobble(gyro: NDArray[np.float64], t: NDArray[np.float64], rad_per_unit: float, window: int,
           tolerance: float | None = None) -> float:
    """RMS angle (rad, norm over the axes) by which the orientation moves about its mean within windows of ``window``
    samples: :func:`wobbles` of the one stretch ``gyro`` (m, 3) at ``t`` (m,)."""
    return float(wobbles(gyro, t, rad_per_unit, window, [(0, gyro.shape[0])], tolerance)[0])


def wobbles(gyro: NDArray[np.float64], t: NDArray[np.float64], rad_per_unit: float, window: int,
            spans: list[tuple[int, int]], tolerance: float | None = None,
            blocks: rm.Blocks | None = None) -> NDArray[np.float64]:
    """RMS angle (rad, norm over the axes) by which the orientation moves about its mean within windows of ``window``
    samples, for each stretch ``spans[i]`` (samples ``[a, z)`` of ``gyro`` (n, 3) at ``t`` (n,); all at once).

    In each window (:data:`WOBBLE_DWELLS` dwells; a stretch's samples past its last whole window are one more
    window, when three or more) the rates less their mean (the bias, and a steady turn, which
    :meth:`optcal.data.rest_tests.RestModel.turns` tests) are integrated by the trapezoid rule over the true time
    steps, less what the gyro's own white noise gives (its angle random walk, from the rates' sample-to-sample
    differences): a hand's tremor or a vibration is left.  0 when that random walk reaches
    :data:`RESOLVED_WOBBLE_SHARE` of the tolerance: the gyro cannot resolve it.

    With ``tolerance`` (rad), a stretch whose wobble cannot reach it returns that bound instead: within a window
    of ``T`` the angle moves from its mean by at most ``∫|ω − ω̄| ≤ T·rms(ω − ω̄)``, and the windows' mean squares
    are at most the stretch's, so the wobble is at most ``T`` times the stretch's rate spread.

    ``blocks``: the rest model's blocks of these very samples (``blocks.gmean``, ``blocks.gvar`` of ``gyro``), from
    which that spread is summed block by block (:func:`_block_span_sums`) instead of sample by sample: the same
    spread, from the blocks' moments, at least as large (their variances carry ``q²/12`` and a rounding floor), with a
    margin for the rounding of either sum added (:func:`_spread_margin`), so that it stays a bound and no stretch's
    verdict changes: a stretch it cannot clear is measured window by window as without it.
    """
    a = np.array([span[0] for span in spans], dtype=np.intp)
    z = np.array([span[1] for span in spans], dtype=np.intp)
    m = z - a
    out = np.zeros(a.size)
    todo = m >= 3
    if tolerance is not None and todo.any():
        # each stretch's rate spread by sums over it (one pass over the samples for all stretches)
        # about the stretches' first rates' median (a gyro's bias: a large one would cancel the spread's digits)
        centre = np_column_medians(gyro[a[todo]])
        if blocks is None:
            s1, s2 = _span_sums(gyro, a, z, centre)
        else:
            s1, s2 = _block_span_sums(gyro, blocks, a, z, centre)
        mm = np.maximum(m, 1)[:, None]
        spread2 = np.maximum(s2 / mm - (s1 / mm) ** 2, 0.0).sum(axis=1)
        if blocks is not None:
            spread2 += _spread_margin(s2 / mm, m)
        spread = np.sqrt(spread2)
        window_s = t[a + np.minimum(window, m) - 1] - t[a]
        bound = window_s * spread * rad_per_unit
        within = todo & (bound <= tolerance)
        out[within] = bound[within]
        todo &= ~within
    rows = np.flatnonzero(todo)
    if not rows.size:
        return out
    # the windows: each stretch's whole windows, then its remainder (three samples or more)
    whole = m[rows] // window
    rest = m[rows] - whole * window
    owner = np.concatenate([np.repeat(rows, whole), rows[rest >= 3]])
    first = np.concatenate([np.repeat(a[rows], whole) + _ranks(whole) * window, (a[rows] + whole * window)[rest >= 3]])
    length = np.concatenate([np.full(int(whole.sum()), window), rest[rest >= 3]]).astype(np.intp)
    total = np.zeros(a.size)
    noise = np.zeros(a.size)
    count = np.bincount(owner, weights=length, minlength=a.size)
    size = int(length.max())
    chunk = max(1, WOBBLE_CHUNK_VALUES // (3 * size))
    j = np.arange(size)
    padded = np.zeros((gyro.shape[0] + 1, 3))  # the rates, then a zero row: a window's samples past its end
    padded[:-1] = gyro
    for c0 in range(0, owner.size, chunk):
        f, n = first[c0:c0 + chunk], length[c0:c0 + chunk]
        # the samples along the first axis (sample, window, axis): a sum over a window's samples adds whole rows of
        # windows × axes in the samples' order, the same sums as a window at a time, without a call per sample
        idx = np.minimum(f[None, :] + j[:, None], gyro.shape[0] - 1)
        inside = j[:, None] < n[None, :]
        pair = inside[1:] & inside[:-1]
        # two scratch arrays of (size, windows, 3), every step in place (the expressions in the comments)
        w = np.take(padded, np.where(inside, idx, gyro.shape[0]), axis=0)  # w = where(inside, gyro[idx], 0)
        tt = np.take(t, idx)
        dt = np.where(pair, np.diff(tt, axis=0), 0.0)
        # the gyro's own white noise, from its sample-to-sample differences (var(Δω) = 2σ² for white noise; a
        # tremor of a few hertz hardly changes from one sample to the next): integrated, a random walk whose
        # mean square about its mean over a window of T, the mean rate removed (a Brownian bridge), is σ² dt T / 12
        d = np.diff(w, axis=0)  # d = where(pair, diff(w), 0): past a window's end w is 0, so only its last step
        short = np.flatnonzero(n < size)
        d[n[short] - 1, short] = 0.0
        k = (n - 1.0)[:, None]
        d_sum = d.sum(axis=0)
        d2_sum = np.multiply(d, d, out=d).sum(axis=0)
        white = np.sum(d2_sum / k - (d_sum / k) ** 2, axis=1) / 2.0
        mean = w.sum(axis=0) / n[:, None]
        # angle = cumsum((0.5 (w[1:] + w[:-1]) − mean) dt), 0 past the window's end (and at its first sample)
        angle = np.add(w[1:], w[:-1], out=d)
        angle *= 0.5
        angle -= mean
        angle *= dt[..., None]
        np.cumsum(angle, axis=0, out=angle)
        np.copyto(angle, 0.0, where=~pair[..., None])
        # the angle's squares about its mean over the window's samples: Σ A² − (Σ A)² / n
        angle_sum = angle.sum(axis=0)
        spread2 = np.sum(np.multiply(angle, angle, out=angle).sum(axis=0) - angle_sum ** 2 / n[:, None], axis=1)
        span = tt[n - 1, np.arange(n.size)] - tt[0]
        owners = owner[c0:c0 + chunk]
        total += np.bincount(owners, weights=spread2, minlength=a.size)
        noise += np.bincount(owners, weights=n * white * (span / (n - 1.0)) * span / 12.0, minlength=a.size)
    r2 = rad_per_unit * rad_per_unit  # the rates' unit to rad/s: the angles scale by it
    total, noise = total[rows] * r2, noise[rows] * r2
    n_all = np.maximum(count[rows], 1.0)
    # the gyro's own random walk not below the tolerance: it cannot tell a wobble (the accelerometer's tests do)
    resolved = noise <= RESOLVED_WOBBLE_SHARE**2 * 2.0 * WOBBLE_SHRINK * n_all
    out[rows] = np.where(resolved, np.sqrt(np.maximum(total - noise, 0.0) / n_all), 0.0)
    return out


def _span_sums(x: NDArray[np.float64], a: NDArray[np.intp], z: NDArray[np.intp], centre: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The sums of ``x − centre`` (n, 3) and of its squares over each span ``[a[i], z[i])`` (spans in order, not
    overlapping, none empty), by one pass over the samples, column by column through one buffer of a column's length
    (the same sums as of the (n, 3) differences: on a 12-hour log two temporaries of 100 MB and their page faults
    were 0.2 s)."""
    edges = np.column_stack([a, z]).ravel()
    if edges.size and edges[-1] == x.shape[0]:
        edges = edges[:-1]  # the last span runs to the end: reduceat's last sum does
    if not (edges.size and bool(np.all(np.diff(edges) >= 0))):
        d = x - centre
        s1 = np.array([d[i:j].sum(axis=0) for i, j in zip(a, z)]).reshape(-1, x.shape[1])
        s2 = np.array([np.square(d[i:j]).sum(axis=0) for i, j in zip(a, z)]).reshape(-1, x.shape[1])
        return s1, s2
    s1 = np.empty((edges.size, x.shape[1]))
    s2 = np.empty((edges.size, x.shape[1]))
    buffer = np.empty(x.shape[0])
    for j in range(x.shape[1]):
        np.subtract(x[:, j], centre[j], out=buffer)
        s1[:, j] = np.add.reduceat(buffer, edges)
        s2[:, j] = np.add.reduceat(np.multiply(buffer, buffer, out=buffer), edges)
    return s1[0::2], s2[0::2]


def _block_span_sums(x: NDArray[np.float64], blocks: rm.Blocks, a: NDArray[np.intp], z: NDArray[np.intp],
                     centre: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_span_sums` of the gyro's rates ``x`` (n, 3) over each span ``[a[i], z[i])`` (none empty), from the rest
    model's blocks of the same samples: the blocks wholly inside a span by their moments, ``Σ (x − c) = n (x̄ − c)``
    and ``Σ (x − c)² = (n − 1) s² + n (x̄ − c)²`` (O(blocks)), the samples of the part-blocks at its two ends by
    themselves (fewer than two blocks' worth).  The second sums are at least the samples' (``blocks.gvar`` carries
    the rounding floor and ``q²/12`` of :func:`~optcal.data.rest_model.make_blocks`, and is clipped at 0), up to the
    rounding of the two ways of summing (:func:`_spread_margin`)."""
    assert blocks.gmean is not None and blocks.gvar is not None
    k0 = np.searchsorted(blocks.start, a)  # the first block starting at or after a
    k1 = np.searchsorted(blocks.stop, z, side="right")  # the blocks before k1 end at or before z
    whole = k1 > k0
    s1 = np.zeros((a.size, x.shape[1]))
    s2 = np.zeros((a.size, x.shape[1]))
    if whole.any():
        # every block's two sums (O(blocks)), then each span's by reduceat over its blocks' edges when the spans
        # come in order (as the rest model's stretches do), else over their blocks gathered
        first, stop = k0[whole], k1[whole]
        edges = np.column_stack([first, stop]).ravel()
        ordered = bool(np.all(np.diff(edges) >= 0))
        rows = None if ordered else rm.Ranges.of(first, stop)
        n = blocks.n[:, None] if rows is None else blocks.n[rows.rows, None]
        d = np.subtract(blocks.gmean if rows is None else blocks.gmean[rows.rows], centre)
        b1 = n * d
        b2 = np.multiply(b1, d, out=d)
        b2 += (n - 1.0) * (blocks.gvar if rows is None else blocks.gvar[rows.rows])
        if rows is not None:
            s1[whole], s2[whole] = rows.sums(b1), rows.sums(b2)
        else:
            if edges[-1] == blocks.count:
                edges = edges[:-1]  # the last span runs to the last block: reduceat's last sum does
            s1[whole] = np.add.reduceat(b1, edges, axis=0)[0::2]
            s2[whole] = np.add.reduceat(b2, edges, axis=0)[0::2]
    # the samples outside the whole blocks: a span's head and tail, or all of a span that holds no whole block
    head_stop = np.where(whole, blocks.start[np.minimum(k0, blocks.count - 1)], z)
    tail_start = np.where(whole, blocks.stop[np.maximum(k1 - 1, 0)], z)
    lo = np.concatenate([a, tail_start])
    hi = np.concatenate([np.maximum(head_stop, a), z])
    owner = np.concatenate([np.arange(a.size), np.arange(a.size)])
    keep = hi > lo
    if keep.any():
        e = rm.Ranges.of(lo[keep], hi[keep])
        d = x[e.rows] - centre
        np.add.at(s1, owner[keep], e.sums(d))
        np.add.at(s2, owner[keep], e.sums(d * d))
    return s1, s2


#: Units in the last place, per sample of a stretch, by which its rate spread² summed sample by sample and block by
#: block (:func:`_block_span_sums`) may differ: a sequential sum of ``k`` terms errs by at most ``k`` ulps of its
#: magnitude; each way sums at most ``2m`` terms (the samples, then the blocks) into ``s2/m`` and into ``s1/m``, whose
#: square is at most ``s2/m``; two ways, two terms, ``2m`` each: 8.
SPREAD_ROUNDING_ULPS: float = 8.0


def _spread_margin(mean_square: NDArray[np.float64], m: NDArray[np.intp]) -> NDArray[np.float64]:
    """What the spread² ``Σ_axes (s2/m − (s1/m)²)`` of a stretch of ``m`` samples may lose to rounding, of its
    mean squares ``s2/m`` (k, 3) about the centre (:data:`SPREAD_ROUNDING_ULPS`; ten more terms for the divisions and
    the subtraction): added to the blocks' spread² it stays above the samples' as computed, so a bound that clears a
    stretch by the blocks clears it by the samples too (10⁻⁸ of it on a 12-hour, 100 Hz stretch)."""
    eps = float(np.finfo(float).eps)
    return np.asarray(SPREAD_ROUNDING_ULPS * eps * (np.maximum(m, 1) + 10.0) * mean_square.sum(axis=1))


def _ranks(counts: NDArray[np.intp]) -> NDArray[np.intp]:
    """0, 1, …, ``counts[i]`` − 1 for each ``i``, concatenated."""
    total = int(counts.sum())
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    return np.asarray(np.arange(total) - starts, dtype=np.intp)


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


#: Fewest batches of the end piece's length in the rest of its pose for the piece's shift to be told from the
#: rest's own wander (:func:`touches`): the scatter of fewer means is no measure of it.
MIN_TOUCH_BATCHES: int = 3


def touches(groups: list[list[tuple[int, int]]], kept: list[tuple[int, int, int, int]], model: RestModel
            ) -> tuple[list[list[tuple[int, int]]], list[tuple[int, int]]]:
    """The groups less the end pieces that are a hand's touch next to a move, and those pieces.

    A pose joined from pieces (:func:`join_twitches`) whose last piece, after a twitch, leads into a move (or whose
    first, before a twitch, follows one) may be the sensor held as it is about to be moved, or still settling from
    the move: shifted from the rest by a fraction of a milli-g, well within the samples' spread (so joined), yet
    by many of the pose mean's standard errors.  Such a piece is left out when both

    * its mean is off the rest's by more than means of its length wander within the rest (the scatter of the rest's
      consecutive batches of as many blocks, at least :data:`MIN_TOUCH_BATCHES` of them: a flicker noise's wander
      is measured, not assumed; the χ²₃ of the difference over that scatter at the detector's false-alarm rate), and
    * keeping it would make the pose's mean worse: its pull on the joined mean, ``(n_e / N)² |d|²``, more than what
      it saves of the rest's variance, ``(n_e / N) σ²_rest`` (the larger of the rest's batch scatter over its
      batches and its blocks' noise).

    A piece inside a pose, or at the recording's ends, is not next to a move; nor one as long as the rest.
    """
    b = model.b
    blocks = {(a, z): (j0, j1) for a, z, j0, j1 in kept}
    out: list[list[tuple[int, int]]] = []
    dropped: list[tuple[int, int]] = []
    tiny = np.finfo(float).tiny
    for i, group in enumerate(groups):
        group = list(group)
        for end, moved in ((-1, i + 1 < len(groups)), (0, i > 0)):
            if len(group) < 2 or not moved:
                continue
            j0, j1 = blocks[group[end]]
            rest = np.concatenate([np.arange(*blocks[p]) for p in (group[:-1] if end == -1 else group[1:])])
            length = j1 - j0
            batches = rest.size // length
            if batches < MIN_TOUCH_BATCHES:
                continue
            piece, _, n_piece = _piece_mean(model, j0, j1)
            w = b.n[rest, None]
            n_rest = float(w.sum())
            rest_mean = (b.mean[rest] * w).sum(axis=0) / n_rest
            used = rest[: batches * length]
            sums = np.add.reduceat(b.mean[used] * b.n[used, None], np.arange(0, used.size, length), axis=0)
            counts = np.add.reduceat(b.n[used], np.arange(0, used.size, length))
            wander = (sums / counts[:, None]).var(axis=0, ddof=1)  # of a mean of the piece's length
            d = piece - rest_mean
            shifted = float(np.sum(d * d / np.maximum(wander * (1.0 + 1.0 / batches), tiny))) \
                > rm.chi2_limit(model.s.false_alarm, 3) * model.s.threshold
            white = model.kappa2 * (column_medians(b.var[rest]) / n_rest + model.floor)
            rest_var = np.maximum(wander / batches, white)
            share = n_piece / (n_piece + n_rest)
            if shifted and share * float(np.sum(d * d)) > float(np.sum(rest_var)):
                dropped.append(group.pop(end))
        out.append(group)
    return out, dropped


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


def group_positions(group: list[tuple[int, int]]) -> slice | NDArray[np.int64]:
    """The sample positions of a group of stretches ``[a, b)``: a slice for one stretch (no index array)."""
    if len(group) == 1:
        return slice(int(group[0][0]), int(group[0][1]))
    return np.concatenate([np.arange(a, b) for a, b in group])
