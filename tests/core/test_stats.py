"""The shared summary statistics of :mod:`optcal.core.stats`."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from optcal.core.stats import sorted_unique


def test_sorted_unique_is_numpys_unique_without_numpy_ma():
    """``np.unique``'s values for integer arrays (empty, one value, all equal, repeats, negatives, 2-D), and the
    disturbance check of a still log that uses it imports no ``numpy.ma`` (numpy 2's ``unique`` does)."""
    rng = np.random.default_rng(5)
    cases = [np.empty(0, dtype=np.intp), np.array([7]), np.full(9, 3), rng.integers(-50, 50, 1000),
             rng.integers(0, 4, (20, 5)), np.arange(10)[::-1]]
    for x in cases:
        got = sorted_unique(x)
        assert got.dtype == np.unique(x).dtype and np.array_equal(got, np.unique(x))
    probe = ("import sys, numpy as np; from optcal.families.noise.disturbance import disturbance_change; "
             "from optcal.families.noise.allan import allan_deviation; x = np.random.default_rng(0).normal(size=(4000, 1)); "
             "x[1000:1010] += 5.0; rest = np.ones(4000, bool); rest[1000:1010] = False; "
             "c = allan_deviation(x[:, 0], 100.0); disturbance_change(x, rest, 100.0, [c]); print('numpy.ma' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def test_row_reductions_column_by_column_are_numpys_bit_for_bit():
    """row_norms, row_max_abs and column_ptp against numpy's row and column reductions: values over 600 decades
    (squares that overflow and underflow), NaN, infinities, signed zeros and subnormals, 1 to 8 columns (8: numpy's
    own norm, whose sums are no longer in order)."""
    from optcal.core.stats import column_ptp, row_max_abs, row_norms

    rng = np.random.default_rng(3)
    for m in range(1, 9):
        x = rng.normal(size=(3000, m)) * 10.0 ** rng.uniform(-300, 300, size=(3000, m))
        x[::97] = np.nan
        x[5::89, 0] = np.inf
        x[7::83] = -0.0
        x[9::71, -1] = 1e-310
        with np.errstate(over="ignore"):
            assert np.array_equal(row_norms(x), np.linalg.norm(x, axis=1), equal_nan=True), m
        centre = rng.normal(size=m)
        assert np.array_equal(row_max_abs(x, centre), np.max(np.abs(x - centre), axis=1), equal_nan=True), m
        finite = x[np.isfinite(x).all(axis=1)]
        assert np.array_equal(column_ptp(finite), np.ptp(finite, axis=0)), m
        assert np.array_equal(column_ptp(x), np.ptp(x, axis=0), equal_nan=True), m


def test_mean_and_se_is_students_and_the_weighted_form():
    """Equal weights: the mean and sd/√k (Student's one-sample form); weights: Σwd/Σw and the scatter-measured
    error of a weighted mean, k/(k−1) Σ w²(d − d̄)² over (Σw)² (the time offset's per-move combination); one value
    has no scatter, none gives NaN."""
    from optcal.core.stats import mean_and_se

    rng = np.random.default_rng(4)
    d = rng.normal(0.3, 1.0, 17)
    mean, se = mean_and_se(d)
    assert mean == pytest.approx(np.mean(d)) and se == pytest.approx(np.std(d, ddof=1) / np.sqrt(d.size))
    w = rng.uniform(0.1, 3.0, d.size)
    mean, se = mean_and_se(d, w)
    centre = np.sum(w * d) / np.sum(w)
    assert mean == pytest.approx(centre)
    assert se == pytest.approx(np.sqrt(np.sum(w**2 * (d - centre) ** 2) / np.sum(w) ** 2 * d.size / (d.size - 1)))
    assert mean_and_se([2.0]) == (2.0, 0.0) and all(np.isnan(mean_and_se([])))
