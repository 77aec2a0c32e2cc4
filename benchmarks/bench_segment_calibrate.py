"""Benchmark: a 10⁶-sample raw CSV segmented and calibrated end to end in ≤ 5 s.

Run on demand (not part of the default test run)::

    /work/venv/bin/pytest benchmarks/bench_segment_calibrate.py --benchmark-only

The recording is MPU-6050-like: int16 counts (16,300-16,700 counts/g, 60 counts noise),
400 poses of 20 s with 5 s rotations between them at 100 Hz (999,500 samples, 2 h 47 min),
gyro and temperature columns: 7 numeric columns, 61 MB of CSV.  Two measurements: the
library call ``calibrate(load(path))`` in a warm process, and the command
``optcal calibrate FILE --json`` as a new process (Python start-up and imports included).
"""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from optcal.data import load
from optcal.families.simulate.recording import synthesize_recording
from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import uniform_directions

BUDGET_S = 5.0


@pytest.fixture(scope="module")
def million_sample_csv(tmp_path_factory):
    model = LumpedModel.from_physical([16300, 16400, 16700], 0.01, -0.005, 0.008, [700, -360, -1800])
    syn = synthesize_recording(model, uniform_directions(400, rng=1), dwell_s=20.0, transition_s=5.0, sigma=60.0,
                               quantum=1.0, units="counts", rng=2, temperature=(25.0, 0.001))
    path = tmp_path_factory.mktemp("bench") / "million.csv"
    syn.to_csv(str(path), float_format="%.6f")
    return path, syn


def segment_and_calibrate(path):
    from optcal.families.accel.calibration import calibrate

    poses = load(path)
    return poses, calibrate(poses)


def test_million_sample_csv_end_to_end(benchmark, million_sample_csv):
    path, syn = million_sample_csv
    assert syn.n_samples >= 999_000
    poses, result = benchmark.pedantic(segment_and_calibrate, args=(path,), rounds=3, iterations=1, warmup_rounds=1)
    assert poses.n == len(syn.dwells)
    assert result.rms_norm_residual_g < 1e-3
    assert benchmark.stats.stats.max <= BUDGET_S, f"slowest run {benchmark.stats.stats.max:.2f} s > {BUDGET_S} s"


def test_million_sample_csv_command_line(million_sample_csv):
    path, syn = million_sample_csv
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "optcal.cli.main", "calibrate", str(path), "--json"],
                          capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - start
    assert done.returncode == 0, done.stderr
    print(f"optcal calibrate on {syn.n_samples} samples: {elapsed:.2f} s (new process)")
    assert elapsed <= BUDGET_S
