"""The rest corpus with a real MEMS gyro's effects (issue 36): g-sensitivity, bias steps after knocks, a thermal
drift and the Earth's rate, written as a logger writes it (plain or unit-named columns, host-stamp bursts) and read
back through optcal's reader (optcal/families/simulate/rest_corpus.py: RealGyro, render_read, real_corpus)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from optcal.families.simulate.rest_corpus import (
    BIAS_STEP_DPS,
    EARTH_RATE_RAD_S,
    G_SENSITIVITY_DPS_PER_G,
    REAL_VARIANTS,
    THERMAL_DRIFT_DPS,
    real_corpus,
    render,
    render_read,
    score_detector,
    simulate_kind,
)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_the_real_gyro_effects_are_drawn_in_their_stated_ranges(seed) -> None:
    sim = simulate_kind("turntable", seed, real=True)
    ideal = simulate_kind("turntable", seed)
    real = sim.real_gyro
    assert real is not None and ideal.real_gyro is None
    # the same motion and noise as the ideal case: only the gyro's effects differ
    assert np.array_equal(sim.specific_force, ideal.specific_force) and np.array_equal(sim.gyro_noise, ideal.gyro_noise)
    level = np.degrees(np.abs(real.g_sensitivity).max())
    assert level <= G_SENSITIVITY_DPS_PER_G[1]
    steps = np.degrees(np.linalg.norm(real.steps, axis=1))
    assert 1 <= steps.size and np.all((steps >= BIAS_STEP_DPS[0] - 1e-12) & (steps <= BIAS_STEP_DPS[1] + 1e-12))
    drift = np.degrees(np.linalg.norm(real.drift))
    assert THERMAL_DRIFT_DPS[0] - 1e-12 <= drift <= THERMAL_DRIFT_DPS[1] + 1e-12
    # in a rest after the last step and the warm-up, the gyro reads G f, the steps, the drift and the Earth's rate
    a, b = sim.motion.rests[-1]
    f = sim.specific_force[a:b].mean(axis=0)
    expected = real.g_sensitivity @ f + real.steps.sum(axis=0)
    err = sim.gyro_effects[a:b].mean(axis=0) - expected  # type: ignore[index]
    t = np.arange(a, b) / sim.rate_hz
    warm = np.mean(1.0 - np.exp(-t / real.tau_s))
    assert np.linalg.norm(err - warm * real.drift) <= EARTH_RATE_RAD_S * 1.0001


@pytest.mark.parametrize("variant", REAL_VARIANTS)
def test_a_variant_written_and_read_back_is_the_same_recording(variant) -> None:
    """Plain names, counts and bursty host stamps are read back to the samples written: the reader decides the
    units (m/s² or counts) and spreads the bursts over the stamped span at the rate they imply."""
    gyro, quantised, plain, bursts = variant
    sim = simulate_kind("hand_held", 4, real=True)
    direct = render(sim, gyro, quantised).recording
    read = render_read(sim, gyro, quantised, plain, bursts).recording
    assert read.n == direct.n
    assert np.allclose(read.acc, direct.acc, rtol=1e-12, atol=1e-9)
    assert (read.gyro is None) == (not gyro)
    if gyro:
        assert np.allclose(read.gyro, direct.gyro, rtol=1e-12, atol=1e-12)  # type: ignore[arg-type]
    assert read.rate_hz == pytest.approx(sim.rate_hz, rel=0.01)
    assert read.units == direct.units


def test_real_corpus_figures_and_the_gyro_free_recall() -> None:
    """The detector on the real-gyro corpus (seeds 0-1), per kind and variant, printed for the study; without the
    gyro every resting kind keeps its rests (the reading of plain names and bursts is right), and with it, its
    g-sensitivity, steps, drift and the Earth's rate, nine in ten or more where its scale is known (a bias fitted as a
    real gyro's; before it, 0.53-0.99 by kind and variant on seeds 0-2), with at most one false rest."""
    rows = []
    for (gyro, quantised, plain, bursts), case in real_corpus(range(2), ("hand_held", "turntable", "holds_only")):
        score = score_detector(case)
        rows.append({"kind": case.kind, "gyro": gyro, "counts": quantised, "plain": plain, "bursts": bursts,
                     "rests": score.eligible, "recalled": score.recalled, "false": score.false})
    table = pd.DataFrame(rows).groupby(["kind", "gyro", "counts", "plain", "bursts"]).sum(numeric_only=True)
    table["recall"] = table["recalled"] / table["rests"]
    print("\n" + table.to_string())
    no_gyro = table.xs(False, level="gyro")
    assert (no_gyro["recall"] >= 0.95).all(), no_gyro
    assert int(no_gyro["false"].sum()) == 0
    # a gyro whose scale is stated or measured on the moves: nine in ten or more
    scaled = table.drop(index=[k for k in table.index if k[2] and k[3]])
    assert (scaled["recall"] >= 0.9).all(), table
    # counts under plain names, where no move measures the scale (a table turning about the vertical, a logger that
    # stores only holds): the bias of the ideal gyro, as before; measured 0.69-1.00 by kind on these seeds
    assert (table["recall"] >= 0.65).all(), table
    assert int(table["false"].sum()) <= 1
