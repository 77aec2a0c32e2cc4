"""Issue 26 (items 3 and 4): column roles by evidence, comment-line headers, and the names files use.
Each regression test fails on the data layer before issue 26."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from helpers.cli_run import run
from helpers.common import SHARED
from helpers.recordings import turned_recording
from optcal.data import load, load_with_segmentation
from optcal.errors import InputError

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
needs_xsens = pytest.mark.skipif(not XSENS.exists(), reason="needs ../shared/data/imutk-xsens")


@pytest.fixture(scope="module")
def turned():
    """12 poses in g at 100 Hz with a gyro in °/s (bias 0.5, -0.3, 0.2 °/s)."""
    return turned_recording(12, 3, 4, dwell_s=4.0)


def xsens_counts() -> pd.DataFrame:
    return pd.read_csv(XSENS)


# 3 --------------------------------------------------------------------- which triple is the accelerometer
@needs_xsens
def test_a_headerless_log_written_gyro_first_is_read_by_the_data(tmp_path, capsys):
    """imu_tk fork's ``t gx gy gz ax ay az`` in signed counts (the Xsens log, its gyro's bias removed): read
    as ``t ax ay az gx gy gz`` it was refused, 'cannot tell the units (median |a| = 48.3)'.  The data say
    columns 5-7 are the accelerometer: its rest readings move on a sphere, the gyro's stay at its bias."""
    x = xsens_counts()
    gyro = x[["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]].to_numpy()
    acc = x[["acc_x_counts", "acc_y_counts", "acc_z_counts"]].to_numpy()
    rows = np.column_stack([x["t_s"], gyro - np.round(np.median(gyro[:5000], axis=0)), acc - 32768])
    np.savetxt(tmp_path / "imu.txt", rows, fmt=["%.5f"] + ["%d"] * 6)
    loaded = load_with_segmentation(tmp_path / "imu.txt")
    columns = loaded.decisions.columns
    assert columns.value.startswith("t←#1, ax←#5, ay←#6, az←#7, gx←#2, gy←#3, gz←#4")
    assert "columns 5-7 read as the accelerometer by the data" in columns.reason
    assert "--columns t=1,ax=2,ay=3,az=4,gx=5,gy=6,gz=7 reads them the other way" in columns.reason
    reference = load_with_segmentation(XSENS)  # the same recording, named
    assert loaded.poses.n == reference.poses.n
    assert np.allclose(loaded.poses.acc, reference.poses.acc - 32768)
    code, out, _ = run(["calibrate", tmp_path / "imu.txt"], capsys)
    assert code == 0 and "columns: t←#1, ax←#5" in out and "; --columns)" in out


def test_a_generated_gyro_first_log_is_read_by_the_data(turned, tmp_path):
    f = turned.frame
    np.savetxt(tmp_path / "imu.txt", f[["t", "gx", "gy", "gz", "ax", "ay", "az"]].to_numpy(), fmt="%.7f")
    poses = load(tmp_path / "imu.txt")
    assert poses.decisions.columns.value.startswith("t←#1, ax←#5")
    assert poses.n == len(turned.dwells) and poses.units == "g"
    np.savetxt(tmp_path / "six.txt", f[["gx", "gy", "gz", "ax", "ay", "az"]].to_numpy(), fmt="%.7f")  # no time
    assert load(tmp_path / "six.txt", rate=100.0).decisions.columns.value.startswith("ax←#4, ay←#5, az←#6")


def test_a_time_column_written_last_is_the_time(turned, tmp_path):
    """``ax ay az gx gy gz t``: the increasing column is the time, wherever it is (first or last)."""
    np.savetxt(tmp_path / "imu.txt", turned.frame[["ax", "ay", "az", "gx", "gy", "gz", "t"]].to_numpy(), fmt="%.7f")
    poses = load(tmp_path / "imu.txt")
    assert poses.decisions.columns.value.startswith("t←#7, ax←#1")
    assert poses.n == len(turned.dwells)


def test_a_sensor_never_turned_keeps_the_common_layout_and_says_so(tmp_path):
    """One rest: the data do not tell the triples apart; the common layout, with the --columns that swaps it."""
    rng = np.random.default_rng(9)
    n = 2000
    acc = np.array([0.02, -0.01, 0.999]) + 0.002 * rng.standard_normal((n, 3))
    gyro = np.array([0.5, -0.3, 0.2]) + 0.1 * rng.standard_normal((n, 3))
    np.savetxt(tmp_path / "still.txt", np.column_stack([np.arange(n) / 100.0, acc, gyro]), fmt="%.6f")
    columns = load_with_segmentation(tmp_path / "still.txt").decisions.columns
    assert columns.value.startswith("t←#1, ax←#2")
    assert "the data do not tell which triple is the accelerometer" in columns.reason
    assert "--columns t=1,ax=5,ay=6,az=7,gx=2,gy=3,gz=4" in columns.reason


def test_units_refused_for_columns_taken_by_layout_point_at_columns(tmp_path):
    """A still log (roles undecided) whose common layout puts a gyro in °/s first: the units refusal names --columns."""
    rng = np.random.default_rng(10)
    n = 2000
    gyro = np.array([30.0, -20.0, 25.0]) + 0.1 * rng.standard_normal((n, 3))  # |g| ≈ 44: no unit's 1 g
    acc = np.array([0.0, 0.0, 1.0]) + 0.002 * rng.standard_normal((n, 3))
    np.savetxt(tmp_path / "still.txt", np.column_stack([np.arange(n) / 100.0, gyro, acc]), fmt="%.6f")
    with pytest.raises(InputError, match="cannot tell the units.*map them with --columns"):
        load(tmp_path / "still.txt")


# 4 --------------------------------------------------------------------- comment headers and names
def comment_header_file(path: Path, frame: pd.DataFrame, mark: str = "#") -> None:
    """``# time tx ty tz wx wy wz mx my mz qx qy qz qw``: a logger's columns named in a comment line."""
    n = len(frame)
    rows = np.column_stack([frame["t"], frame[["ax", "ay", "az"]], frame[["gx", "gy", "gz"]],
                            np.tile([0.2, 0.0, 0.4, 1.0, 0.0, 0.0, 0.0], (n, 1))])
    head = f"{mark} time tx ty tz wx wy wz mx my mz qx qy qz qw"
    np.savetxt(path, rows, fmt="%.7f", header=head, comments="")


def test_a_comment_line_names_the_columns(turned, tmp_path):
    comment_header_file(tmp_path / "log.txt", turned.frame)
    loaded = load_with_segmentation(tmp_path / "log.txt")
    decisions = loaded.decisions
    assert decisions.columns.value == "t←time, gx←wx, gy←wy, gz←wz, ax←tx, ay←ty, az←tz"
    assert "the data say acceleration" in decisions.columns.reason and "header in the comment on line 1" in decisions.layout
    assert loaded.poses.n == len(turned.dwells)
    # the names are the file's: --columns uses them
    assert load(tmp_path / "log.txt", columns="ax=tx,ay=ty,az=tz").n == len(turned.dwells)


def test_a_percent_comment_line_names_the_columns(turned, tmp_path):
    f = turned.frame
    np.savetxt(tmp_path / "log.txt", f[["t", "ax", "ay", "az"]].to_numpy(), fmt="%.7f", header="% t ax ay az", comments="")
    poses = load(tmp_path / "log.txt")
    assert poses.decisions.columns.reason == "names in the comment on line 1" and poses.n == len(turned.dwells)


def test_a_comment_that_names_nothing_leaves_the_columns_by_position(turned, tmp_path):
    np.savetxt(tmp_path / "log.txt", turned.frame[["t", "ax", "ay", "az"]].to_numpy(), fmt="%.7f",
               header="# logged with my own firmware", comments="")  # 5 words for 4 columns
    np.savetxt(tmp_path / "log4.txt", turned.frame[["t", "ax", "ay", "az"]].to_numpy(), fmt="%.7f",
               header="# logged by firmware two", comments="")  # 4 words, none a column name
    for name in ("log.txt", "log4.txt"):
        assert "no header" in load(tmp_path / name).decisions.columns.reason


def test_tx_ty_tz_that_are_not_acceleration_are_refused(turned, tmp_path):
    """tx, ty, tz of a trajectory (a translation, in m): their rest readings lie on no sphere."""
    f = turned.frame.copy()
    rng = np.random.default_rng(12)
    steps = np.repeat(rng.normal(size=(len(turned.dwells) + 2, 3)), len(f) // (len(turned.dwells) + 2) + 1, axis=0)
    f[["ax", "ay", "az"]] = np.cumsum(steps[: len(f)] * 1e-3, axis=0) + 1e-5 * rng.standard_normal((len(f), 3))
    comment_header_file(tmp_path / "trajectory.txt", f)
    with pytest.raises(InputError, match=r"tx, ty, tz are read as the accelerometer only when the data say acceleration.*--columns"):
        load(tmp_path / "trajectory.txt")


def test_names_with_a_prefix_are_recognised(turned, tmp_path):
    """``rostopic echo -p``'s ``field.linear_acceleration.x`` and ``imu_acc_x`` name the accelerometer."""
    f = turned.frame
    out = pd.DataFrame({"field.header.stamp": f["t"]})
    for axis in "xyz":
        out[f"field.linear_acceleration.{axis}"] = f["a" + axis]
    for axis in "xyz":
        out[f"field.angular_velocity.{axis}"] = f["g" + axis]
    out.to_csv(tmp_path / "ros.csv", index=False)
    poses = load(tmp_path / "ros.csv")
    assert poses.decisions.columns.value.startswith("t←field.header.stamp, ax←field.linear_acceleration.x")
    assert "gz←field.angular_velocity.z" in poses.decisions.columns.value


@pytest.mark.skipif(not (SHARED / "data" / "mikoff-mpu9150").exists(), reason="needs ../shared/data/mikoff-mpu9150")
def test_mikoff_logs_read_as_before_now_by_the_data():
    """``ax ay az wx wy wz`` without a header: the common layout, now confirmed by the rest readings."""
    loaded = load_with_segmentation(SHARED / "data" / "mikoff-mpu9150" / "imu0.log", rate=100.0)
    assert loaded.decisions.columns.value.startswith("ax←#1, ay←#2, az←#3, gx←#4")
    assert "columns 1-3 read as the accelerometer by the data" in loaded.decisions.columns.reason
    assert loaded.poses.n == 22
