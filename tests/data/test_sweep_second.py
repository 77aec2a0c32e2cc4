"""Issue 36/40, the second strangers' sweep (docs/rest-model.md, "Strangers' recordings, second sweep"): two
layouts public loggers wrote that optcal misread, each reproduced on a GENERATED file (no recording is committed).

* a MAT-file whose variables carry the trial's name before the sensor's (``static_acc``, ``static_gyr``,
  ``static_mag``: Maskul93/MIMU-calib-tutorial): the names said nothing to the ``acc*``/``gyr*``/``mag*`` prefixes,
  so the magnetometer's file was refused ("no magnetometer variable"), a gyroscope's still log was read as an
  accelerometer's, and a file holding two of them was refused as "2 matrices could be the accelerometer's";
* a headerless log with a delimiter after each line's last value (``24838,40562,...,1896,``: an Arduino loop's
  ``Serial.print(",")`` after every field, mgiurato/IMU-Calibration): the empty last field made 10 columns, refused
  as "a time column and 9 axes, but neither the first column nor the last increases".

Each test fails on the code before this sweep.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.io import savemat

from helpers.cli_run import run
from helpers.recordings import turned_recording
from optcal.data import load, load_with_segmentation
from optcal.data.containers import ACCELEROMETER, GYROSCOPE, MAGNETOMETER, Variable, role_of
from optcal.errors import InputError
from optcal.families.mag.samples import read_mag

G = 9.80665


@pytest.fixture(scope="module")
def turned():
    """10 poses in g at 100 Hz with a gyro in °/s."""
    return turned_recording(10, 5, 6)


# ------------------------------------------------------------------ the sensor named after the trial
@pytest.mark.parametrize(("name", "role"), [
    ("static_acc", ACCELEROMETER), ("static_gyr", GYROSCOPE), ("static_mag", MAGNETOMETER),
    ("trial3_accel", ACCELEROMETER), ("raw_gyroscope", GYROSCOPE), ("imu_compass", MAGNETOMETER),
    # whole words only, and one role only: these name no sensor
    ("field_magnitude", None), ("static_watts", None), ("acc_vs_mag_trial", ACCELEROMETER), ("trial_acc_mag", None),
])
def test_a_later_word_of_a_variables_name_says_its_sensor(name, role):
    assert role_of(Variable(name, np.zeros((10, 3)))) == role


def test_a_mat_file_of_trial_named_sensors_is_read(turned, tmp_path):
    """``static_acc`` (m/s^2) and ``static_gyr`` (rad/s) side by side: before, neither name matched a prefix and the
    file was refused as two candidate accelerometer matrices; now the accelerometer is chosen by its name and the
    gyro read beside it."""
    f = turned.frame
    path = tmp_path / "trial.mat"
    savemat(path, {"static_acc": f[["ax", "ay", "az"]].to_numpy() * G,
                   "static_gyr": np.radians(f[["gx", "gy", "gz"]].to_numpy())})
    loaded = load_with_segmentation(path, rate=100.0)
    assert loaded.poses.n == len(turned.dwells)
    assert loaded.decisions.columns.value.startswith("ax←static_acc(:,1)")
    assert "its name or attributes say acceleration" in loaded.decisions.columns.reason
    assert loaded.decisions.units.value == "m/s^2"
    assert loaded.recording is not None and loaded.recording.gyro is not None
    assert "gx←static_gyr[x]" in loaded.decisions.columns.value


def test_a_gyroscope_alone_is_not_read_as_an_accelerometer(tmp_path):
    """A gyro's still log (``static_gyr``, rad/s, 60 s): before, "the one matrix of 3 axes" was taken as the
    accelerometer (and refused on its units); now the refusal says the only matrix is a gyroscope's."""
    rng = np.random.default_rng(3)
    path = tmp_path / "gyr_static.mat"
    savemat(path, {"static_gyr": [-0.064, 0.003, -0.010] + 0.003 * rng.standard_normal((6000, 3))})
    with pytest.raises(InputError, match=r"no accelerometer matrix .* static_gyr \(6000 × 3, gyroscope\)"):
        load(path, rate=100.0)


def test_a_magnetometer_named_after_its_trial_is_read(tmp_path, capsys):
    """``static_mag`` (µT, a sphere drawn by hand): refused before ("no magnetometer variable (by its name or
    units) among: static_mag"); now read, and ``calibrate --sensor mag`` recovers the field."""
    rng = np.random.default_rng(4)
    d = rng.standard_normal((3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    m = 37.0 * d * [1.03, 0.97, 1.0] + [23.0, 3.6, 39.7] + 0.2 * rng.standard_normal((3000, 3))
    path = tmp_path / "mag_sphere.mat"
    savemat(path, {"static_mag": m})
    samples = read_mag(path)
    assert samples.n == 3000 and samples.columns["mx"] == "static_mag(:,1)"
    code, out, err = run(["calibrate", path, "--sensor", "mag"], capsys)
    assert code == 0, err
    assert "variable 'static_mag' (3000 × 3) read as the magnetometer" in out


# ------------------------------------------------------------------ a delimiter at each line's end
def test_a_delimiter_at_each_lines_end_is_not_a_column(turned, tmp_path, capsys):
    """``ax,ay,az,gx,gy,gz,mx,my,mz,`` without a header or time: before, 10 columns, refused as a time column and 9
    axes whose first and last columns do not increase; now the empty last field is said and not read."""
    f = turned.frame
    n = len(f)
    mag = np.tile([0.21, -0.05, 0.43], (n, 1))
    values = np.column_stack([f[["ax", "ay", "az"]], f[["gx", "gy", "gz"]], mag])
    path = tmp_path / "log_raw.txt"
    path.write_text("".join(",".join(f"{v:.6f}" for v in row) + ",\r\n" for row in values))
    loaded = load_with_segmentation(path, rate=100.0)
    assert loaded.poses.n == len(turned.dwells)
    assert loaded.decisions.columns.value == "ax←#1, ay←#2, az←#3, gx←#4, gy←#5, gz←#6"
    assert "columns 7, 8, 9, 10 not read" in loaded.decisions.layout
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "Traceback" not in err and "--rate" in err
    # where the data do not decide which triple is the accelerometer, the common layout's reason says why 10 fields
    # make 9 columns
    path.write_text("".join(",".join(f"{v:.6f}" for v in row) + ",\n" for row in values[:40]))
    code, out, err = run(["segment", path, "--rate", "100"], capsys)
    assert "the last 1 of 10 fields empty in every row (a delimiter at each line's end): not read" in out + err


def test_a_field_empty_in_some_rows_only_is_still_a_column(tmp_path):
    """Only a field empty in EVERY row is dropped: a last column with values in some rows keeps the width (here
    it increases where it is filled, so it stays the time column of 10 columns, as before)."""
    rng = np.random.default_rng(5)
    rows = []
    for i in range(60):
        v = list(rng.normal(0, 1, 9)) + ([] if i % 2 else [float(i)])
        rows.append(",".join(f"{x:.4f}" for x in v) + ("," if i % 2 else ""))
    path = tmp_path / "ragged.csv"
    path.write_text("\n".join(rows) + "\n")
    columns = load(path).decisions.columns
    assert columns.value.startswith("t←#10") and "the common layout of 10 columns" in columns.reason


# ------------------------------------------------------------------ Sensor Logger's export: bare axes named by the file
def sensor_logger_file(path, t, xyz) -> None:
    """Sensor Logger's CSV (awesome-sensor-logger's UNITS.md): ``time`` in ns since 1970, ``seconds_elapsed``, and
    the axes in the order ``z, y, x`` without a unit."""
    rows = [f"{int(1678040536877350100 + s * 1e9)},{s:.6f},{z:.6f},{y:.6f},{x:.6f}" for s, (x, y, z) in zip(t, xyz)]
    path.write_text("time,seconds_elapsed,z,y,x\n" + "\n".join(rows) + "\n")


def test_sensor_logger_total_acceleration_and_its_gyroscope_are_read(turned, tmp_path):
    """``TotalAcceleration.csv`` (m/s^2, with gravity) with ``--gyro-file Gyroscope.csv`` (rad/s): before, refused
    ("no accelerometer column(s) ... time, seconds_elapsed, z, y, x"); now the file's name says the quantity."""
    f = turned.frame
    acc, gyro = tmp_path / "TotalAcceleration.csv", tmp_path / "Gyroscope.csv"
    sensor_logger_file(acc, f["t"], f[["ax", "ay", "az"]].to_numpy() * G)
    sensor_logger_file(gyro, f["t"], np.radians(f[["gx", "gy", "gz"]].to_numpy()))
    loaded = load_with_segmentation(acc, gyro_file=gyro)
    assert loaded.poses.n == len(turned.dwells)
    columns = loaded.decisions.columns
    assert columns.value.startswith("t←seconds_elapsed, ax←x, ay←y, az←z, gx←Gyroscope.csv:x")
    assert "Sensor Logger's export" in columns.reason and "TotalAcceleration is the accelerometer with gravity" in (
        columns.reason)
    assert loaded.decisions.units.value == "m/s^2"
    assert loaded.recording is not None and loaded.recording.gyro_units == "rad/s"


def test_sensor_logger_acceleration_without_gravity_is_refused_naming_the_files_with_it(turned, tmp_path, capsys):
    """Its ``Accelerometer.csv`` is the user's motion without gravity: one line naming the files that hold gravity
    and the --columns that reads it anyway (which then reads it)."""
    f = turned.frame
    path = tmp_path / "Accelerometer.csv"
    sensor_logger_file(path, f["t"], f[["ax", "ay", "az"]].to_numpy() * G)
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert "acceleration without gravity" in err and "TotalAcceleration.csv" in err
    assert "--columns t=seconds_elapsed,ax=x,ay=y,az=z" in err
    assert load(path, columns="t=seconds_elapsed,ax=x,ay=y,az=z").decisions.columns.value.startswith("t←seconds_elapsed")
    # its gyroscope alone is no accelerometer
    gyro = tmp_path / "Gyroscope.csv"
    sensor_logger_file(gyro, f["t"], np.radians(f[["gx", "gy", "gz"]].to_numpy()))
    with pytest.raises(InputError, match="no accelerometer column"):
        load(gyro)


# ------------------------------------------------------------------ PicoQuake's CSV: a sample counter and its rate in a comment
def test_a_count_column_that_steps_by_one_and_a_rate_among_settings_make_a_recording(turned, tmp_path):
    """PicoQuake writes ``# Config: data_rate = 2000.0 Hz, filter = 488 Hz, ...`` above ``count,a_x,a_y,a_z,g_x,...``
    (count 0, 1, 2, ...). Before: ``count`` was a pose table's per-pose sample count, so 4350 samples were read as
    4350 poses, and ``g_x`` was not read; now a count that steps by one a row is a sample index, the rate among the
    settings gives its time, and the gyro is read."""
    f = turned.frame
    path = tmp_path / "picoquake.csv"
    values = f[["ax", "ay", "az", "gx", "gy", "gz"]].to_numpy()
    rows = "\n".join(f"{i}," + ",".join(f"{v:.6f}" for v in row) for i, row in enumerate(values))
    path.write_text("# PLab PicoQuake Data\n# Num. samples: 4350, Duration: 43.5 s\n"
                    "# Config: data_rate = 100.0 Hz, filter = 42 Hz, acc_range = 4 g, gyro_range = 250.0 dps\n"
                    "count,a_x,a_y,a_z,g_x,g_y,g_z\n" + rows + "\n")
    loaded = load_with_segmentation(path)
    assert loaded.decisions.kind.value == "raw recording"
    assert "'data_rate = 100.0 Hz' in the file header's 'Config' line" in loaded.decisions.kind.reason
    # beside an accelerometer named a_x, a_y, a_z, the g_ columns are the gyro's (g_x alone could be g-force)
    assert loaded.decisions.columns.value == "index←count, ax←a_x, ay←a_y, az←a_z, gx←g_x, gy←g_y, gz←g_z"
    assert loaded.poses.n == len(turned.dwells)
    assert loaded.recording is not None and loaded.recording.gyro is not None


def test_g_columns_without_an_a_named_accelerometer_are_not_the_gyro():
    """``g_x`` beside ``acc_x`` (or alone) stays unread: only an accelerometer named ``a_`` makes ``g_`` the gyro."""
    from optcal.data.columns import resolve_columns

    assert "gx" not in resolve_columns(["t", "acc_x", "acc_y", "acc_z", "g_x", "g_y", "g_z"], {}).column_map
    assert "gx" in resolve_columns(["t", "a_x", "a_y", "a_z", "g_x", "g_y", "g_z"], {}).column_map


def test_a_count_column_of_averaged_samples_keeps_the_pose_table(tmp_path):
    """A pose table's ``count`` (samples averaged per pose: 200, 180, 250, ...) does not step by one: it stays
    the per-pose count, and the file a pose table."""
    rng = np.random.default_rng(8)
    d = rng.standard_normal((12, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    counts = rng.integers(150, 260, 12)
    path = tmp_path / "poses.csv"
    path.write_text("ax,ay,az,count\n" + "\n".join(f"{x:.6f},{y:.6f},{z:.6f},{c}" for (x, y, z), c in zip(d, counts))
                    + "\n")
    loaded = load(path)
    assert loaded.decisions.kind.value == "pose table"
    assert "n_samples←count" in loaded.decisions.columns.value
