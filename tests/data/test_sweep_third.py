"""The third strangers' sweep (docs/rest-model.md, "Strangers' recordings, third sweep"): layouts public loggers
wrote that optcal misread, each reproduced on a GENERATED file (no recording is committed).

* a header row with a delimiter after its last name (``Index,Accel X (LSB),...,Temperature,``: Ehsangit2021/ITG_MPU's
  ICM-20948 export; any Arduino loop that prints ``","`` after every field, the header's included): the empty last
  name made the line "not a row of names", so the file was read as having no header, its names kept as a metadata
  line and its columns taken by the common layout of their number (or refused as "no header row");

Each test fails on the code before this sweep.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cli_run import run
from helpers.recordings import turned_recording
from optcal.data import load_with_segmentation
from optcal.data.text import sniff_layout
from optcal.families.simulate.poses import uniform_directions


@pytest.fixture(scope="module")
def turned():
    """10 poses in g at 100 Hz with a gyro in °/s."""
    return turned_recording(10, 5, 6)


# ------------------------------------------------------------------ a delimiter after the header's last name
@pytest.mark.parametrize("rows_end", [",", ""])
def test_a_header_ending_in_a_delimiter_names_the_columns(turned, tmp_path, rows_end):
    """``time_ms,gx,gy,gz,ax,ay,az,`` over rows with (or without) a delimiter after the last value: before, the
    header was not read (a metadata line), the first column taken as seconds and the triples by their order; now its
    names map the columns (the gyro first, the time in ms by its name)."""
    f = turned.frame
    values = np.column_stack([f["t"] * 1000.0, f[["gx", "gy", "gz"]], f[["ax", "ay", "az"]]])
    path = tmp_path / "arduino.csv"
    path.write_text("time_ms,gx,gy,gz,ax,ay,az,\n"
                    + "".join(",".join(f"{v:.6f}" for v in row) + rows_end + "\n" for row in values))
    layout = sniff_layout(path)
    assert layout.has_header and layout.names[:7] == ["time_ms", "gx", "gy", "gz", "ax", "ay", "az"]
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 1.0
    # the accelerometer's columns are the named ones (1 g at rest), not the first triple (the gyro, near 0)
    np.testing.assert_allclose(np.linalg.norm(loaded.poses.acc, axis=1), 1.0, atol=0.03)
    assert loaded.decisions.columns.reason.startswith("header names")


def test_a_header_ending_in_a_delimiter_over_rows_with_an_extra_value_is_refused_naming_columns(turned, tmp_path,
                                                                                                 capsys):
    """ITG_MPU's export: 11 names and a delimiter, over rows of 12 values and a delimiter (the temperature written
    with a decimal comma, ``32,04466``, splits in two fields). Before: "the file has no header row"; now the header
    is recognised, the mismatch said, and ``--columns`` by position reads the file with the line as a note."""
    f = turned.frame
    n = len(f)
    counts = np.column_stack([np.arange(n) + 14691, np.round(f[["ax", "ay", "az"]] * 16384),
                              np.round(f[["gx", "gy", "gz"]] * 131), np.tile([-89, 217, 275], (n, 1))]).astype(int)
    names = ["Index"] + [f"{s} {a} (LSB)" for s in ("Accel", "Gyro", "Compass") for a in "XYZ"] + ["Temperature"]
    path = tmp_path / "IMU.csv"
    path.write_text(",".join(names) + ",\n" + "".join(
        ",".join(str(v) for v in row) + f",32,{4466 + i % 7:05d},\n" for i, row in enumerate(counts)))
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "Traceback" not in err
    assert "no header row" not in err
    assert "line 1 looks like the header (11 columns: Index" in err and "--columns" in err
    code, out, err = run(["segment", path, "--columns", "ax=2,ay=3,az=4,gx=5,gy=6,gz=7", "--rate", "100"], capsys)
    assert code == 0, err
    assert "line 1's names do not match the fields (read as a note)" in out


# ------------------------------------------------------------------ a stamp split in whole seconds and nanoseconds
EPOCH = 1696324304  # 2023-10-03 in s since 1970, as SiyangMeng/matlabSensor_ros_localization's data/acc2.csv


def split_stamp_rows(t, values, pause_at=None, pause_s=0.0) -> str:
    """Rows ``secs,nsecs,x,y,z`` (ROS's header.stamp written as two integers, ns padded with blanks as that file's)
    for times ``t`` (s from the start), a pause of ``pause_s`` inserted before sample ``pause_at``."""
    t = np.asarray(t, dtype=float).copy()
    if pause_at is not None:
        t[pause_at:] += pause_s
    ns = np.round(t * 1e9).astype(np.int64) + EPOCH * 1_000_000_000  # integers: exact, as a logger writes them
    secs, frac = ns // 1_000_000_000, ns % 1_000_000_000
    return "".join(f"{s},{f:9d}," + ",".join(f"{v:.6f}" for v in row) + "\n" for s, f, row in zip(secs, frac, values))


def transition(turned, k: int) -> int:
    """A sample between dwell k and dwell k + 1 (a move: a pause there cuts no rest)."""
    return (turned.dwells[k][1] + turned.dwells[k + 1][0]) // 2


def test_a_stamp_split_in_seconds_and_nanoseconds_is_one_time_column(turned, tmp_path):
    """``secs, nsecs, ax, ay, az`` without a header (m/s^2): before, refused ("5 unnamed columns fit no common
    layout"; its example ``--columns t=1,...`` reads the whole seconds only, 100 samples per stamp); now columns 1-2
    are one stamp, read as seconds since 1970, and the file is a 100 Hz recording of its 10 rests."""
    f = turned.frame
    path = tmp_path / "acc2.csv"
    path.write_text(split_stamp_rows(f["t"], f[["ax", "ay", "az"]].to_numpy() * 9.80665))
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 0.5
    assert loaded.decisions.columns.value == "t←#1, ax←#3, ay←#4, az←#5"
    assert "whole seconds and ns of the second" in loaded.decisions.columns.reason
    assert "not read" not in loaded.decisions.layout  # the second field is the time's fraction, read


def test_a_split_stamp_is_a_typed_field_of_the_headerless_decision():
    """The reader sets the stamp's fraction aside as read from the decision's field (``joined_stamp``, the
    sub-second unit), not by searching for its words in the reason: ns for ROS's ``secs, nsecs``, ``None`` where
    column 1 is a time column on its own."""
    from optcal.data.columns import headerless_mapping

    secs = np.repeat(np.arange(1696324304.0, 1696324307.0), 100)
    nsecs = np.tile(np.arange(100) * 1e7 + 12345.0, 3)
    axes = [np.full(secs.size, v) for v in (0.1, 0.2, 9.8)]
    split = headerless_mapping("acc2.csv", [secs, nsecs, *axes], "5 columns")
    assert split.joined_stamp == "ns" and split.mapping == {"t": "1", "ax": "3", "ay": "4", "az": "5"}
    whole = headerless_mapping("acc.csv", [secs + nsecs * 1e-9, *axes], "4 columns")
    assert whole.joined_stamp is None and whole.mapping == {"t": "1", "ax": "2", "ay": "3", "az": "4"}


@pytest.mark.parametrize(("secs", "frac"), [
    ([0, 0, 1, 1, 2], [900, 10, 20, 950, 5]),  # the fraction goes back within a second: not a stamp's
    ([0, 1, 2, 3, 4], [10, 20, 30, 40, 50]),  # the seconds never repeat: column 1 is a time column on its own
    ([0, 0, 1, 1, 2], [0.5, 0.7, 0.1, 0.3, 0.2]),  # no integer count
])
def test_two_fields_that_are_not_one_stamp_are_not_joined(secs, frac):
    from optcal.data.columns import split_stamp

    cols = [np.asarray(secs, float), np.asarray(frac, float)] + [np.zeros(5)] * 3
    assert split_stamp(cols) is None


# ------------------------------------------------------------------ a pause of the recording is not a host's burst
@pytest.mark.parametrize("bursts", [False, True])
def test_a_pause_of_the_recording_is_kept_as_a_gap_not_spread_as_bursts(turned, tmp_path, bursts):
    """Three sessions joined in one file (acc2.csv: 30181 samples at 9 ms with pauses of 296 s and 414 s): the
    mean step (32.5 ms) was 3.6 times the median, read as host bursts, and the samples were spread evenly over the
    whole span, at 30.7 Hz instead of 111 Hz. Now a step longer than a host holds samples (4 s) is a pause: regular
    stamps are kept (100 Hz), and bursty ones are spread within each section, at the rate between the pauses."""
    f = turned.frame
    t = f["t"].to_numpy().copy()
    if bursts:  # a host stamps 10 samples at once, then waits 10 sample periods
        i = np.arange(t.size)
        t = t[0] + (i // 10) * 0.1 + (i % 10) * 1e-4
    t[transition(turned, 4):] += 300.0
    path = tmp_path / "joined.csv"
    path.write_text("t,ax,ay,az\n" + "".join(f"{EPOCH + s:.6f}," + ",".join(f"{v:.6f}" for v in row) + "\n"
                                            for s, row in zip(t, f[["ax", "ay", "az"]].to_numpy() * 9.80665)))
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 1.0
    assert "1 pause(s) of the recording" in loaded.decisions.time_base.reason
    assert loaded.decisions.time_base.value == ("uniform" if bursts else "stamps")
    pose_t = loaded.poses.t
    assert np.all(np.diff(pose_t) > 0) and np.max(np.diff(pose_t)) > 250.0  # the pause stays between two rests


# ------------------------------------------------------------------ a time column of text
def test_a_time_column_of_dates_as_text_is_set_aside_and_said(turned, tmp_path, capsys):
    """Yost Labs' 3-Space logger (Nicholas-Hall4799/threespace_imu): ``Time`` written as ``Wed Dec 22 21:09:46
    2021``. Before: every row dropped as non-finite, "no usable sample (of N rows: non-finite samples: N)", even with
    --rate; now the column is set aside and said, the refusal names --rate, and with it the file is read."""
    f = turned.frame
    start = 1640207386  # 2021-12-22 21:09:46 UTC
    from datetime import datetime, timezone
    stamps = [datetime.fromtimestamp(start + int(s), timezone.utc).strftime("%a %b %d %H:%M:%S %Y") for s in f["t"]]
    path = tmp_path / "imu_data.csv"
    path.write_text("Time,ax,ay,az,gx,gy,gz\n" + "".join(
        f"{d}," + ",".join(f"{v:.6f}" for v in row) + "\n"
        for d, row in zip(stamps, f[["ax", "ay", "az", "gx", "gy", "gz"]].to_numpy())))
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "Traceback" not in err
    assert "no usable sample" not in err
    assert "column 'Time' holds no number in any row (text such as 'Wed Dec 22 21:09:46 2021'" in err
    assert "--rate" in err
    loaded = load_with_segmentation(path, rate=100.0)
    assert loaded.poses.n == len(turned.dwells)
    assert "column 'Time' holds no number" in loaded.decisions.layout


# ------------------------------------------------------------------ a magnetometer in tesla
def test_a_magnetometer_written_in_tesla_is_read_in_tesla(tmp_path, capsys):
    """Emkijen/ESA-Poster-IPP's ``mag.csv``: ``t,Bx,By,Bz`` in T (|m| 1e-4). Before: "not the Earth's field in µT,
    nT, gauss or mgauss, so the samples are read as counts"; now T, whose range lies 10^6 below µT's (and counts,
    integers, never have so small a median); counts and the other units keep their readings."""
    from optcal.families.mag.units import units_from_magnitude

    assert units_from_magnitude(5e-5) == "T" and units_from_magnitude(50.0) == "uT"
    assert units_from_magnitude(500.0) == "mgauss" and units_from_magnitude(3000.0) is None
    rng = np.random.default_rng(3)
    d = uniform_directions(400, rng=4)
    m = 48e-6 * d @ np.diag([1.02, 0.97, 1.0]) + np.array([3e-6, -2e-6, 1e-6]) + 1e-7 * rng.normal(size=d.shape)
    path = tmp_path / "mag.csv"
    path.write_text("t,Bx,By,Bz\n" + "".join(f"{0.01 * i:.2f},{x:.12f},{y:.12f},{z:.12f}\n" for i, (x, y, z) in
                                             enumerate(m)))
    code, out, err = run(["calibrate", path, "--sensor", "mag"], capsys)
    assert code == 0, err
    assert "magnetometer units: T (from the data" in out


def test_a_magnetometer_with_a_split_stamp_is_read(tmp_path, capsys):
    """SiyangMeng's ``mag.csv`` (``secs, nsecs, mx, my, mz`` in µT, no header): before, refused ("5 unnamed
    columns fit no common layout of a magnetometer"); now columns 1-2 are the time and 3-5 the field."""
    d = uniform_directions(400, rng=4)
    m = 48.0 * d + np.array([3.0, -2.0, 1.0])
    path = tmp_path / "mag.csv"
    path.write_text(split_stamp_rows(np.arange(400) * 0.01, m))
    code, out, err = run(["calibrate", path, "--sensor", "mag"], capsys)
    assert code == 0, err
    assert "mx=3, my=4, mz=5, t=1" in out and "columns 1-2 one time stamp" in out


# ------------------------------------------------------------------ MATLAB objects in a MAT-file
def test_a_mat_file_of_matlab_objects_is_refused_saying_so(tmp_path, monkeypatch, capsys):
    """MATLAB Mobile's ``sensorlog_*.mat`` holds timetables: scipy reads each as an opaque placeholder named "None"
    (warning "Duplicate variable name") and optcal said "no accelerometer matrix … among the file's numeric
    variables: none". Now the refusal says the file holds MATLAB objects and how to export them. (scipy cannot
    write such objects, so its reader is given one, as it returns it for that file.)"""
    import scipy.io
    from scipy.io.matlab import MatlabOpaque

    opaque = np.zeros(1, dtype=[("s0", "O"), ("s1", "O"), ("s2", "O"), ("arr", "O")]).view(MatlabOpaque)
    monkeypatch.setattr(scipy.io, "loadmat", lambda *a, **k: {"__header__": b"MATLAB 5.0", "None": opaque})
    path = tmp_path / "sensorlog_20231003_091144.mat"
    scipy.io.savemat(path, {"x": np.zeros(3)})
    for argv in (["segment", path], ["calibrate", path, "--sensor", "mag"]):
        code, out, err = run(argv, capsys)
        assert code == 2 and "Traceback" not in err
        assert "holds MATLAB objects" in err and "writetimetable" in err


def test_a_magnetometers_file_given_to_the_accelerometers_command_names_sensor_mag(tmp_path, capsys):
    """``t_ms,mx,my,mz,B`` (emmaghita/esp32-magnetometer) to ``optcal segment``: the refusal named only --columns;
    now it says the columns are a magnetometer's and names ``--sensor mag``. An unknown file's refusal does not."""
    path = tmp_path / "mag_data.csv"
    path.write_text("t_ms,mx,my,mz,B\n" + "".join(f"{1712 + 100 * i},-350,-208,-1000,1079.7\n" for i in range(50)))
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "--sensor mag" in err
    path.write_text("t,u,v,w\n" + "".join(f"{0.01 * i},1,2,3\n" for i in range(50)))
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "--sensor mag" not in err and "--columns" in err
