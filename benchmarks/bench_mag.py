"""Runtime target of the magnetometer's calibration (run on demand: ``pytest benchmarks/bench_mag.py``).

* 10⁶ raw samples of a distorted field (hard and soft iron, 0.5 % noise): read from memory,
  the forms chosen by evidence (the full form: convex then ML), the dip with an accelerometer — ≤ 10 s.
  The baseline in the same run: numpy's least-squares sphere fit of the same samples (one
  linear solve), printed beside it.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from optcal.families.mag.calibration import calibrate_mag
from optcal.families.mag.fit import _sphere_fit
from optcal.families.mag.samples import MagSamples
from optcal.families.mag.units import decide_mag_units

N_SAMPLES = 1_000_000


@pytest.fixture(scope="module")
def samples() -> MagSamples:
    rng = np.random.default_rng(0)
    up = rng.normal(size=(N_SAMPLES, 3))
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    # a field dipping 60° in the world frame, seen in each orientation: build m with m·up = −sin 60°
    side = np.cross(up, rng.normal(size=(N_SAMPLES, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    field = -np.sin(np.radians(60)) * up + np.cos(np.radians(60)) * side
    S = np.array([[48.0, 1.0, -0.5], [1.0, 45.0, 0.8], [-0.5, 0.8, 52.0]])
    m = field @ S.T + [10.0, -20.0, 5.0] + rng.normal(scale=0.25, size=(N_SAMPLES, 3))
    return MagSamples(m=m, units=decide_mag_units(m, "uT", "the benchmark"), acc=up * 9.81)


def test_mag_calibration_of_10_6_samples_within_10_s(benchmark, samples: MagSamples) -> None:
    t0 = time.perf_counter()
    _sphere_fit(samples.m)
    baseline = time.perf_counter() - t0
    result = benchmark.pedantic(calibrate_mag, args=(samples,), rounds=1, iterations=1)
    print(f"\nmagnetometer, 10^6 samples: {benchmark.stats.stats.max:.2f} s; numpy sphere fit (baseline) {baseline:.2f} s")
    assert result.fit.fit.form == "full"
    assert result.dip is not None and result.dip.dip_deg == pytest.approx(60.0, abs=0.5)
    assert benchmark.stats.stats.max <= 10.0
