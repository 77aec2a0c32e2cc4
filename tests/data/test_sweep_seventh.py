"""The seventh strangers' sweep (docs/rest-model.md, "Strangers' recordings, seventh sweep"): layouts public loggers
wrote that optcal misread, each reproduced on a GENERATED file (no recording is committed).

* A MATLAB matrix of a 9-axis logger with its time first (ZhangPeike/IMU_Calibration's ``caldata.mat``: one
  variable ``cal_data``, 41308 × 10, ``t ax ay az gx gy gz mx my mz`` in s and counts): refused before as "no
  accelerometer matrix (a numeric matrix of 3, 4, 6 or 7 columns or rows)", naming no flag; now read in the layout
  a headerless text file of 10 columns has (the magnetometer's axes said not read), and a matrix of an axis count
  no layout has is refused naming the ``--topic NAME:rows --columns ...`` that reads it.
* MicroStrain's MSCL channel names with a prefix joined by case (NCSU-High-Powered-Rocketry-Club/AirbrakesV2's
  3DM-CX5 logs: ``state,extension,timestamp,invalid_fields,scaledAccelX,...,scaledGyroZ,...,estCompensatedAccelX,...``,
  the IMU's packets and the filter's interleaved, each row leaving the other's fields empty): refused before as "no
  accelerometer column(s)"; now ``scaledAccelX`` is read as ``ax`` by its end, its case boundaries as separators, and
  the filter's rows counted as excluded.

Each test fails on the code before this sweep.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.io import savemat

from helpers.cli_run import run_args as run
from helpers.recordings import turned_recording
from optcal.data import load_with_segmentation

#: The counts of the ZhangPeike file's sensor (an MPU-9250 at ±16 g and ±2000 °/s: 2048 counts per g, 16.4 per °/s).
ACC_COUNTS_PER_G = 2048.0
GYRO_COUNTS_PER_DPS = 16.4


@pytest.fixture(scope="module")
def turned():
    """8 poses in g at 100 Hz with a gyro in rad/s (the simulator's)."""
    return turned_recording(8, 3, 4)


def _nine_axis_matrix(turned, extra: int = 0) -> np.ndarray:
    """``t ax ay az gx gy gz mx my mz`` in s and counts, one sample per row, and ``extra`` constant columns after."""
    f = turned.frame
    acc = np.round(f[["ax", "ay", "az"]].to_numpy() * ACC_COUNTS_PER_G)
    gyro = np.round(np.degrees(f[["gx", "gy", "gz"]].to_numpy()) * GYRO_COUNTS_PER_DPS) + np.array([-9.0, -4.0, -17.0])
    mag = np.tile([-101.0, 34.0, -122.0], (len(acc), 1))
    cols = [f["t"].to_numpy()[:, None], acc, gyro, mag]
    if extra:
        cols.append(np.zeros((len(acc), extra)))
    return np.hstack(cols)


def test_a_nine_axis_matrix_with_its_time_first_is_read_as_a_headerless_file_would_be(turned, tmp_path):
    path = tmp_path / "caldata.mat"
    savemat(path, {"cal_data": _nine_axis_matrix(turned)})
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 0.5
    assert loaded.recording.units == "counts"
    columns = loaded.decisions.columns.value
    assert "ax←cal_data(:,2)" in columns and "gz←cal_data(:,7)" in columns and "cal_data(:,8)" not in columns
    assert "axes 8-10 not read: a 9-axis logger's magnetometer" in loaded.decisions.columns.reason
    np.testing.assert_allclose(loaded.recording.acc[:, 2], np.round(turned.frame["az"].to_numpy() * ACC_COUNTS_PER_G))


def test_a_matrix_of_another_axis_count_is_refused_naming_the_flags_that_read_it(turned, tmp_path, capsys):
    path = tmp_path / "wide.mat"
    savemat(path, {"cal_data": _nine_axis_matrix(turned, extra=2)})  # 12 axes: no layout
    code, out, err = run(capsys, "segment", str(path))
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, err
    assert "cal_data (" in lines[0] and "--topic cal_data:rows --columns ax=N,ay=N,az=N" in lines[0]
    loaded = load_with_segmentation(path, topic="cal_data:rows", columns="t=1,ax=2,ay=3,az=4,gx=5,gy=6,gz=7")
    assert loaded.poses.n == len(turned.dwells)


def test_mscl_channel_names_with_a_prefix_joined_by_case_are_read_by_their_end(turned, tmp_path):
    f = turned.frame
    stamps = 1730147660435860599 + np.round(f["t"].to_numpy() * 1e9).astype(np.int64)
    header = ("state,extension,timestamp,invalid_fields,scaledAccelX,scaledAccelY,scaledAccelZ,scaledGyroX,scaledGyroY,"
              "scaledGyroZ,deltaVelX,deltaVelY,deltaVelZ,estCompensatedAccelX,estCompensatedAccelY,"
              "estCompensatedAccelZ,estAngularRateX,estAngularRateY,estAngularRateZ\n")
    rows = []
    for k, (s, a, w) in enumerate(zip(stamps, f[["ax", "ay", "az"]].to_numpy(), f[["gx", "gy", "gz"]].to_numpy())):
        rows.append(f"S,-0.5,{s},," + ",".join(f"{v:.8f}" for v in (*a, *w, *(a / 1000.0))) + ",,,,,,\n")
        if k % 2 == 0:  # the estimation filter's packet between the IMU's: its own fields, the IMU's empty
            rows.append(f"S,-0.5,{s + 500},,,,,,,,,,," + ",".join(f"{v:.8f}" for v in (*(9.80665 * a), *w)) + "\n")
    path = tmp_path / "xplus.csv"
    path.write_text(header + "".join(rows))
    loaded = load_with_segmentation(path)
    columns = loaded.decisions.columns.value
    assert "ax←scaledAccelX" in columns and "gz←scaledGyroZ" in columns and "estCompensated" not in columns
    assert loaded.poses.n == len(turned.dwells)
    assert loaded.recording.units == "g"
    assert loaded.recording.n_usable == len(f)  # the IMU's rows all read
    assert sum(loaded.recording.exclusions.values()) == len(rows) - len(f)  # the filter's excluded and counted
