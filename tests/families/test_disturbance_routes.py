"""The two routes of the disturbance check (:mod:`optcal.families.noise.disturbance`, ``optcal allan``'s moves): a
log whose samples not at rest are many (a slow tilt the rest model flags, a turn and back, knocks) takes the route
that sums the changed samples' neighbourhoods from slices of the phase, instead of sorting and searching six points
per changed sample and τ (the route that ran unbounded on a 12-hour log with moves); its ratios equal the full
recomputation's and the piece route's.  A generated 5-minute, two-axis log at 100 Hz (seconds)."""

from __future__ import annotations

import numpy as np
import pytest

import optcal.families.noise.disturbance as disturbance
from optcal.data.static_stretches import true_runs
from optcal.families.noise.allan import allan_deviation, overlapping_adev, phase_from_rate

RATE = 100.0


def moving_log(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two axes of white noise (σ 1) with a slow tilt (30 s: the level drifts by 8 σ and stays), a turn and back
    (3 s of a 20 σ bump) and three knocks (0.25 s of 5 σ), flagged not at rest, and a last stretch at the log's end."""
    rng = np.random.default_rng(seed)
    n = int(300 * RATE)
    x = rng.normal(0.0, 1.0, (n, 2))
    at_rest = np.ones(n, dtype=bool)
    tilt = slice(8000, 11000)
    x[tilt] += np.linspace(0.0, 8.0, 3000)[:, None]
    x[11000:] += 8.0
    x[20000:20300] += 20.0 * np.sin(np.linspace(0, np.pi, 300))[:, None]
    for i0 in (2000, 24000, 27000):
        x[i0:i0 + 25] += 5.0
        at_rest[i0:i0 + 25] = False
    at_rest[tilt] = at_rest[20000:20300] = at_rest[-40:] = False
    return x, at_rest


def full_ratio(x: np.ndarray, at_rest: np.ndarray, spans, curves) -> float:
    """The largest |σ_patched(τ) − σ(τ)| / half-interval over the axes, the patched series' Allan deviation computed
    in full (the module's definition, no shortcut)."""
    worst = 0.0
    for j, c in enumerate(curves):
        y = np.array(x[:, j])
        positions, added = disturbance.patch_values(y, at_rest, RATE, spans)
        y[positions] += added
        full, _ = overlapping_adev(phase_from_rate(y, RATE), RATE, np.rint(c.taus * RATE).astype(int))
        worst = max(worst, float(np.max(np.abs(full - c.adev) / ((c.ci_high - c.ci_low) / 2.0))))
    return worst


def counted(monkeypatch: pytest.MonkeyPatch, name: str) -> list[int]:
    calls = [0]
    original = getattr(disturbance, name)

    def wrapped(*args, **kwargs):
        calls[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(disturbance, name, wrapped)
    return calls


def test_many_samples_not_at_rest_take_the_dense_route_and_give_the_full_recomputations_ratios(monkeypatch) -> None:
    x, at_rest = moving_log()
    curves = [allan_deviation(x[:, j], RATE) for j in range(2)]
    pieces, dense = counted(monkeypatch, "_pieces"), counted(monkeypatch, "_dense_cuts")
    found = disturbance.disturbance_change(x, at_rest, RATE, curves)
    assert pieces[0] == 0 and dense[0] == 2 * (1 + disturbance.PLACEBOS)  # every patch of both axes, densely
    assert found.relevant and found.placebo_ratios.size == disturbance.PLACEBOS

    moved = true_runs(~at_rest)
    assert found.ratio == pytest.approx(full_ratio(x, at_rest, moved, curves), rel=1e-9)
    draws = disturbance.placebo_spans(at_rest, moved)
    for got, spans in zip(found.placebo_ratios, draws):
        assert got == pytest.approx(full_ratio(x, at_rest, spans, curves), rel=1e-7)

    monkeypatch.setattr(disturbance, "dense_route", lambda *args: False)  # the piece route: the same figures
    slow = disturbance.disturbance_change(x, at_rest, RATE, curves)
    assert pieces[0] == 2 * (1 + disturbance.PLACEBOS) and dense[0] == 2 * (1 + disturbance.PLACEBOS)
    assert (slow.axis, slow.tau) == (found.axis, found.tau)
    assert slow.ratio == pytest.approx(found.ratio, rel=1e-9)
    # the piece route reads a patch's changed samples as sorted and distinct, which patch_values now gives for a
    # draw whose stretches overlap too (it read 844 where the full recomputation gives 1.6): every draw agrees
    disjoint = np.array([_disjoint(spans) for spans in draws])
    assert 5 <= disjoint.sum() < disjoint.size
    np.testing.assert_allclose(slow.placebo_ratios, found.placebo_ratios, rtol=1e-6)


def _disjoint(spans) -> bool:
    a, b = spans
    order = np.argsort(a)
    return bool(np.all(a[order][1:] >= b[order][:-1]))


def test_a_few_samples_not_at_rest_stay_on_the_piece_route() -> None:
    """A still log's knocks (the 12-hour still log has 151 samples not at rest): the piece route, whose cost is theirs."""
    n_phase = int(12 * 3600 * RATE) + 1
    few = [(np.arange(151), np.zeros(151))]
    many = [(np.arange(370_000), np.zeros(370_000))] * (1 + disturbance.PLACEBOS)
    assert not disturbance.dense_route(few, 22, n_phase)
    assert disturbance.dense_route(many, 22, n_phase)


def test_the_placebos_rooms_from_the_runs_at_rest_equal_a_pass_over_the_log() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        n = int(rng.integers(1, 400))
        rest = rng.random(n) < rng.random()
        sums = np.concatenate([[0], np.cumsum(rest)])
        starts, ends = true_runs(rest)
        for length in range(1, min(30, n + 1)):
            by_pass = np.flatnonzero(sums[length:] - sums[:sums.size - length] == length)  # [p, p + length) at rest
            np.testing.assert_array_equal(disturbance._room(starts, ends, length), by_pass)
