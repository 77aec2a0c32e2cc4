"""Runtime target of the Allan analysis (run on demand: ``pytest benchmarks/bench_allan.py``).

* Allan deviation of a 12 h, 100 Hz static log (4.32 million samples, three axes): overlapping
  estimator on octave τ, allantools confidence intervals and the noise-parameter fit — ≤ 10 s.
"""

from __future__ import annotations

import numpy as np
import pytest

from optcal.families.noise.allan import simulate_noise
from optcal.families.noise.analysis import analyse_static_log

RATE = 100.0
N_SAMPLES = int(12 * 3600 * RATE)


@pytest.fixture(scope="module")
def twelve_hour_log() -> np.ndarray:
    rng = np.random.default_rng(0)
    return np.column_stack([simulate_noise(N_SAMPLES, RATE, 200e-6, 100e-6, 10e-6, rng) for _ in range(3)])


def test_allan_of_a_12_h_100_hz_three_axis_log_within_10_s(benchmark, twelve_hour_log: np.ndarray) -> None:
    analysis = benchmark.pedantic(analyse_static_log, args=(twelve_hour_log, RATE, "g"), rounds=3, iterations=1)
    assert analysis.n_samples == N_SAMPLES
    assert benchmark.stats.stats.max <= 10.0
