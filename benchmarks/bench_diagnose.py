"""Benchmark: ``diagnose`` on 120 poses with 200 simulations, and ``optcal demo`` end to end.

Run on demand (not part of the default test run)::

    /work/venv/bin/pytest benchmarks/bench_diagnose.py --benchmark-only

Targets: the diagnosis of 120 poses (baseline, 200-fold parametric bootstrap of the baseline and of
the extended model, forward selection with 10-fold held-out errors) well under 10 s in a warm
process; ``optcal demo`` (a 100 Hz recording of 28,600 samples built, segmented, diagnosed and told)
well under a minute on 2 cores, as a new process.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from diagnosis_cases import make_case  # noqa: E402

from optcal.diagnosis import diagnose  # noqa: E402

DIAGNOSE_BUDGET_S = 10.0
DEMO_BUDGET_S = 60.0


def test_diagnose_120_poses(benchmark: pytest.FixtureRequest) -> None:
    case = make_case("temperature_bias", 3, n_range=(120, 120))
    diagnose(case.poses, simulations=5)  # build the CasADi problems for n = 120 once
    result = benchmark.pedantic(lambda: diagnose(case.poses, simulations=200), rounds=3, iterations=1)
    assert [f.effect for f in result.findings] == ["temperature_bias"]
    assert benchmark.stats.stats.max < DIAGNOSE_BUDGET_S


def test_demo_as_a_new_process(benchmark: pytest.FixtureRequest) -> None:
    exe = str(Path(sys.executable).with_name("optcal"))

    def run() -> float:
        t0 = time.perf_counter()
        subprocess.run([exe, "demo", "--seed", "1"], check=True, capture_output=True)
        return time.perf_counter() - t0

    seconds = benchmark.pedantic(run, rounds=2, iterations=1)
    assert seconds < DEMO_BUDGET_S
