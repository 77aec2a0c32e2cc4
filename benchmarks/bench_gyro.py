"""Calibration time on imu_tk's own Xsens recording against imu_tk (run on demand: ``pytest benchmarks/bench_gyro.py``).

The issue's target: the whole-IMU calibration takes less time than imu_tk's.  The comparison is
made in the same run when imu_tk can be run here: ``OPTCAL_IMUTK_CMD`` holds the command that
runs imu_tk's ``test_imu_calib`` on the recording (e.g. ``"/opt/imu_tk/bin/test_imu_calib
xsens_acc.mat xsens_gyro.mat"``), timed as a subprocess.  Otherwise the figure of
``IMUTK_REFERENCE.md`` (whole process 0.30-0.38 s on this machine, 2026-11-23) is the baseline,
and the benchmark records both and asserts only with ``OPTCAL_BENCH_STRICT=1``.  Each round's CPU
time (``time.process_time``) is recorded next to the wall time (``extra_info["cpu_seconds"]``):
on a loaded shared machine the wall time measures the other jobs as much as optcal.

* ``test_imu_calibration_xsens`` — optcal's whole process (read the CSV, detect the still
  intervals, accelerometer ML fit, gyro fit) as ``calibrate_imu`` does it.
* ``test_gyro_fit_only_xsens`` — the gyro part alone (moves, integrator build, IPOPT), data read once.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from optcal.gyro.estimator import GyroSettings, calibrate_gyro, calibrate_imu

XSENS = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "imutk-xsens" / "xsens_imutk.csv"
#: imu_tk's whole process on this machine (IMUTK_REFERENCE.md), seconds: the upper end of 0.30-0.38 s.
IMUTK_REFERENCE_S: float = 0.38


def imutk_seconds() -> tuple[float, str]:
    """imu_tk's time, measured now (``OPTCAL_IMUTK_CMD``, median of 5) or from IMUTK_REFERENCE.md."""
    cmd = os.environ.get("OPTCAL_IMUTK_CMD")
    if not cmd:
        return IMUTK_REFERENCE_S, "IMUTK_REFERENCE.md (0.30-0.38 s whole process)"
    times = []
    for _ in range(5):
        start = time.perf_counter()
        subprocess.run(shlex.split(cmd), check=True, capture_output=True)
        times.append(time.perf_counter() - start)
    return sorted(times)[2], f"measured now: {cmd}"


@pytest.fixture(scope="module")
def xsens() -> Path:
    if not XSENS.exists():
        pytest.skip("../shared/data/imutk-xsens is not present")
    return XSENS


def cpu_timed(function: Callable[..., Any], cpu_seconds: list[float]) -> Callable[..., Any]:
    """``function``, appending the CPU time of each call to ``cpu_seconds``."""
    def timed(*args: Any) -> Any:
        start = time.process_time()
        try:
            return function(*args)
        finally:
            cpu_seconds.append(time.process_time() - start)
    return timed


def _compare(benchmark, seconds: float, cpu_seconds: list[float]) -> None:
    baseline, source = imutk_seconds()
    cpu = float(np.median(cpu_seconds))
    benchmark.extra_info.update({"imutk_seconds": baseline, "imutk_source": source, "ratio_to_imutk": seconds / baseline,
                                 "cpu_seconds": cpu, "cpu_ratio_to_imutk": cpu / baseline})
    if os.environ.get("OPTCAL_BENCH_STRICT"):
        assert seconds <= baseline


def test_imu_calibration_xsens(benchmark, xsens: Path) -> None:
    cpu: list[float] = []
    cal = benchmark.pedantic(cpu_timed(calibrate_imu, cpu), args=(str(xsens),), rounds=5, iterations=1, warmup_rounds=1)
    assert cal.rms_angle_after_deg <= 0.517
    _compare(benchmark, benchmark.stats.stats.median, cpu[1:])


def test_gyro_fit_only_xsens(benchmark, xsens: Path) -> None:
    import optcal
    from optcal.data import load_with_segmentation
    from optcal.gyro.moves import moves_from_segmentation
    from optcal.gyro.units import GyroUnitsDecision

    loaded = load_with_segmentation(str(xsens))
    moves = moves_from_segmentation(loaded.segmentation)
    acc = optcal.calibrate(loaded.poses)
    cpu: list[float] = []
    cal = benchmark.pedantic(cpu_timed(calibrate_gyro, cpu), args=(moves, acc, GyroUnitsDecision("counts", "file"), GyroSettings()),
                             rounds=5, iterations=1, warmup_rounds=1)
    assert cal.rms_angle_after_deg <= 0.517
    _compare(benchmark, benchmark.stats.stats.median, cpu[1:])
