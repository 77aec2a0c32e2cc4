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
* A MATLAB file of two IMUs stored one vector per axis (ssong47/compute_relative_angle_between_two_IMUs's
  ``raw_pitch_slow.mat``: ``all_time``, ``all_accel_1_x``, ..., ``all_gyro_2_z``, quaternions, an encoder, each
  149829 × 1): refused before as "no accelerometer matrix", naming no flag; now each sensor's three vectors are
  joined as one matrix (said), the two accelerometers refused naming ``--topic``, and with ``--topic all_accel_1``
  the gyro named as it is (``all_gyro_1``) and the time (``all_time``) read beside it.
* Rests of one orientation between turns about gravity (the same file's yaw trial, its turning IMU: 187 rests, |a|
  1.000 g): refused as "pose means do not look like an accelerometer's", which they are; now refused as of one
  orientation, an accelerometer never turned, naming the turn first.
* An iOS app's CoreMotion dump, one record over four lines (fffire-oss/imu_processing's ``dataset/circle.txt``: a
  date-time line, then ``Acceleration: x, y, z``, ``Rotation Rate: ...``, ``Magnetic Field: ...``): refused before as
  "no usable sample (of 2936 rows: non-finite ...)", naming no flag; now read (:mod:`optcal.data.line_records`), the
  clock from the date-time lines, the magnetometer's lines and any other line said not read.

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


def test_two_imus_stored_one_vector_per_axis_are_joined_and_chosen_by_topic(turned, tmp_path, capsys):
    f = turned.frame
    acc, gyro = f[["ax", "ay", "az"]].to_numpy(), np.degrees(f[["gx", "gy", "gz"]].to_numpy())
    still = np.tile([1.0, 0.0, 0.0], (len(f), 1))  # the second IMU: one orientation throughout
    variables = {"data_line": 510.0, "all_time": 60.0 + f["t"].to_numpy()[:, None],
                 "all_encoder": np.zeros((len(f), 1))}
    for k, (a, w) in {"1": (acc, gyro), "2": (still, np.zeros_like(gyro))}.items():
        for j, axis in enumerate("xyz"):
            variables[f"all_gyro_{k}_{axis}"] = w[:, j:j + 1]
            variables[f"all_accel_{k}_{axis}"] = a[:, j:j + 1]
    path = tmp_path / "raw_pitch_slow.mat"
    savemat(path, variables)
    code, out, err = run(capsys, "segment", str(path))
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, err
    assert "all_accel_1 (3450 × 3)" in lines[0] and "all_accel_2 (3450 × 3)" in lines[0] and "--topic NAME" in lines[0]
    loaded = load_with_segmentation(path, topic="all_accel_1")
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 0.5
    columns = loaded.decisions.columns.value
    assert "ax←all_accel_1_x" in columns and "gz←all_gyro_1_z" in columns and "t←all_time" in columns
    np.testing.assert_allclose(loaded.recording.gyro[:, 1], gyro[:, 1])


def test_rests_of_one_orientation_in_g_are_refused_as_one_orientation_not_as_no_accelerometer(tmp_path, capsys):
    noise = np.random.default_rng(5)
    rate, rows, t = 100.0, [], 0.0
    for _ in range(14):  # 3-s rests, gravity on z, between 1-s turns about gravity (the accelerometer sees none)
        for k in range(int(4 * rate)):
            turning = k >= 3 * rate
            a = np.array([0.01, -0.02, 1.0]) + noise.normal(scale=0.002, size=3)
            w = noise.normal(scale=0.01, size=3) + (np.array([0.0, 0.0, 1.5]) if turning else 0.0)
            rows.append(",".join(f"{v:.6f}" for v in (t, *a, *w)))
            t += 1 / rate
    path = tmp_path / "yaw.csv"
    path.write_text("t,ax,ay,az,gx,gy,gz\n" + "\n".join(rows) + "\n")
    code, out, err = run(capsys, "calibrate", str(path))
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, err
    assert "14 pose means are of one orientation" in lines[0] and "median |a| is 1 g" in lines[0]
    assert "do not look like an accelerometer" not in lines[0]
    assert "turn the sensor through several orientations" in lines[0]


def test_records_over_several_lines_with_a_label_before_each_sensor_are_read(turned, tmp_path):
    from helpers.ios_dump import ios_dump_lines

    f = turned.frame
    lines = ios_dump_lines(f["t"].to_numpy(), f[["ax", "ay", "az"]].to_numpy(), f[["gx", "gy", "gz"]].to_numpy())
    path = tmp_path / "circle.txt"
    path.write_text("\n".join(lines) + "\nSent from my iPhone\n")
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 0.5
    assert loaded.recording.units == "g"
    np.testing.assert_allclose(loaded.recording.gyro[:, 2], f["gz"].to_numpy())
    assert "magnetometer line(s) not read" in loaded.decisions.layout
    assert "1 line(s) of another shape not read" in loaded.decisions.layout
