"""The time offset under a lever arm written into a real recording independently of the estimator (issue 39, gyro11).

The lever arm is planted exactly: a rigid body's point at ``r`` from the centre it turns about reads
``f = g + α × r + ω × (ω × r)``, with ``ω`` and ``α`` from a cubic spline of the calibrated rates low-passed at 5 Hz
(zero phase), not from the estimator's 0.1 s running mean.  A 0.3 m lever arm on mikoff's imu0 moved the offset 13.6 -> 18.8 ms, and its standard error 1.9 -> 5.0 ms:
the lever arm's part the estimator's regressor does not follow scatters the moves' offsets, and the t test measures
that scatter.  Fitting the specific force itself (``f − û = δ u̇ + a/g``, exact and linear in ``r``) instead of its
direction moved it by +3.2 ± 3.2 ms too, and the estimator's smoothing span 0.05 / 0.1 / 0.2 s by −0.5 / +5.1 / +4.1
ms (each about one planted SE or less): the shift is the regressor's noise, not the direction's linearisation.  What
holds, and is tested: the planted offset agrees with the unplanted one within two of its stated standard errors,
which grow with the lever arm.  About 7 CPU s (two diagnoses of imu0, the gyro's part only).

The planted offset's own t still passes its family-wise level (3.8 against 3.25), but its correction does not carry
to the moves it was not fitted to: their paired gain is within its standard error (0.025 ± 0.032°, t 0.77), so it is
not named, and the report says so with those figures.  Before the held-out rule asked for a gain beyond its
standard error, the held-out rms ratio 1.0044 > 1 named it.  Unplanted, imu0's offset gains 0.044 ± 0.013° (t 3.3).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfiltfilt

from helpers.common import SHARED
from test_gyro_diagnosis_files import MIKOFF, MIKOFF_COLUMNS, run_diagnose

STANDARD_GRAVITY = 9.80665
#: The lever arm (m): a hand turning the board about its wrist, 0.3 m off the sensor.
LEVER_M = 0.3 * np.array([0.6, 0.8, 0.0])
#: The plant's low-pass (Hz): passes a hand's turn, whose power is below a few Hz.
LOWPASS_HZ = 5.0
#: Two standard errors: a 95 % two-sided agreement of the planted and unplanted offsets under the estimate's own
#: stated error (the unplanted's, 1.9 ms, is a third of the planted's and is left out of the sum).
AGREEMENT_SE = 2.0


def plant_lever(raw: pd.DataFrame, r: np.ndarray) -> pd.DataFrame:
    """The accelerometer columns plus ``α × r + ω × (ω × r)`` (raw units), ω and α from a spline of the low-passed rates."""
    from optcal.data import load_with_segmentation
    from optcal.families.gyro.estimator import GyroSettings, calibrate_imu_loaded

    imu = calibrate_imu_loaded(load_with_segmentation(MIKOFF, rate=100.0), settings=GyroSettings())
    T, b, acc_cal = np.asarray(imu.gyro.T), np.asarray(imu.gyro.bias), imu.accelerometer
    t = np.arange(len(raw)) / 100.0
    rates = (raw[MIKOFF_COLUMNS[3:]].to_numpy(float) - b) @ T.T
    # the body's motion: the rates through a zero-phase 4th-order low-pass at 5 Hz (a hand's turn is below a few
    # Hz; the gyro's white noise is not motion), α the derivative of their cubic spline
    smooth = sosfiltfilt(butter(4, LOWPASS_HZ, fs=100.0, output="sos"), rates, axis=0)
    spline = CubicSpline(t, smooth, axis=0)
    omega, alpha = spline(t), spline.derivative()(t)
    extra_g = (np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))) / STANDARD_GRAVITY
    per_raw = (acc_cal.correct(np.eye(3)) - acc_cal.correct(np.zeros((1, 3)))).T  # g per raw unit (linear part)
    out = raw.copy()
    out[MIKOFF_COLUMNS[:3]] = raw[MIKOFF_COLUMNS[:3]].to_numpy(float) + np.linalg.solve(per_raw, extra_g.T).T
    return out


def test_lever_arm_planted_by_spline_leaves_the_offset_within_its_error(tmp_path: Path, capsys) -> None:
    if not MIKOFF.exists():
        pytest.skip("../shared/data/mikoff-mpu9150 is not present")
    raw = pd.read_csv(MIKOFF, sep=r"\s+", header=None, names=MIKOFF_COLUMNS)
    own = run_diagnose(MIKOFF, "--rate", "100", capsys=capsys)["gyroscope"]["time_offset"]
    path = tmp_path / "imu0_lever.log"
    np.savetxt(path, plant_lever(raw, LEVER_M).to_numpy(float), fmt="%.5f")
    planted = run_diagnose(path, "--rate", "100", capsys=capsys)["gyroscope"]["time_offset"]
    assert own["tested"] and planted["tested"]
    assert planted["se_s"] > own["se_s"]  # the lever arm's unfollowed part is scatter, and the error says so
    assert abs(planted["dt_s"] - own["dt_s"]) < AGREEMENT_SE * planted["se_s"]
    # named only when its held-out gain is beyond its own noise: imu0's is, the lever arm's scatter's is not,
    # though the planted estimate's t passes
    assert abs(planted["t"]) > planted["critical_t"] and planted["heldout_ratio"] > 1.0
    assert not planted["significant"] and planted["heldout_gain_deg"] < planted["heldout_se_deg"]
    assert own["significant"] and own["heldout_gain_deg"] > own["heldout_moves_critical_t"] * own["heldout_se_deg"]
