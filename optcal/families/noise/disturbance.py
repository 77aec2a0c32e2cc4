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

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.families.noise.allan import AllanCurve, overlapping_adev, phase_from_rate

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


def _stretches(at_rest: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Starts and (exclusive) ends of the runs not at rest."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (~at_rest).astype(np.int8), [0]])))
    return edges[0::2], edges[1::2]


def patched(x: NDArray[np.float64], at_rest: NDArray[np.bool_], rate_hz: float,
            spans: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None) -> NDArray[np.float64]:
    """``x`` (n,) with each stretch not at rest replaced as the module docstring says.

    Parameters
    ----------
    x : ndarray, shape (n,)
    at_rest : ndarray of bool, shape (n,)
    rate_hz : float
    spans : (starts, ends), optional
        The stretches replaced (default: those not at rest; a placebo's are at rest).
    """
    n = x.size
    c = np.array(x, dtype=float)
    if not at_rest.any():
        return c
    a, b = _stretches(at_rest) if spans is None else spans
    if not a.size:
        return c
    at_rest = at_rest.copy()
    for i, j in zip(a.tolist(), b.tolist()):
        at_rest[i:j] = False  # a placebo's span is not its own reference
    w = np.maximum(b - a, int(np.ceil(REFERENCE_S * rate_hz)))
    cs = np.concatenate([[0.0], np.cumsum(np.where(at_rest, x, 0.0))])
    cn = np.concatenate([[0], np.cumsum(at_rest)])
    lo, hi = np.maximum(a - w, 0), np.minimum(b + w, n)
    count = cn[hi] - cn[lo]  # the stretch itself adds nothing: none of its samples is at rest
    level = np.where(count == 0, float(np.mean(x[at_rest])), (cs[hi] - cs[lo]) / np.maximum(count, 1))
    for i, j, r in zip(a.tolist(), b.tolist(), level.tolist()):
        k = j - i
        for s0 in (i - k, j):  # the rest just before, else just after, of the stretch's length
            if s0 >= 0 and s0 + k <= n and bool(at_rest[s0:s0 + k].all()):
                src = x[s0:s0 + k]
                c[i:j] = src - np.mean(src) + r
                break
        else:  # no rest of that length beside it: its level (without noise; said by a larger change)
            c[i:j] = r
    return c


def _ratios(series: NDArray[np.float64], rate_hz: float, ms: NDArray[np.intp], adev: NDArray[np.float64],
            half: NDArray[np.float64]) -> NDArray[np.float64]:
    """``|σ(τ) − adev| / half`` of one axis's ``series`` at the cluster lengths ``ms``."""
    value, _ = overlapping_adev(phase_from_rate(series, rate_hz), rate_hz, ms)
    return np.asarray(np.abs(value - adev) / half)


def disturbance_change(x: NDArray[np.float64], at_rest: NDArray[np.bool_], rate_hz: float,
                       curves: list[AllanCurve]) -> DisturbanceChange:
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
    """
    x = np.asarray(x, dtype=float).reshape(at_rest.size, -1)
    ms = [np.rint(c.taus * rate_hz).astype(np.intp) for c in curves]
    half = [np.maximum((c.ci_high - c.ci_low) / 2.0, np.finfo(float).tiny) for c in curves]
    ratios = [_ratios(patched(x[:, j], at_rest, rate_hz), rate_hz, ms[j], c.adev, half[j]) for j, c in enumerate(curves)]
    j = int(np.argmax([r.max() for r in ratios]))
    i = int(np.argmax(ratios[j]))
    c = curves[j]
    placebos = np.empty(0)
    if ratios[j][i] > RELEVANT_SHARE:
        placebos = np.array([max(float(_ratios(patched(x[:, k], at_rest, rate_hz, spans), rate_hz, ms[k], cv.adev,
                                                  half[k]).max()) for k, cv in enumerate(curves))
                             for spans in placebo_spans(at_rest)])
    return DisturbanceChange(j, float(c.taus[i]), float(ratios[j][i] * half[j][i]), float(c.adev[i]), float(half[j][i]),
                             placebos)


def placebo_spans(at_rest: NDArray[np.bool_]) -> list[tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """:data:`PLACEBOS` sets of spans at rest, each stretch not at rest moved to a random place whose span and the
    span before it are at rest (seed 0: the same answer on every run); none where the rest has no room (then the
    change is judged by :data:`RELEVANT_SHARE` alone)."""
    a, b = _stretches(at_rest)
    k = b - a
    rest = np.concatenate([[0], np.cumsum(at_rest)])
    rng = np.random.default_rng(0)
    rooms = []
    for length in k.tolist():
        room = np.flatnonzero(rest[2 * length:] - rest[:rest.size - 2 * length] == 2 * length)  # [p, p + 2k) at rest
        if not room.size:
            return []
        rooms.append(room + length)
    out = []
    for _ in range(PLACEBOS):
        p = np.array([int(rng.choice(room)) for room in rooms], dtype=np.intp)
        out.append((p, p + k))
    return out
