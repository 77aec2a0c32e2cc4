"""A gyroscope's still log with no accelerometer columns (a gyro's Allan recording ``t, gx, gy, gz``; a ROS
``rostopic echo -p /imu`` export keeping only ``angular_velocity``): ``optcal allan FILE`` analyses the gyro's noise
(``--sensor gyro`` implied, said in the units decision); every command that needs an accelerometer refuses the file
in one line naming ``--sensor gyro``.  Before, every reading refused it as "no accelerometer column(s)".

Generated files only (no recording is committed).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import optcal
from helpers.cli_run import run
from optcal.data.gyro_log import NO_ACCELEROMETER
from optcal.errors import InputError

FS = 100.0
SIGMA = 0.002  # rad/s per sample: angle random walk σ/√f_s = 2e-4 rad/s/√Hz, a MEMS gyro's
BIAS = (0.01, -0.02, 0.005)


def _gyro(n: int, rng: int = 3) -> np.ndarray:
    return np.asarray(BIAS) + SIGMA * np.random.default_rng(rng).normal(size=(n, 3))


def _write(path, header: str, columns: np.ndarray, time: str = ".9g") -> None:
    path.write_text(header + "\n" + "".join(f"{row[0]:{time}}," + ",".join(f"{v:.9g}" for v in row[1:]) + "\n"
                                            for row in columns))


@pytest.fixture(scope="module")
def still(tmp_path_factory):
    """120 s at 100 Hz of a still gyro in rad/s, as ``t,gx,gy,gz`` and beside an accelerometer (the same samples)."""
    folder = tmp_path_factory.mktemp("gyro_only")
    n = int(120 * FS)
    t = np.arange(n) / FS
    g = _gyro(n)
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * np.random.default_rng(4).normal(size=(n, 3))
    _write(folder / "gyro.csv", "t,gx,gy,gz", np.column_stack([t, g]))
    _write(folder / "imu.csv", "t,ax,ay,az,gx,gy,gz", np.column_stack([t, acc, g]))
    # rostopic echo -p /imu with only angular_velocity kept: %time in ns since 1970
    _write(folder / "ros.csv", "%time,field.angular_velocity.x,field.angular_velocity.y,field.angular_velocity.z",
           np.column_stack([1.6e18 + np.round(t * 1e9), g]), time=".0f")
    return folder


def _allan(capsys, *args) -> dict:
    code, out, err = run(["allan", *args, "--json", "--gyro-units", "rad/s"], capsys)
    assert code == 0, err
    return json.loads(out)


@pytest.mark.parametrize("name", ["gyro.csv", "ros.csv"])
@pytest.mark.parametrize("sensor", [[], ["--sensor", "gyro"]])
def test_a_gyro_only_still_log_gives_the_gyros_noise(still, capsys, name, sensor):
    """The gyro's angle random walk σ/√f_s, the same figures as the same samples read beside an accelerometer
    (the stand-in accelerometer changes nothing of the gyro's analysis); the units decision says why."""
    out = _allan(capsys, still / name, *sensor)
    ref = _allan(capsys, still / "imu.csv", "--sensor", "gyro")
    assert out["sensor"] == "gyro"
    for axis in "xyz":
        assert out[axis]["angle_random_walk"] == pytest.approx(SIGMA / np.sqrt(FS), rel=0.1)
        # the same samples: equal to the rate's digits (ns since 1970 held in a double step by 256 ns: 1e-5 of it)
        assert out[axis]["angle_random_walk"] == pytest.approx(ref[axis]["angle_random_walk"], rel=1e-4)
    units = out["log"]["decisions"]["units"]
    assert units["value"] == NO_ACCELEROMETER and "no accelerometer columns" in units["reason"]
    assert out["log"]["n_samples"] == ref["log"]["n_samples"] == int(120 * FS)


def test_a_gyro_only_log_that_turns_is_refused_as_not_still(tmp_path, capsys):
    """The gyro alone judges the stillness: 40 s of a slow sway (±0.3 rad/s about z) in 120 s is refused as not
    still (the stand-in accelerometer holds still, so a rest the gyro ends is ended by the gyro)."""
    n = int(120 * FS)
    t = np.arange(n) / FS
    g = _gyro(n)
    moving = (t > 40) & (t < 80)
    g[moving, 2] += 0.3 * np.sin(2 * np.pi * 0.5 * t[moving])
    path = tmp_path / "turning.csv"
    _write(path, "t,gx,gy,gz", np.column_stack([t, g]))
    code, out, err = run(["allan", path], capsys)
    assert code == 2 and "the log is not still" in err and err.count("\n") == 1


def test_the_accelerometers_commands_refuse_a_gyro_only_log_naming_sensor_gyro(still, capsys):
    """``--sensor acc`` (or both), segment and calibrate, and optcal.load: one line naming ``--sensor gyro``."""
    for args in (["allan", still / "gyro.csv", "--sensor", "acc"], ["allan", still / "gyro.csv", "--sensor", "both"],
                 ["segment", still / "gyro.csv"], ["calibrate", still / "ros.csv"]):
        code, out, err = run(args, capsys)
        assert code == 2 and err.count("\n") == 1 and "--sensor gyro" in err, (args, err)
        assert "no accelerometer column(s)" in err and "Traceback" not in err
    with pytest.raises(InputError, match="--sensor gyro"):
        optcal.load(still / "gyro.csv")


def test_a_gyro_only_log_refuses_the_accelerometers_units(still, capsys):
    """``--units`` names the accelerometer's units: on a file with no accelerometer it is refused, naming
    ``--gyro-units``."""
    code, out, err = run(["allan", still / "gyro.csv", "--units", "g"], capsys)
    assert code == 2 and "--gyro-units" in err and err.count("\n") == 1


def test_a_headerless_gyro_log_by_position_with_a_window(tmp_path, capsys):
    """Variense VMU931's export (``gyroscope,411480,-0.286,0.042,0.142``: the quantity's name, a stamp in ms, x, y, z;
    no header): read by position, the columns said as positions (not as names ``2``, ``3``), a refusal's decisions
    saying no accelerometer (not the stand-in's g), and ``--window`` (which re-converts the stand-in) analysed."""
    n = int(60 * FS)
    stamps = 411480 + np.arange(n) * 10  # ms
    g = _gyro(n)
    path = tmp_path / "gyroscope_20180927.csv"
    path.write_text("".join(f"gyroscope,{s},{x:.9g},{y:.9g},{z:.9g}\n" for s, (x, y, z) in zip(stamps, g)))
    columns = ["--columns", "t=2,gx=3,gy=4,gz=5", "--gyro-units", "rad/s"]
    code, out, err = run(["allan", path, *columns], capsys)  # the stamps in ms read as seconds: refused
    assert code == 2 and "--time-unit ms" in err
    assert "columns: t←#2, gx←#3, gy←#4, gz←#5" in out and f"units: {NO_ACCELEROMETER} (no accelerometer" in out
    code, out, err = run(["allan", path, *columns, "--time-unit", "ms", "--window", "420:", "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["sensor"] == "gyro" and summary["log"]["n_samples"] == int(np.count_nonzero(stamps >= 420000))
    assert summary["x"]["angle_random_walk"] == pytest.approx(SIGMA / np.sqrt(FS), rel=0.1)


def test_sensor_loggers_gyroscope_file_alone(tmp_path, capsys):
    """Sensor Logger's ``Gyroscope.csv`` (``time,seconds_elapsed,z,y,x``, rad/s by its UNITS.md; BennyJHui/imu_data,
    sewonm/Robot-Logger-Test) given to ``optcal allan`` alone: its bare axes read as the gyro's by the file's name
    (before: "no accelerometer column(s)" naming only --columns), the unit stated, the noise analysed."""
    n = int(60 * FS)
    t = np.arange(n) / FS
    g = _gyro(n)
    path = tmp_path / "Gyroscope.csv"
    path.write_text("time,seconds_elapsed,z,y,x\n" + "".join(
        f"{int(1.76e18 + s * 1e9)},{s:.6f},{z:.9g},{y:.9g},{x:.9g}\n" for s, (x, y, z) in zip(t, g)))
    code, out, err = run(["allan", path, "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["sensor"] == "gyro" and summary["units"]["input"] == "rad/s"
    assert "stated by the file" in summary["log"]["units_reason"]
    for axis in "xyz":
        assert summary[axis]["angle_random_walk"] == pytest.approx(SIGMA / np.sqrt(FS), rel=0.1)
