"""The accelerometer's units heard where the physics holds (docs/rest-model.md, the fourth sweep's Emkijen row).

Emkijen's spinning flight (m/s², ``t,ax,ay,az,wx,wy,wz``) moves most of the time: its whole-file median |a| is
54.5, so it was read as raw counts and ``--units m/s^2`` refused as contradicting the data.  Its quiet stretches
read |a| = 9.8 and none of its samples is a whole number (raw counts all are).  Reproduced on a GENERATED flight:
six 4-s rests in six orientations, 10-s spins between them (60 m/s² of centripetal acceleration with a 2-Hz
wobble).  The control: the same flight in raw counts (whole numbers, 16384 per g) stays counts.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli_run import run
from helpers.vmu931 import write_vmu931
from optcal.data.static import SPINNING_STRETCHES

FS = 100.0
G = 9.80665
LSB_G = 16384.0


def _flight(seed: int = 0) -> np.ndarray:
    """Specific force (n, 3) in m/s²: rests in six orientations, spins between them."""
    rng = np.random.default_rng(seed)
    ups = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], dtype=float)
    parts = []
    for k, up in enumerate(ups):
        parts.append(np.tile(G * up, (int(4 * FS), 1)))
        if k < len(ups) - 1:
            t = np.arange(int(10 * FS)) / FS
            spin = np.column_stack([60.0 + 10.0 * np.sin(2 * np.pi * 2.0 * t),
                                    G * np.cos(2 * np.pi * 0.5 * t), G * np.sin(2 * np.pi * 0.5 * t)])
            parts.append(spin)
    a = np.vstack(parts)
    return a + 0.02 * rng.normal(size=a.shape)  # 2 mg of noise at rest


def _write(path, a: np.ndarray, fmt: str) -> None:
    t = np.arange(len(a)) / FS
    path.write_text("t,ax,ay,az\n" + "".join(f"{s:.4f}," + ",".join(fmt.format(v) for v in row) + "\n"
                                             for s, row in zip(t, a)))


def test_a_moving_recording_in_m_s2_is_read_in_m_s2_from_its_quiet_stretches(tmp_path, capsys):
    a = _flight()
    assert np.median(np.linalg.norm(a, axis=1)) > 50.0  # the whole file's median says counts
    path = tmp_path / "flight.csv"
    _write(path, a, "{:.8f}")
    code, out, err = run(["segment", path], capsys)
    assert code == 0, err
    units = next(line for line in out.splitlines() if line.strip().startswith("units:"))
    assert "units: m/s^2" in units and "quiet stretches" in units, units
    code, out, err = run(["segment", path, "--units", "m/s^2"], capsys)  # was refused: "pass --units counts"
    assert code == 0, err
    assert "given with --units" in out and "agrees" in out


def test_the_same_flight_in_raw_counts_stays_counts(tmp_path, capsys):
    path = tmp_path / "counts.csv"
    _write(path, np.round(_flight() / G * LSB_G), "{:.0f}")
    code, out, err = run(["segment", path], capsys)
    assert code == 0, err
    units = next(line for line in out.splitlines() if line.strip().startswith("units:"))
    assert "units: counts" in units and "quiet stretches" not in units, units
    code, out, err = run(["segment", path, "--units", "m/s^2"], capsys)  # its quiet |a| is 16384: refused
    assert code == 2 and "pass --units counts" in err and err.count("\n") == 1


# ------------------------------------------------------------------ a steady spin is quiet, but not at rest
def _steady_spin(gyro_per_rad_s: float, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """A 10-s rest (z up), a 2-s spin-up, then 60 s of a steady 12 rad/s spin about z with the sensor 0.3 m
    off the axis (43 m/s² of centripetal acceleration, constant in the sensor's frame): (acc m/s², gyro)."""
    rng = np.random.default_rng(seed)
    w = np.concatenate([np.zeros(int(10 * FS)), np.linspace(0.0, 12.0, int(2 * FS)), np.full(int(60 * FS), 12.0)])
    a = np.column_stack([-0.3 * w**2, np.zeros(w.size), np.full(w.size, G)]) + 0.02 * rng.normal(size=(w.size, 3))
    g = np.column_stack([np.full(w.size, 0.01), np.full(w.size, -0.02), w]) + 0.01 * rng.normal(size=(w.size, 3))
    return a, g * gyro_per_rad_s


@pytest.mark.parametrize(("names", "per_rad_s"), [("wx,wy,wz", 1.0), ("gx_dps,gy_dps,gz_dps", float(np.degrees(1.0)))])
def test_a_steady_spin_is_not_a_quiet_stretch_where_the_gyro_turns(tmp_path, capsys, names, per_rad_s):
    """Emkijen's flight: half its quiet blocks spin at ~12 rad/s (their noise at the floor, |a| = 44 m/s²).  The
    steady spin alone is quiet for the accelerometer: before, its quiet median |a| was the spin's 44 and the file
    refused ("cannot tell the units"); now the blocks whose gyro is over 1 °/s off its rest reading (in °/s as
    stated, or as the smaller of rad/s and °/s where unstated) are set aside and the rest's 9.8 m/s² is heard."""
    a, g = _steady_spin(per_rad_s)
    assert np.median(np.linalg.norm(a, axis=1)) > 40.0  # the whole file's median is the spin's
    t = np.arange(len(a)) / FS
    path = tmp_path / "spin.csv"
    path.write_text(f"t,ax,ay,az,{names}\n" + "".join(
        f"{s:.4f}," + ",".join(f"{v:.8f}" for v in (*ra, *rg)) + "\n" for s, ra, rg in zip(t, a, g)))
    code, out, err = run(["segment", path], capsys)
    units = next(line for line in (out + err).splitlines() if line.strip().startswith(("units:", "error:")))
    assert "units: m/s^2" in units and "set aside as turning" in units, units
    assert ("deg/s as stated" if per_rad_s != 1.0 else "bounded as °/s") in units


# ------------------------------------------------------------------ the --columns example on a split stamp
def test_a_split_stamps_columns_example_names_the_files_positions_and_reads_the_stamp(tmp_path, capsys):
    """A headerless ``secs,nsecs,ax,ay,az`` file (ROS's header.stamp, the third sweep's acc2.csv): its columns
    reason's example said ``--columns t=1,ax=2,ay=3,az=4``, column 2 being the stamp's ns; and ``t=1`` read the
    whole seconds alone (100 rows a stamp).  Now the example names the file's positions (ax=3) and t=1 reads the
    stamp as the layout does: the same rate either way."""
    a = _flight()[: int(20 * FS)]
    t = np.arange(len(a)) / FS
    ns = np.round(t * 1e9).astype(np.int64) + 1696324304 * 1_000_000_000
    path = tmp_path / "acc2.csv"
    path.write_text("".join(f"{s},{f:9d}," + ",".join(f"{v:.6f}" for v in row) + "\n"
                            for s, f, row in zip(ns // 1_000_000_000, ns % 1_000_000_000, a)))
    code, out, err = run(["segment", path], capsys)
    assert code == 0, err
    assert "e.g. --columns t=1,ax=3,ay=4,az=5" in out
    time_line = next(line for line in out.splitlines() if line.strip().startswith("time:"))
    code, out, err = run(["segment", path, "--columns", "t=1,ax=3,ay=4,az=5"], capsys)
    assert code == 0, err
    assert next(line for line in out.splitlines() if line.strip().startswith("time:")) == time_line
    assert "whole seconds and ns of the second" in out


# ------------------------------------------------------------------ a column of words naming the sensor, headered
def test_a_headered_attribute_column_names_the_bare_axes(tmp_path, capsys):
    """Variense VMU931's headered exports (``Attribute,Time stamp,x,y,z``, ``Acceleration`` / ``Gyroscope`` /
    ``Magnetometer`` in every row; Alanzwang/vmu931): before, "no accelerometer column(s)", ``--columns`` asked for;
    now the word names the triple (the gyroscope's: the gyro's log; the magnetometer's: refused naming
    ``--sensor mag``, which reads it: tests/families/test_mag_vmu931.py), the time column by its name."""
    files = write_vmu931(tmp_path, 63156, header=True)
    n = 3000
    code, out, err = run(["segment", files["acceleration"], "--time-unit", "ms"], capsys)
    assert code == 0, err
    assert "columns: ax←x, ay←y, az←z, t←Time stamp" in out and "column 'Attribute'" in out
    code, out, err = run(["allan", files["gyroscope"], "--time-unit", "ms", "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["sensor"] == "gyro" and summary["log"]["n_samples"] == n
    code, out, err = run(["segment", files["magnetometer"]], capsys)
    assert code == 2 and "optcal calibrate FILE --sensor mag reads it" in err and err.count("\n") == 1


def test_a_column_of_words_that_names_no_sensor_still_asks_for_columns(tmp_path, capsys):
    """The control: a word column naming no sensor (a session label) leaves bare x, y, z unread, ``--columns``
    asked for, as before."""
    rows = "".join(f"session_a,{5 * k},0.01,0.02,0.98\n" for k in range(400))
    path = tmp_path / "labelled.csv"
    path.write_text("label,time,x,y,z\n" + rows)
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "--columns" in err and err.count("\n") == 1


@pytest.mark.parametrize("flags", [[], ["--no-gyro-gate"]])
def test_a_steady_spin_is_not_a_rest_and_does_not_set_the_gyros_bias(tmp_path, capsys, flags):
    """The same flight, its units now right: before, one pose was the 60-s spin (|a| 4.5 g) and the true rest was
    set aside as "gyro off its bias" (the bias followed the majority of the still blocks, which spin at 12 rad/s).
    A rest reads |a| = 1 g and a gyro within a MEMS gyro's bias (RestBounds): the rest is the one pose, the spin's
    blocks are said as set aside from the bias; without the gyro as evidence the spin is rejected by its |a|;
    --keep-spins gives the spin as a pose again."""
    a, g = _steady_spin(1.0)
    t = np.arange(len(a)) / FS
    path = tmp_path / "spin.csv"
    path.write_text("t,ax,ay,az,wx,wy,wz\n" + "".join(
        f"{s:.4f}," + ",".join(f"{v:.8f}" for v in (*ra, *rg)) + "\n" for s, ra, rg in zip(t, a, g)))
    code, out, err = run(["segment", path, "--json", *flags], capsys)
    assert code == 0, err
    seg = json.loads(out)["segmentation"]
    assert len(seg["intervals"]) == 1, seg["intervals"]
    pose = seg["intervals"][0]
    assert pose["t_end"] < 10.0 and abs(np.linalg.norm(pose["mean"]) - G) < 0.05, pose
    if flags:
        assert seg["evidence"][SPINNING_STRETCHES] == 1
    else:
        assert "--keep-spins keeps them" in seg["rest_bounds"]
    code, out, err = run(["segment", path, "--json", "--keep-spins", *flags], capsys)  # the override: as before
    assert code == 0, err
    assert any(iv["t_start"] > 10.0 for iv in json.loads(out)["segmentation"]["intervals"])  # the spin a pose again
