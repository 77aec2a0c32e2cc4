"""The fifth strangers' sweep (docs/rest-model.md, "Strangers' recordings, fifth sweep"): layouts public loggers
wrote that optcal misread, each reproduced on a GENERATED file (no recording is committed).

* EuRoC's and Kalibr's IMU CSV (``#timestamp [ns],w_RS_S_x [rad s^-1],...,a_RS_S_x [m s^-2]``: the ASL datasets,
  TUM-VI, most visual-inertial exports; kalebburnham/IMU-Research's copy of MH_01 with its stamps re-written by a
  spreadsheet as ``1.40363657975856E+018``): refused before ("no accelerometer column(s)"); read now, the gyro in
  rad/s and the accelerometer in m/s² by their bracketed units;
* the Android IMU stream's rows (``683432.72989, 3, ax, ay, az, 4, gx, gy, gz, 5, mx, my, mz``, 98Glopes/imu-jupyter):
  the sensors' type numbers, one whole number in every row, were taken for columns, so no common layout fitted and
  the refusal's example (``ax=2``) named a label; now they are set aside where the layout fails with them;
* a gyro named by the rotation (NXP's IMU data logger, ``% SampleNumber MagX ... AccZ GyroR GyroP GyroY ...``):
  ``GyroY`` (the yaw) was read as the gyro's y axis alone, ``GyroR`` and ``GyroP`` not, and the gyro then dropped
  unsaid; now the gyro is said not read, naming the ``--columns`` that reads the roll, pitch and yaw as x, y, z.

Each test fails on the code before this sweep.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.recordings import turned_recording
from optcal.data import load_with_segmentation

G = 9.80665


@pytest.fixture(scope="module")
def turned():
    """8 poses in g at 100 Hz with a gyro in rad/s (the simulator's)."""
    return turned_recording(8, 3, 4)


def test_euroc_imu_csv_is_read_by_its_names_and_bracketed_units(turned, tmp_path):
    f = turned.frame
    stamps = 1403636579758555392 + np.round(f["t"].to_numpy() * 1e9)
    header = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
              "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n")
    path = tmp_path / "data.csv"
    path.write_text(header + "".join(
        f"{s:.14E}," + ",".join(f"{v:.10f}" for v in (*w, *(G * a))) + "\n"
        for s, w, a in zip(stamps, f[["gx", "gy", "gz"]].to_numpy(), f[["ax", "ay", "az"]].to_numpy())))
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 0.5
    assert loaded.decisions.columns.value.startswith("t←timestamp [ns], gx←w_RS_S_x [rad s^-1]")
    assert loaded.decisions.units.value == "m/s^2" and "m_s_2" in loaded.decisions.units.reason
    assert loaded.recording.gyro_units == "rad/s"


def _nxp_rows(turned) -> str:
    """NXP's IMU data logger (Mike Stanley's): comment lines, the names in a ``%`` comment, counts, no time."""
    f = turned.frame
    acc = np.round(f[["ax", "ay", "az"]].to_numpy() * 353.0)
    gyro = np.round(f[["gx", "gy", "gz"]].to_numpy() * np.degrees(1.0) * 16.0) + np.array([-515, -534, -529])
    mag = np.tile([371, -66, 585], (len(acc), 1))
    head = ("% Mike Stanley's IMU Data Logger\n% Accelerometer Range = +/- 6g\n"
            "% SampleNumber MagX MagY MagZ AccX AccY AccZ GyroR GyroP GyroY LButton RButton\n")
    return head + "".join(f"{k + 1} " + " ".join(f"{v:.0f}" for v in (*m, *a, *g)) + " 0 0 \n"
                          for k, (m, a, g) in enumerate(zip(mag, acc, gyro)))


def test_a_gyro_named_by_roll_pitch_yaw_is_said_not_read(turned, tmp_path):
    path = tmp_path / "SlowPickup.dat"
    path.write_text(_nxp_rows(turned))
    loaded = load_with_segmentation(path, rate=100.0)
    assert "gy←" not in loaded.decisions.columns.value and loaded.recording.gyro is None  # GyroY was read as gy
    assert "--columns gx=GyroR,gy=GyroP,gz=GyroY" in loaded.decisions.layout
    assert loaded.poses.n == len(turned.dwells)
    named = load_with_segmentation(path, rate=100.0, columns="gx=GyroR,gy=GyroP,gz=GyroY")
    assert "gx←GyroR, gy←GyroP, gz←GyroY" in named.decisions.columns.value and named.recording.gyro is not None
    assert "gyro not read" not in named.decisions.layout


def _stream_rows(turned, dt_column: bool) -> str:
    """The Android IMU stream's rows (98Glopes/imu-jupyter): s since boot, then each sensor's type number before
    its triple (3 accelerometer m/s², 4 gyroscope rad/s, 5 magnetometer µT), blank lines between rows, and in
    ``static.csv`` a last field of the step since the row before."""
    f = turned.frame
    t = 683432.72989 + f["t"].to_numpy()
    acc, gyro = G * f[["ax", "ay", "az"]].to_numpy(), f[["gx", "gy", "gz"]].to_numpy()
    tail = (lambda k: f" ,  {0.01 if k else 0.0}") if dt_column else (lambda k: "")
    return "".join(f"{s:.5f}, 3, " + ", ".join(f"{v:7.3f}" for v in a) + ", 4, " + ", ".join(f"{v:7.3f}" for v in w)
                   + ", 5,  -6.700,-15.900, 14.100" + tail(k) + "\n  \n"
                   for k, (s, a, w) in enumerate(zip(t, acc, gyro)))


def test_label_columns_of_one_whole_number_are_set_aside(turned, tmp_path, capsys):
    from helpers.cli_run import run

    path = tmp_path / "log11.csv"
    path.write_text(_stream_rows(turned, dt_column=False))
    loaded = load_with_segmentation(path)  # before: "13 unnamed columns fit no common layout", e.g. ax=2
    assert loaded.decisions.columns.value == "t←#1, ax←#3, ay←#4, az←#5, gx←#7, gy←#8, gz←#9"
    assert "columns 2, 6, 10, 11, 12, 13 not read" in loaded.decisions.layout  # the labels and the magnetometer
    assert loaded.poses.n == len(turned.dwells)
    path = tmp_path / "static.csv"  # a 14th field (the step): still no common layout, the example names the axes
    path.write_text(_stream_rows(turned, dt_column=True))
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "e.g. --columns t=1,ax=3,ay=4,az=5" in err and "columns 2, 6, 10 set aside" in err


#: NXP's IMU data logger's footer (kalebburnham/IMU-Research, Nudge.dat): a blank line, then ``%`` lines of the
#: samples' statistics, one of 13 fields (its names' line carries a second ``%``).
NXP_FOOTER = ("\n% Sample Count Used for mean/std calculations = 316.\n\n"
              "%                                  MagX     MagY     MagZ     AccX     AccY     AccZ     % GyroR   GyroP"
              "    GyroY  LButton  RButton\n"
              "% Means                      :  371.000  -66.000  585.000    1.000    2.000  353.000 -515.000 -534.000"
              " -526.000    0.000    0.000 \n"
              "% Maximums                   :      387      -13      589       31      110      359     -514     -533"
              "     -454        0        0 \n")


@pytest.mark.parametrize("engine", ["numpy", "pyarrow", "pandas"])
def test_comment_lines_among_and_after_the_data_are_skipped_and_counted(turned, tmp_path, monkeypatch, engine):
    from optcal.data import text

    rows = _nxp_rows(turned).splitlines(keepends=True)
    if engine == "pyarrow":  # its rows' trailing blank is an empty field to pyarrow, which then leaves them to pandas
        rows = [r.rstrip(" \n") + "\n" for r in rows]
    middle = len(rows) // 2  # a pause noted among the rows, in the other loggers' marks, one indented
    rows[middle:middle] = ["  // paused\n", "; resumed\n", "# still\n"]
    path = tmp_path / "Nudge.dat"
    path.write_text("".join(rows) + NXP_FOOTER)
    if engine != "numpy":  # the large files' paths, on a small file
        monkeypatch.setattr(text, "SMALL_FILE_BYTES", 0)
    if engine == "pandas":  # pyarrow's reader declines (e.g. not installed)
        monkeypatch.setattr(text, "arrow_streamed_block", lambda *args: None)
    _, parsed = text.read_numbers(path)
    footer = len(rows) + 2 + np.array([0, 2, 3, 4])  # the file's lines of the footer's % lines (1-based)
    lines = [middle + 1, middle + 2, middle + 3, *footer.tolist()]
    assert parsed.engine == ("pyarrow" if engine == "pyarrow" else "pandas")  # numpy declines a comment line
    assert parsed.comments is not None and list(parsed.comments.lines) == lines
    assert parsed.comments.marks == ("//", ";", "#", "%")
    assert parsed.n_rows == len(turned.frame) and not parsed.non_numeric
    loaded = load_with_segmentation(path, rate=100.0)
    assert f"7 comment line(s) among the data skipped (lines {lines[0]}-{lines[-1]}" in loaded.decisions.layout
    assert loaded.poses.n == len(turned.dwells)
    clean = tmp_path / "clean.dat"
    clean.write_text(_nxp_rows(turned))
    assert np.allclose(loaded.recording.acc, load_with_segmentation(clean, rate=100.0).recording.acc)
