"""Issue 36, the strangers' sweep (docs/rest-model.md, "Strangers' recordings"): three layouts public
loggers wrote that optcal refused, each reproduced on a GENERATED file (no recording is committed).

* a header that lost a delimiter (``time (s)x (g),y (g),z (g)`` over four fields, an MPU-9250 logger's):
  refused even with ``--columns`` by position; now ``--columns t=1,ax=2,...`` reads it and the refusal names it;
* a still log without a header written gyro first (``t gx gy gz ax ay az``, an ADI logger's): neither
  triple moves on a sphere, so the roles stayed undecided and the units were refused; gravity's norm now
  settles them when one triple reads 1 g and the other less than 1 g in any unit;
* a 9-axis log without a header (``t ax ay az gx gy gz mx my mz``, imu_tk's ROS node's ``imu_data.txt``):
  refused ("10 unnamed columns fit no common layout"); now read, the last triple said not read.

Each test fails on the code before the sweep (the first two assertions of each were refusals).
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cli_run import run
from helpers.recordings import turned_recording
from optcal.data import load, load_with_segmentation
from optcal.errors import InputError


@pytest.fixture(scope="module")
def turned():
    """10 poses in g at 100 Hz with a gyro in °/s (bias 0.5, -0.3, 0.2 °/s)."""
    return turned_recording(10, 5, 6)


# ------------------------------------------------------------------ a header that lost a delimiter
def lost_delimiter_file(path, frame) -> None:
    """willward20's MPU-9250 logger: a title line, then ``time (s)x (g),y (g),z (g)`` above 4 fields a row."""
    rows = "\n".join(f"{t:.6f},{x:.6f},{y:.6f},{z:.6f}" for t, x, y, z in frame[["t", "ax", "ay", "az"]].to_numpy())
    path.write_text("Acceleration Data Collected on Level Surface. Z up.\ntime (s)x (g),y (g),z (g)\n" + rows + "\n")


def test_a_header_with_fewer_names_than_fields_is_read_by_position(turned, tmp_path):
    f = tmp_path / "six_position_test_data.csv"
    lost_delimiter_file(f, turned.frame)
    poses = load_with_segmentation(f, columns="t=1,ax=2,ay=3,az=4")
    assert poses.poses.n == len(turned.dwells)
    assert poses.decisions.columns.value == "t←#1, ax←#2, ay←#3, az←#4"
    assert "line 2's names do not match the fields (read as a note)" in poses.decisions.columns.reason
    assert "line 2's names do not match the fields: read as a note" in poses.decisions.layout


def test_a_header_with_fewer_names_than_fields_is_refused_naming_columns(turned, tmp_path, capsys):
    """Without --columns the refusal stands (a header that does not match its rows is not guessed at), and
    now names the flag that reads the fields by position: one line, exit 2."""
    f = tmp_path / "six_position_test_data.csv"
    lost_delimiter_file(f, turned.frame)
    with pytest.raises(InputError, match=r"line 2 looks like the header \(3 columns.*--columns t=1,ax=2,ay=3,az=4"):
        load(f)
    code, out, err = run(["segment", f], capsys)
    assert code == 2 and "Traceback" not in err and "--columns t=1,ax=2,ay=3,az=4" in err
    code, out, err = run(["segment", f, "--columns", "t=1,ax=2,ay=3,az=4"], capsys)
    assert code == 0 and f"{len(turned.dwells)} static intervals" in out


def test_a_short_row_below_a_header_is_still_refused(tmp_path):
    """The other way round (fewer fields than names) is not a lost delimiter: refused as before, with --columns."""
    f = tmp_path / "short.csv"
    f.write_text("ax,ay,az\n1,2\n" * 1 + "".join(f"{i},{i + 1}\n" for i in range(20)))
    with pytest.raises(InputError, match="looks like the header"):
        load(f)


# ------------------------------------------------------------------ a still log written gyro first
def still_log(path, gyro, acc, n: int = 3000, rate: float = 100.0, seed: int = 11) -> None:
    """``t gx gy gz ax ay az`` without a header: one orientation, the gyro at its bias."""
    rng = np.random.default_rng(seed)
    g = np.asarray(gyro) + 0.002 * rng.standard_normal((n, 3))
    a = np.asarray(acc) + 0.02 * rng.standard_normal((n, 3))
    np.savetxt(path, np.column_stack([254500.0 + np.arange(n) / rate, g, a]), fmt="%.7e")


def test_a_still_log_written_gyro_first_is_read_by_gravitys_norm(tmp_path):
    """An ADI logger's still log: gyro (rad/s, |bias| 0.05) first, accelerometer (m/s^2) after. Before the sweep:
    'cannot tell the units (median |a| = 0.05 ...)'; now columns 5-7 are the accelerometer, one rest of 30 s."""
    f = tmp_path / "x_adi_up.txt"
    still_log(f, [0.003, -0.002, -0.05], [9.86, 0.15, -0.2])
    loaded = load_with_segmentation(f)
    columns = loaded.decisions.columns
    assert columns.value.startswith("t←#1, ax←#5, ay←#6, az←#7, gx←#2")
    assert "by the norms" in columns.reason and "--columns t=1,ax=2,ay=3,az=4,gx=5,gy=6,gz=7" in columns.reason
    assert loaded.decisions.units.value == "m/s^2" and loaded.poses.n == 1


def test_a_still_log_whose_gyro_could_read_one_g_keeps_the_common_layout(tmp_path):
    """A gyro in °/s whose bias norm is 9.6 (an MPU-6050's zero-rate offsets are up to ±20 °/s) could be 1 g in
    m/s^2 beside an accelerometer in g: the norms do not settle it, so the common layout stands as before and
    says so, with the --columns that swaps it."""
    f = tmp_path / "still.txt"
    still_log(f, [6.0, -5.0, 5.5], [0.0, 0.02, 0.999])
    columns = load(f).decisions.columns
    assert columns.value.startswith("t←#1, ax←#2")
    assert "the data do not tell which triple is the accelerometer" in columns.reason
    assert "--columns t=1,ax=5,ay=6,az=7,gx=2,gy=3,gz=4" in columns.reason


# ------------------------------------------------------------------ a 9-axis log without a header
def test_a_nine_axis_log_without_a_header_is_read_and_its_magnetometer_said(turned, tmp_path, capsys):
    f = turned.frame
    n = len(f)
    mag = np.tile([0.21, -0.05, 0.43], (n, 1))
    path = tmp_path / "imu_data.txt"
    np.savetxt(path, np.column_stack([f["t"], f[["ax", "ay", "az"]], f[["gx", "gy", "gz"]], mag]), fmt="%.6f")
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert loaded.decisions.columns.value == "t←#1, ax←#2, ay←#3, az←#4, gx←#5, gy←#6, gz←#7"
    assert "columns 8, 9, 10 not read" in loaded.decisions.layout
    code, out, _ = run(["segment", path], capsys)
    assert code == 0 and "columns 8, 9, 10 not read (--columns maps them)" in out


# ------------------------------------------------------------------ a time column that goes back
def test_a_headerless_log_whose_time_goes_back_says_so(tmp_path):
    """An Arduino serial log (AhmedFouad23's ``+veX.csv``) repeats lines and restarts its ``millis()``: the refusal
    said "4 unnamed columns fit no common layout"; it now says where the would-be time column goes back."""
    rows = [f"{59000 + 52 * (i % 5)},1.01,-0.02,-0.05" for i in range(40)]
    f = tmp_path / "+veX.csv"
    f.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError, match=r"would be a time column and 3 axes.*goes back at data row 6: 59000 after "
                                         r"59208, 7 such step\(s\).*--columns t=1,ax=2,ay=3,az=4"):
        load(f)


# ------------------------------------------------------------------ phyphox's export: a bare axis and its unit
def test_phyphox_columns_are_read_by_their_units(turned, tmp_path):
    """phyphox writes ``"Time (s)","X (m/s^2)","Y (m/s^2)","Z (m/s^2)"`` (Slmaking/Reorientation-of-smartphone):
    refused before ("no accelerometer column(s)"); a bare axis whose unit is an acceleration's is the
    accelerometer, one whose unit is a rate's the gyroscope; and the time's reason keeps the name whole."""
    f = turned.frame
    path = tmp_path / "Accelerometer.csv"
    rows = "\n".join(f"{t:.9E},{x * 9.80665:.9E},{y * 9.80665:.9E},{z * 9.80665:.9E},{p:.9E},{q:.9E},{r:.9E}"
                     for t, x, y, z, p, q, r in f[["t", "ax", "ay", "az", "gx", "gy", "gz"]].to_numpy())
    path.write_text('"Time (s)","X (m/s^2)","Y (m/s^2)","Z (m/s^2)","X (deg/s)","Y (deg/s)","Z (deg/s)"\n' + rows + "\n")
    loaded = load_with_segmentation(path)
    d = loaded.decisions
    assert d.columns.value == ("t←Time (s), ax←X (m/s^2), ay←Y (m/s^2), az←Z (m/s^2), "
                               "gx←X (deg/s), gy←Y (deg/s), gz←Z (deg/s)")
    assert d.units.value == "m/s^2" and loaded.poses.n == len(turned.dwells)
    assert "column 'Time (s)' in s" in d.time_base.reason


def test_a_bare_axis_in_counts_is_not_taken(tmp_path):
    """``X (counts)`` says nothing of the quantity: not read as an accelerometer (refused naming --columns)."""
    path = tmp_path / "counts.csv"
    path.write_text('"t (s)","X (counts)","Y (counts)","Z (counts)"\n' + "".join(f"{i / 100},1,2,16000\n" for i in range(50)))
    with pytest.raises(InputError, match="no accelerometer column"):
        load(path)


def test_phyphox_gyroscope_file_merges_with_its_unit(turned, tmp_path, capsys):
    """phyphox exports the gyroscope apart (``Gyroscope.csv``: ``"Time (s)","X (rad/s)",...``); ``--gyro-file`` asked
    it for an accelerometer ("no accelerometer column(s)"). Its gyro columns now merge, the unit stated by the names."""
    f = turned.frame
    acc = tmp_path / "Accelerometer.csv"
    gyro = tmp_path / "Gyroscope.csv"
    acc.write_text('"Time (s)","X (m/s^2)","Y (m/s^2)","Z (m/s^2)"\n' + "\n".join(
        f"{t:.9E},{x * 9.80665:.9E},{y * 9.80665:.9E},{z * 9.80665:.9E}" for t, x, y, z in f[["t", "ax", "ay", "az"]].to_numpy()) + "\n")
    gyro.write_text('"Time (s)","X (rad/s)","Y (rad/s)","Z (rad/s)"\n' + "\n".join(
        f"{t:.9E},{np.radians(p):.9E},{np.radians(q):.9E},{np.radians(r):.9E}" for t, p, q, r in f[["t", "gx", "gy", "gz"]].to_numpy()) + "\n")
    loaded = load_with_segmentation(acc, gyro_file=gyro)
    assert "gx←Gyroscope.csv:X (rad/s)" in loaded.decisions.columns.value
    assert loaded.poses.n == len(turned.dwells)
    code, out, _ = run(["segment", acc, "--gyro-file", gyro], capsys)
    assert code == 0 and "gyro: rad/s as stated" in out
