"""A logger that repeats the magnetometer's value until its next update (AlexMinhao/MagnetometerCali's ``M1.csv``:
an AK8963 at about 22 Hz in a 111-Hz log, each triple on 5 rows): before, every row was kept, each update weighed
five times, and a row holding axes of two updates (a torn copy) was a sample.  Now the runs are told from a sensor's own repeated codes by their lengths
(:mod:`optcal.data.held_samples`), one row per update is kept, the repeats are counted and said, and
``--keep-mag-repeats`` keeps every row."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, lfilter

from optcal.data.held_samples import held_runs
from optcal.families.mag.samples import HELD_ROWS, TORN_ROWS, read_mag

#: AK8963's 16-bit step, µT.
STEP_UT = 0.15


def _turning_field(t: np.ndarray) -> np.ndarray:
    """A 45-µT field seen by a sensor tumbling about a wandering axis, a hard iron of (10, -5, 3) µT."""
    az, el = 0.7 * t, 0.9 * np.sin(0.23 * t)
    return 45.0 * np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]) + [10.0, -5.0, 3.0]


def test_a_magnetometer_held_over_a_faster_logs_rows_is_read_once_per_update(tmp_path):
    rng = np.random.default_rng(4)
    log_hz, mag_hz, seconds = 111.0, 22.0, 40.0
    t_mag = np.arange(int(seconds * mag_hz)) / mag_hz
    m = np.round((_turning_field(t_mag) + rng.normal(0, 0.3, (t_mag.size, 3))) / STEP_UT) * STEP_UT
    t_row = np.arange(int(seconds * log_hz)) / log_hz
    update = np.searchsorted(t_mag, t_row, side="right") - 1  # the last update at or before each row
    rows = np.column_stack([t_row, m[update]])
    # ten torn copies, as M1.csv's: the row before an update already holds its y, x and z still the old update's
    changes = np.flatnonzero(np.diff(update)) + 1
    torn = changes[10:110:10] - 1
    torn = torn[rows[torn, 2] != rows[torn + 1, 2]]  # y changes there (else the row is a plain repeat)
    assert torn.size >= 8
    rows[torn, 2] = rows[torn + 1, 2]
    path = tmp_path / "held.csv"
    np.savetxt(path, rows, delimiter=",", header="t,mag_x_uT,mag_y_uT,mag_z_uT", comments="", fmt="%.6f")
    samples = read_mag(path)
    assert samples.n == np.unique(update).size and samples.exclusions[TORN_ROWS] == torn.size
    assert samples.exclusions[HELD_ROWS] == rows.shape[0] - samples.n - torn.size
    assert np.allclose(samples.m, m[np.unique(update)])
    assert any("repeats each value until its next update" in n and "--keep-mag-repeats" in n for n in samples.notes)
    kept = read_mag(path, keep_repeats=True)
    assert kept.n == rows.shape[0] and HELD_ROWS not in kept.exclusions
    assert any("every row kept (--keep-mag-repeats)" in n for n in kept.notes)


@pytest.mark.parametrize("noise_steps", [0.15, 0.3, 1.0], ids=["still, noise 0.15 step", "0.3 step", "1 step"])
def test_a_still_coarse_magnetometer_read_every_row_is_no_hold(noise_steps):
    """The control: a magnetometer read afresh every row repeats its whole triple often when it is still and its
    noise is below its step, but in runs that fall off geometrically (more of one row than of any other length)."""
    rng = np.random.default_rng(5)
    m = np.round(([20.0, -3.0, 40.0] + rng.normal(0, noise_steps * STEP_UT, (20000, 3))) / STEP_UT) * STEP_UT
    repeats = np.count_nonzero(np.all(m[1:] == m[:-1], axis=1))
    assert repeats > 0 and held_runs(m) is None


def test_a_filtered_oversampled_magnetometer_read_every_row_keeps_its_rows(tmp_path):
    """A still magnetometer read afresh every row behind a low-pass of a twenty-fifth of the log's rate, its noise a
    fifth of its 0.3-µT step: its codes repeat in runs too long to be geometric, so the runs test alone (HOLD_Z)
    called them a hold of two rows (z = 4.0 for this log) and kept 1,086 of its 20,000 rows; their lengths spread
    far from two rows (RATIO_SHARE), so every row is a sample (the rule the accelerometer's reader has)."""
    step = 0.3
    b, a = butter(2, 0.04)  # cut-off at 0.02 of the log's rate
    noise = lfilter(b, a, np.random.default_rng(20).standard_normal((22000, 3)), axis=0)[2000:]
    noise /= noise.std(axis=0)
    m = np.round(([21.3, -8.2, 44.6] + 0.2 * step * noise) / step) * step
    assert np.count_nonzero(np.all(m[1:] == m[:-1], axis=1)) > 10000  # a still, coarse sensor repeats its codes
    path = tmp_path / "filtered.csv"
    np.savetxt(path, np.column_stack([np.arange(m.shape[0]) / 100.0, m]), delimiter=",",
               header="t,mag_x_uT,mag_y_uT,mag_z_uT", comments="", fmt="%.6f")
    samples = read_mag(path)
    assert samples.n == m.shape[0] and HELD_ROWS not in samples.exclusions and TORN_ROWS not in samples.exclusions
    assert not any("repeats each value" in n for n in samples.notes)
