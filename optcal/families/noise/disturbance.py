"""How much the samples of a still log that are not at rest move its Allan deviation.

A still log is one rest; a move inside it (a turn and back, a knock, a hand on the bench) puts samples into the
series that are not the sensor's noise.  The Allan deviation needs an uninterrupted series, so those samples cannot
be dropped; whether they matter is measured instead.  Each stretch that is not at rest is replaced by the at-rest
samples just before it (after it when the log starts with it), shifted to the level of the rest around it: the
series the sensor would have given had it not been disturbed, with its noise (a replacement by a constant would
remove noise and move σ(τ) by itself).  The Allan deviation of that patched series is compared with the log's at
every τ, and the change with the result's own uncertainty (its confidence interval): a disturbance is relevant
where it moves σ(τ) by more than :data:`RELEVANT_SHARE` of that interval's half-width.  At long τ, where a
cluster holds few samples more than the stretch, replacing even samples at rest by other samples at rest moves σ(τ)
that much (the noise is reshuffled): so the change must also exceed what the same replacement does at
:data:`PLACEBOS` places of the log's rest chosen at random (the placebo's null, one-sided level ``1/(PLACEBOS+1)``),
or it is the noise's own and the stretch is kept.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.stats import sorted_unique
from optcal.data.static_stretches import true_runs
from optcal.families.noise.allan import AllanCurve

#: Share of σ(τ)'s own one-sigma interval (half its width) that the stretches not at rest may move it by: a change
#: inside the curve's one-sigma interval is one the log itself could not tell from its noise (nor could a repeat of
#: the log); beyond it the curve measures the disturbance.
RELEVANT_SHARE: float = 1.0
#: The rest around a stretch that sets its replacement's level: the at-rest samples within this many seconds on
#: either side (at least the stretch's own length): local, so a slow drift of the bias is not counted as the
#: disturbance.
REFERENCE_S: float = 1.0
#: Placebo replacements (the module docstring): 19 gives the one-sided 5 % level of a change larger than all.
PLACEBOS: int = 19


@dataclass(frozen=True)
class DisturbanceChange:
    """What :func:`disturbance_change` found over the axes of a sensor.

    Attributes
    ----------
    axis : int
        The axis (column) where ``change / half_width`` is largest.
    tau : float
        The τ where it is, s.
    change : float
        ``|σ(τ) − σ_patched(τ)|`` there, the curve's units.
    adev, half_width : float
        σ(τ) there and half the width of its confidence interval.
    placebo_ratios : ndarray
        The same largest ratio over axes and τ for each placebo replacement (empty: not drawn, the change within
        :data:`RELEVANT_SHARE`).
    """

    axis: int
    tau: float
    change: float
    adev: float
    half_width: float
    placebo_ratios: NDArray[np.float64]

    @property
    def ratio(self) -> float:
        """The largest ``change / half_width`` over the axes and τ."""
        return self.change / self.half_width

    @property
    def relevant(self) -> bool:
        """True where the stretches move σ(τ) by more than :data:`RELEVANT_SHARE` of its uncertainty and by more
        than every placebo replacement of samples at rest did (largest over axes and τ both: one family)."""
        return self.ratio > RELEVANT_SHARE and bool(np.all(self.ratio > self.placebo_ratios))


def patch_values(x: NDArray[np.float64], at_rest: NDArray[np.bool_], rate_hz: float,
                 spans: tuple[NDArray[np.intp], NDArray[np.intp]]) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """The samples of ``x`` (n,) that the replacement of the module docstring changes and what it adds to each:
    ``(positions, d)`` sorted and distinct, ``x[positions] + d`` the replaced values (where a placebo's stretches
    overlap, the later stretch's value, as :func:`patched` writes it; the piece route's running sums need distinct
    steps: with repeated ones a placebo's ratio read 844 where the full recomputation gives 1.6).

    Parameters
    ----------
    x : ndarray, shape (n,)
    at_rest : ndarray of bool, shape (n,)
    rate_hz : float
    spans : (starts, ends)
        The stretches replaced: those not at rest, or a placebo's (at rest, then not their own reference).
    """
    n = x.size
    none = (np.empty(0, dtype=np.intp), np.empty(0))
    a, b = spans
    if not a.size or not at_rest.any():
        return none
    reference = at_rest.copy()
    for i, j in zip(a.tolist(), b.tolist()):
        reference[i:j] = False  # a span is never its own reference (the stretches not at rest are not at rest)
    at_rest = reference
    w = np.maximum(b - a, int(np.ceil(REFERENCE_S * rate_hz)))
    lo, hi = np.maximum(a - w, 0), np.minimum(b + w, n)
    level = np.empty(a.size)
    for k, (i, j) in enumerate(zip(lo.tolist(), hi.tolist())):  # the stretch itself adds nothing: not at rest
        near = at_rest[i:j]
        level[k] = float(np.mean(x[i:j][near])) if near.any() else float("nan")
    if np.isnan(level).any():  # no rest within reach: the log's rest as a whole
        level[np.isnan(level)] = float(np.mean(x[at_rest]))
    order = np.argsort(a)
    positions, added = [], []
    for i, j, r in zip(a[order].tolist(), b[order].tolist(), level[order].tolist()):
        k = j - i
        new = np.full(k, r)  # no rest of that length beside it: its level (without noise; said by a larger change)
        for s0 in (i - k, j):  # the rest just before, else just after, of the stretch's length
            if s0 >= 0 and s0 + k <= n and bool(at_rest[s0:s0 + k].all()):
                src = x[s0:s0 + k]
                new = src - np.mean(src) + r
                break
        positions.append(np.arange(i, j))
        added.append(new - x[i:j])
    pos, add = np.concatenate(positions), np.concatenate(added)
    if pos.size > 1 and not bool(np.all(pos[1:] > pos[:-1])):  # a placebo's stretches, placed apart, may overlap
        order = np.argsort(pos, kind="stable")
        pos, add = pos[order], add[order]
        last = np.concatenate([pos[1:] != pos[:-1], [True]])  # patched()'s meaning: the last value written
        pos, add = pos[last], add[last]
    return pos, add


def patched(x: NDArray[np.float64], at_rest: NDArray[np.bool_], rate_hz: float,
            spans: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None) -> NDArray[np.float64]:
    """``x`` (n,) with each stretch replaced as the module docstring says (:func:`patch_values`; a copy)."""
    c = np.array(x, dtype=float)
    positions, added = patch_values(c, at_rest, rate_hz, true_runs(~at_rest) if spans is None else spans)
    c[positions] += added
    return c


def _pieces(change: tuple[NDArray[np.intp], NDArray[np.float64]], rate_hz: float, ms: NDArray[np.intp],
            n_phase: int) -> list[tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]]:
    """For each cluster length of ``ms``, the pieces ``[p, q)`` of second differences that the patch ``change``
    (positions, added values: :func:`patch_values`) shifts and the shift ``ΔD`` of each (see :func:`_ratios`)."""
    positions, added = change
    steps = positions + 1  # R steps up at phase index p + 1
    running = np.concatenate([[0.0], np.cumsum(added) / rate_hz])

    def r(t: NDArray[np.intp]) -> NDArray[np.float64]:
        return running[np.searchsorted(steps, t, side="right")]

    out = []
    for m in ms.tolist():
        n = n_phase - 2 * m
        cuts = sorted_unique(np.clip(np.concatenate([steps - 2 * m, steps - m, steps, [0, n]]), 0, n))
        p, q = cuts[:-1], cuts[1:]
        delta = r(p + 2 * m) - 2.0 * r(p + m) + r(p)
        live = delta != 0.0
        out.append((p[live], q[live], delta[live]))
    return out


def _points(pieces: list[tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]],
            ms: NDArray[np.intp]) -> NDArray[np.intp]:
    """The phase's running-sum indices the span sums of ``pieces`` read (:func:`_ratios`), sorted, each once."""
    ends = [np.concatenate([p, q]) for p, q, _ in pieces]
    return sorted_unique(np.concatenate([np.empty(0, dtype=np.intp)]
                                    + [e + shift * m for e, m in zip(ends, ms.tolist()) for shift in (0, 1, 2)]))


def _ratios(pieces: list[tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]],
            prefix: tuple[NDArray[np.intp], NDArray[np.float64]], rate_hz: float, n_phase: int, ms: NDArray[np.intp],
            adev: NDArray[np.float64], half: NDArray[np.float64],
            varying: list[float] | None = None) -> NDArray[np.float64]:
    """``|σ_patched(τ) − adev| / half`` at the cluster lengths ``ms``, the series patched as ``pieces`` say
    (:func:`_pieces`), without a copy of the log.

    The patch adds to the phase a step function ``R`` (phase index ``t`` sums the samples before ``t``; the mean each
    phase removes adds a straight line, which a second difference cancels), so each second difference
    ``D(u) = x_{u+2m} − 2 x_{u+m} + x_u`` (Riley, NIST SP 1065, eq. 11) gains ``ΔD(u) = R(u+2m) − 2R(u+m) + R(u)``,
    constant between the changed samples' places shifted by 0, m and 2m and zero away from them.  On each such piece
    ``Σ (D + ΔD)² − Σ D² = 2 ΔD Σ D + ΔD² · length``, and ``Σ D`` over a piece is three differences of the running
    sum of the phase, ``prefix`` (its indices and values there: :func:`phase_prefix_at`): the cost is the changed
    samples', not the log's.  ``varying``: per cluster length, ``Σ (2 D + ΔD) ΔD`` already summed where ``ΔD`` is
    not constant between the pieces (the dense route, :func:`_dense_pieces`); none for :func:`_pieces`' pieces."""
    points, values = prefix

    def at(t: NDArray[np.intp]) -> NDArray[np.float64]:
        return values[np.searchsorted(points, t)]

    out = np.empty(ms.size)
    for k, (m, (p, q, delta)) in enumerate(zip(ms.tolist(), pieces)):
        n = n_phase - 2 * m
        total = _log_sum(float(adev[k]), m, n, rate_hz)
        if varying is not None:
            total += varying[k]
        span = (at(q + 2 * m) - at(p + 2 * m)) - 2.0 * (at(q + m) - at(p + m)) + (at(q) - at(p))  # Σ D on [p, q)
        total += float(np.sum(2.0 * delta * span + delta * delta * (q - p)))
        out[k] = _ratio(total, n, m, rate_hz, adev[k], half[k])
    return out


def _log_sum(adev: float, m: int, n: int, rate_hz: float) -> float:
    """The log's own ``Σ D²`` at cluster length ``m`` (overlapping_adev's σ inverted)."""
    return (adev * m / rate_hz) ** 2 * 2.0 * n


def _ratio(total: float, n: int, m: int, rate_hz: float, adev: float, half: float) -> float:
    """``|σ_patched − adev| / half`` from the patched series' ``Σ D²`` over its ``n`` second differences at cluster
    length ``m`` (overlapping_adev's σ, NIST SP 1065 eq. 11)."""
    return abs(float(np.sqrt(max(total, 0.0) / (2.0 * n))) / m * rate_hz - adev) / half


def _runs(positions: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The runs of consecutive values of the sorted, distinct ``positions``: ``(starts, ends)``, ends exclusive."""
    if not positions.size:
        return np.empty(0, dtype=np.intp), np.empty(0, dtype=np.intp)
    cut = np.flatnonzero(np.diff(positions) != 1) + 1
    return positions[np.concatenate([[0], cut])], positions[np.concatenate([cut - 1, [positions.size - 1]])] + 1


def _merged(starts: NDArray[np.intp], ends: NDArray[np.intp], n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The intervals ``[starts, ends)`` clipped to ``[0, n)`` and merged where they overlap or touch, sorted."""
    a, b = np.clip(starts, 0, n), np.clip(ends, 0, n)
    keep = b > a
    a, b = a[keep], b[keep]
    if not a.size:
        return a, b
    order = np.argsort(a, kind="stable")
    a, b = a[order], np.maximum.accumulate(b[order])
    new = np.concatenate([[True], a[1:] > b[:-1]])
    first = np.flatnonzero(new)
    return a[first], b[np.concatenate([first[1:] - 1, [a.size - 1]])]


@dataclass(frozen=True)
class _DenseCut:
    """One patch at one cluster length for :func:`_dense_pieces`: the gaps ``[p, q)`` between the ``u`` where ``ΔD``
    varies, ``ΔD`` on each (``delta``, constant there), and ``Σ (2 D + ΔD) ΔD`` over those ``u`` (``varying``)."""

    p: NDArray[np.intp]
    q: NDArray[np.intp]
    delta: NDArray[np.float64]
    varying: float


#: Second differences worked out at a time by :func:`_dense_cuts` (256 KiB a buffer): its two buffers stay in the
#: processor's cache, where differences of a long stretch not at rest written whole (megabytes each) were written and
#: read again from memory.
DENSE_PIECE: int = 2**15


def _second_difference(x: NDArray[np.float64], i: int, j: int, m: int, out: NDArray[np.float64]
                       ) -> NDArray[np.float64]:
    """``x[u + 2m] − 2 x[u + m] + x[u]`` for ``u`` in ``[i, j)``, into the start of ``out`` (Riley, NIST SP 1065,
    eq. 11's second difference, as ``(x[u + 2m] − x[u + m]) − x[u + m] + x[u]``)."""
    v = out[: j - i]
    np.subtract(x[i + 2 * m:j + 2 * m], x[i + m:j + m], out=v)
    v -= x[i + m:j + m]
    v += x[i:j]
    return v


def _step_function(starts: NDArray[np.intp], ends: NDArray[np.intp], running: NDArray[np.float64],
                   n_phase: int) -> NDArray[np.float64]:
    """``R(t)``, the sum of the added values of the changed samples before ``t`` (``running``: their running sum, in
    the order of the runs ``[starts, ends)``), for ``t = 0 … n_phase − 1``: constant between the runs, so filled there
    and summed only along them (a running sum of the log's length per patch was a third of the dense route's time)."""
    r = np.empty(n_phase)
    level, done, rank = 0.0, 0, 0
    for s, e in zip(starts.tolist(), ends.tolist()):
        r[done:s + 1] = level  # t ≤ s: no changed sample of this run before t
        r[s + 1:e + 1] = running[rank:rank + e - s]
        rank += e - s
        level, done = float(running[rank - 1]), e + 1
    r[done:] = level
    return r


def _dense_cuts(x: NDArray[np.float64], change: tuple[NDArray[np.intp], NDArray[np.float64]], rate_hz: float,
                ms: NDArray[np.intp]) -> list[_DenseCut]:
    """Per cluster length of ``ms``, the patch ``change`` (:func:`patch_values`) split as :func:`_dense_pieces` says.

    ``x`` is the phase (:func:`~optcal.families.noise.allan.phase_from_rate`).  ``R`` is :func:`_pieces`' running sum
    of the added values (to rounding), as an array of the phase's length; ``ΔD(u) = R(u+2m) − 2R(u+m) + R(u)``
    changes from ``u`` to ``u + 1`` only where ``u + km`` (``k = 0, 1, 2``) is a changed sample."""
    n_phase = x.size
    positions, added = change  # sorted and distinct (patch_values)
    starts, ends = _runs(positions)
    r = _step_function(starts, ends, np.cumsum(added) / rate_hz, n_phase)
    d_buffer, dd_buffer = np.empty(DENSE_PIECE), np.empty(DENSE_PIECE)
    out = []
    for m in ms.tolist():
        n = n_phase - 2 * m
        a, b = _merged(np.concatenate([starts - k * m for k in (0, 1, 2)]),
                       np.concatenate([ends - k * m for k in (0, 1, 2)]), n)
        varying = 0.0
        for i0, j0 in zip(a.tolist(), b.tolist()):  # u by u: D and ΔD (Riley, NIST SP 1065, eq. 11)
            for i in range(i0, j0, DENSE_PIECE):
                j = min(j0, i + DENSE_PIECE)
                d, dd = _second_difference(x, i, j, m, d_buffer), _second_difference(r, i, j, m, dd_buffer)
                d *= 2.0
                d += dd
                d *= dd  # (2 D + ΔD) ΔD; not np.dot: its threaded BLAS spun the idle cores 20-fold the work
                varying += float(d.sum())
        p, q = np.concatenate([[0], b]), np.concatenate([a, [n]])
        live = q > p
        p, q = p[live], q[live]
        delta = r[p + 2 * m] - 2.0 * r[p + m] + r[p]  # constant on the gap: no changed sample at u + km there
        live = delta != 0.0
        out.append(_DenseCut(p[live], q[live], delta[live], varying))
    return out


def _dense_pieces(column: NDArray[np.float64], changes: list[tuple[NDArray[np.intp], NDArray[np.float64]]],
                  rate_hz: float, ms: NDArray[np.intp]
                  ) -> tuple[list[list[tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]]], list[list[float]]]:
    """:func:`_pieces` of each patch of ``changes`` (:func:`patch_values`) for patches of many samples, with the part
    of the sum :func:`_ratios` takes from them already summed.

    The same sum ``Σ (D + ΔD)² − Σ D²`` as :func:`_ratios`, split differently.  Where ``ΔD`` changes from one ``u`` to
    the next (``u + km`` a changed sample: every ``u`` of a long stretch not at rest is a piece of its own there) it is
    summed ``u`` by ``u`` from slices of the phase and of ``R`` (the second list, per patch and cluster length).  On
    the gaps between, ``ΔD`` is constant: those are the pieces, whose ``Σ D`` :func:`_ratios` takes from three
    differences of the phase's running sum (:func:`phase_prefix_at`).  The cost is a pass of the log's length per patch
    plus the changed samples' neighbourhoods, against :func:`_pieces`' sort and search of six points per piece; the
    sums agree to rounding (the additions are grouped differently).
    """
    from optcal.families.noise.allan import phase_from_rate

    x = phase_from_rate(column, rate_hz)  # the phase (the log's length: freed on return, before the running sums)
    cuts = [_dense_cuts(x, change, rate_hz, ms) for change in changes]
    return [[(c.p, c.q, c.delta) for c in per] for per in cuts], [[c.varying for c in per] for per in cuts]


#: Samples per piece of :func:`phase_prefix_at`'s running sums: its one temporary (256 KiB) stays in the
#: processor's cache, instead of the phase and its running sum of the log's length (35 MB each for an axis of the
#: 12-hour log) written and read again for a few thousand of their values.
PREFIX_PIECE: int = 2**15


def _prefix_piece(column: NDArray[np.float64], a: int, b: int, mean: float | np.floating[Any], scale: float,
                  body_carry: float, prefix_carry: float, v: NDArray[np.float64]) -> tuple[float, float]:
    """``S[a + 2 … b + 1]`` into ``v`` (``b − a`` values) from the running sums carried into piece ``[a, b)``; the
    sums carried out of it.  The one formula of :func:`phase_prefix_at` and :class:`PhaseCarries`."""
    np.subtract(column[a:b], mean, out=v)  # phase[a + 1 … b] = (Σ_{i ≤ ·} (y_i − ȳ)) / f_s
    v[0] += body_carry
    np.cumsum(v, out=v)
    body_carry = float(v[-1])
    v *= scale
    v[0] += prefix_carry  # S[a + 2 … b + 1] = S[a + 1] + Σ phase
    np.cumsum(v, out=v)
    return body_carry, float(v[-1])


class PhaseCarries:
    """The running sums :func:`phase_prefix_at` carries into each of its pieces, worked out ahead (a few pieces at a
    time, while a core would otherwise wait): given them, :func:`phase_prefix_at` sums only the pieces that hold
    its points, from the same carries, so the same numbers to the bit.

    Parameters
    ----------
    column : ndarray, shape (n,)
        The rate samples of one axis, contiguous (the array :func:`disturbance_change` sums: none is copied here).
    rate_hz : float
    """

    def __init__(self, column: NDArray[np.float64], rate_hz: float) -> None:
        self.column = column
        self.rate_hz = float(rate_hz)
        self.scale = 1.0 / float(rate_hz)  # phase_from_rate's scaling of the summed samples
        self.mean = np.mean(column)
        #: The sums carried into piece k (k = 0 … the pieces worked out so far).
        self.body: list[float] = [0.0]
        self.prefix: list[float] = [0.0]
        self._w = np.empty(min(PREFIX_PIECE, max(column.size, 1)))

    def of(self, column: NDArray[np.float64], rate_hz: float) -> bool:
        """Whether these are the carries of ``column`` (the same memory, not a copy or a cut of it) at ``rate_hz``."""
        return (column.shape == self.column.shape and column.strides == self.column.strides
                and column.__array_interface__["data"][0] == self.column.__array_interface__["data"][0]
                and float(rate_hz) == self.rate_hz)

    @property
    def done(self) -> bool:
        """Whether the carries into every piece are known."""
        return (len(self.body) - 1) * PREFIX_PIECE >= self.column.size

    def advance(self, pieces: int) -> bool:
        """Work out the carries of up to ``pieces`` more pieces; whether all are known."""
        n = self.column.size
        for _ in range(pieces):
            a = (len(self.body) - 1) * PREFIX_PIECE
            if a >= n:
                break
            b = min(n, a + PREFIX_PIECE)
            body, prefix = _prefix_piece(self.column, a, b, self.mean, self.scale, self.body[-1], self.prefix[-1],
                                         self._w[: b - a])
            self.body.append(body)
            self.prefix.append(prefix)
        return self.done


def phase_prefix_at(column: NDArray[np.float64], rate_hz: float, points: NDArray[np.intp],
                    carries: PhaseCarries | None = None) -> NDArray[np.float64]:
    """``S[points]`` for ``S = [0, cumsum(phase)]``, ``phase = phase_from_rate(column, rate_hz)`` (NIST SP 1065's
    phase, :func:`~optcal.families.noise.allan.phase_from_rate`), without an array of the log's length.

    Piece by piece (:data:`PREFIX_PIECE` samples), each running sum carried from the piece before as its first term:
    the same additions in the same order as the two whole-column sums, so the same numbers to the bit.  Where
    ``carries`` (of this ``column``) already holds the sums carried into a piece and out of it, the piece is summed only
    up to its last point, and a piece without points is skipped.

    Parameters
    ----------
    column : ndarray, shape (n,)
        The rate samples of one axis.
    rate_hz : float
    points : ndarray of int
        Sorted indices into ``S`` (``0 … n + 1``).
    carries : PhaseCarries, optional
        The carries of ``column`` worked out ahead (:class:`PhaseCarries`), all or some of them.

    Returns
    -------
    ndarray
        ``S`` at ``points``.
    """
    n = column.size
    out = np.zeros(points.size)  # S[0] = S[1] = 0 (phase[0] = 0)
    mean = np.mean(column) if carries is None else carries.mean
    scale = 1.0 / float(rate_hz)  # phase_from_rate's scaling of the summed samples
    known_body, known_prefix = ([0.0], [0.0]) if carries is None else (carries.body, carries.prefix)
    body_carry = prefix_carry = 0.0
    rows = np.searchsorted(points, np.arange(0, n + PREFIX_PIECE, PREFIX_PIECE) + 2)
    w = np.empty(min(PREFIX_PIECE, max(n, 1)))
    for k, a in enumerate(range(0, n, PREFIX_PIECE)):
        i, j = rows[k], rows[k + 1]
        b = min(n, a + PREFIX_PIECE)
        if k < len(known_body):
            body_carry, prefix_carry = known_body[k], known_prefix[k]
            if k + 1 < len(known_body):  # the next piece's carries known: summed only up to this piece's last point
                if i == j:
                    continue
                b = int(points[j - 1]) - 1  # S[points[j - 1]] is v[points[j - 1] - a - 2], the last value summed
        v = w[: b - a]
        body_carry, prefix_carry = _prefix_piece(column, a, b, mean, scale, body_carry, prefix_carry, v)
        out[i:j] = v[points[i:j] - a - 2]
    return out


#: What :func:`_ratios` spends on one point of its pieces (its place in the sort of all of them, six searches in it),
#: in :func:`_dense_pieces`' cost of one sample of the log per patch: 62-73 ns against 5-7 ns (9-15 times), measured
#: on 1.5 and 4 hours of a 100 Hz log with moves (600 and 1275 samples not at rest).  It picks the cheaper of two
#: routes that agree to rounding, so it sets only the time; the low end of the measured range leans to
#: :func:`_ratios`, the route a still log's few samples not at rest keep (151 in 12 hours: 9 times below the crossing).
PIECE_POINT_COST: float = 8.0


def dense_route(changes: Sequence[tuple[NDArray[np.intp], NDArray[np.float64]]], n_taus: int, n_phase: int) -> bool:
    """Whether :func:`_dense_pieces` is the cheaper route for these patches: :func:`_ratios` reads six points of each
    of up to three pieces per changed sample and cluster length, :func:`_dense_pieces` passes over the log once per
    patch (:data:`PIECE_POINT_COST`).

    Parameters
    ----------
    changes : sequence of (positions, added)
        The patches (:func:`patch_values`), the real one and the placebos'.
    n_taus : int
        The cluster lengths the ratios are wanted at.
    n_phase : int
        The phase's length (the log's samples plus one).

    Returns
    -------
    bool
    """
    points = 18.0 * n_taus * sum(change[0].size for change in changes)
    return points * PIECE_POINT_COST > len(changes) * n_phase


def disturbance_change(x: NDArray[np.float64], at_rest: NDArray[np.bool_], rate_hz: float,
                       curves: list[AllanCurve], carries: Sequence[PhaseCarries | None] = ()) -> DisturbanceChange:
    """How far the stretches not at rest move ``curves``, the Allan deviations of the columns of ``x``.

    Parameters
    ----------
    x : ndarray, shape (n, k)
        The sensor's samples, the curves' units, one column per curve.
    at_rest : ndarray of bool, shape (n,)
        The samples the rest model finds at rest.
    rate_hz : float
    curves : list of AllanCurve
        :func:`optcal.families.noise.allan.allan_deviation` of each column.
    carries : sequence of PhaseCarries or None, optional
        Per column, the running sums of its phase worked out ahead (:class:`PhaseCarries`); used only where they are
        of that very column.
    """
    x = np.asarray(x, dtype=float).reshape(at_rest.size, -1)
    ms = [np.rint(c.taus * rate_hz).astype(np.intp) for c in curves]
    half = [np.maximum((c.ci_high - c.ci_low) / 2.0, np.finfo(float).tiny) for c in curves]
    moved = true_runs(~at_rest)
    n_phase = at_rest.size + 1

    def ratios(j: int, spans_list: list[tuple[NDArray[np.intp], NDArray[np.intp]]]) -> list[NDArray[np.float64]]:
        """The ratios on axis j of each set of spans patched (one pass over the axis for all of them)."""
        column = np.ascontiguousarray(x[:, j])
        carried = carries[j] if j < len(carries) else None
        if carried is not None and not carried.of(column, rate_hz):
            carried = None
        changes = [patch_values(column, at_rest, rate_hz, spans) for spans in spans_list]
        varying: list[list[float] | None]
        if dense_route(changes, ms[j].size, n_phase):
            pieces, dense_sums = _dense_pieces(column, changes, rate_hz, ms[j])
            varying = list(dense_sums)
        else:
            pieces = [_pieces(change, rate_hz, ms[j], n_phase) for change in changes]
            varying = [None] * len(pieces)
        points = sorted_unique(np.concatenate([_points(p, ms[j]) for p in pieces]))
        prefix = (points, phase_prefix_at(column, rate_hz, points, carried))
        return [_ratios(p, prefix, rate_hz, n_phase, ms[j], curves[j].adev, half[j], v) for p, v in zip(pieces, varying)]

    # one thread per axis: each pass is a running sum (numpy, the interpreter released), so the axes share the cores
    with ThreadPoolExecutor(max_workers=len(curves), thread_name_prefix="optcal-moves") as pool:
        real = [r[0] for r in pool.map(lambda k: ratios(k, [moved]), range(len(curves)))]
        j = int(np.argmax([r.max() for r in real]))
        i = int(np.argmax(real[j]))
        placebos = np.empty(0)
        draws = placebo_spans(at_rest, moved) if real[j][i] > RELEVANT_SHARE else []
        if draws:  # only where the share alone would refuse: the null decides
            placebos = np.max([[float(r.max()) for r in rs] for rs in pool.map(lambda k: ratios(k, draws),
                                                                               range(len(curves)))], axis=0)
    c = curves[j]
    return DisturbanceChange(j, float(c.taus[i]), float(real[j][i] * half[j][i]), float(c.adev[i]), float(half[j][i]),
                             placebos)


def placebo_spans(at_rest: NDArray[np.bool_], moved: tuple[NDArray[np.intp], NDArray[np.intp]]
                  ) -> list[tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """:data:`PLACEBOS` sets of spans at rest, each stretch not at rest moved to a random place whose span and the
    span before it are at rest (seed 0: the same answer on every run); none where the rest has no room (then the
    change is judged by :data:`RELEVANT_SHARE` alone).  ``moved``: the stretches not at rest (``true_runs(~at_rest)``)."""
    a, b = moved
    k = b - a
    ra, rb = true_runs(at_rest)
    rng = np.random.default_rng(0)
    rooms = []
    found: dict[int, NDArray[np.intp]] = {}  # stretches of one length share their room
    for length in k.tolist():
        if length not in found:
            found[length] = _room(ra, rb, 2 * length) + length
        if not found[length].size:
            return []
        rooms.append(found[length])
    out = []
    for _ in range(PLACEBOS):
        p = np.array([int(rng.choice(room)) for room in rooms], dtype=np.intp)
        out.append((p, p + k))
    return out


def _room(starts: NDArray[np.intp], ends: NDArray[np.intp], length: int) -> NDArray[np.intp]:
    """The ``p`` with ``[p, p + length)`` inside one of the runs ``[starts, ends)`` (sorted, apart), ascending: built
    from the runs, not by a pass over the log (a pass per distinct length of the stretches not at rest cost 0.1-0.2 s
    each on a 12-hour log)."""
    counts = np.maximum(ends - starts - length + 1, 0)
    total = int(counts.sum())
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.arange(total, dtype=np.intp) + np.repeat(starts - first, counts).astype(np.intp, copy=False)
