"""The main job in five lines of Python equals the command line's (issue 40's acceptance), on every shared recording."""

from __future__ import annotations

import json

import pytest

import optcal
from optcal.errors import InputError, OptcalError
from tests.helpers.cli_run import run
from tests.helpers.common import SHARED

#: Every recording of ../shared/data with the flags the README and the data tests give for it
#: (relative path, Python keywords, the same as command-line flags).
RECORDINGS: list[tuple[str, dict[str, object], list[str], dict[str, object]]] = [
    ("imutk-xsens/xsens_imutk.csv", {}, [], {}),
    # 10 rests of which one pair's tilt leaves A_xy weakly determined: refused unless allowed (its own flag)
    ("mpu6050-imucalibration/example_data_calibration.csv", {}, ["--allow-degenerate"], {"allow_degenerate": True}),
    # imucal's six faces and three turns: Ferraris' method (the self-calibration refuses its six faces)
    ("imucal-ferraris/example_ferraris_session.csv", {"rate": 102.4}, ["--rate", "102.4", "--method", "ferraris"],
     {"method": "ferraris"}),
    ("mikoff-mpu9150/imu0.log", {"rate": 100}, ["--rate", "100"], {}),  # 100 Hz by its PROVENANCE.md
    ("ckexplorer-holds/acc_log.csv", {"rate": 50}, ["--rate", "50"], {}),
    ("divemove-tag/magnt_accel_calib.nc", {}, [], {}),
    ("hassan-innalabs-m3/CalibrationOfLowCostTriaxialInertialSensors.mat", {}, [], {}),
    # no rate stated upstream: the rate its PROVENANCE.md assumes
    ("hassan-lis3dh-phone/MobileAccData30orientationRawSample01.mat", {"rate": 50}, ["--rate", "50"], {}),
]


def _without_run_details(saved: dict) -> dict:
    """A saved calibration without what differs between two runs of one fit (times, the command line)."""
    drop = {"created", "elapsed_s", "command_line", "timestamp", "wall_time_s", "solve_time_s", "t_wall", "t_proc"}
    if isinstance(saved, dict):
        return {k: _without_run_details(v) for k, v in saved.items() if k not in drop}
    if isinstance(saved, list):
        return [_without_run_details(v) for v in saved]
    return saved


@pytest.mark.parametrize("name, keywords, flags, fit", RECORDINGS, ids=[r[0].split("/")[0] for r in RECORDINGS])
def test_five_lines_of_python_equal_the_command_line(name, keywords, flags, fit, tmp_path, capsys, shared_data):
    path = SHARED / "data" / name
    if not path.exists():
        pytest.skip(f"{name} is not in ../shared/data")
    cli_json = tmp_path / "cli.json"
    code, out, err = run(["calibrate", path, *flags, "-o", cli_json], capsys)
    assert code == 0, err  # every shared recording calibrates with the flags given for it
    py_json = tmp_path / "py.json"
    r = optcal.load(path, **keywords)
    c = optcal.calibrate(r, **fit)
    c.save(py_json)
    assert _without_run_details(json.loads(py_json.read_text())) == _without_run_details(json.loads(cli_json.read_text()))


def test_a_refusal_is_the_command_lines_refusal(tmp_path, capsys, shared_data):
    path = shared_data / "mpu6050-imucalibration" / "example_data_calibration.csv"
    code, _, err = run(["calibrate", path], capsys)
    assert code == 2
    with pytest.raises(OptcalError) as refused:
        optcal.calibrate(optcal.load(path))
    assert str(refused.value).split(" (or ")[0].split(";")[0] in err  # the same refusal (the CLI names its flag)


def test_the_imu_and_the_magnetometer_in_python_equal_the_command_line(tmp_path, capsys, shared_data):
    xsens = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    code, _, err = run(["calibrate", xsens, "--imu", "-o", tmp_path / "cli_imu.json"], capsys)
    assert code == 0, err
    imu = optcal.calibrate_imu(optcal.load(xsens))
    imu.save(tmp_path / "py_imu.json")
    assert (_without_run_details(json.loads((tmp_path / "py_imu.json").read_text()))
            == _without_run_details(json.loads((tmp_path / "cli_imu.json").read_text())))
    assert imu.fit_warning  # the g-sensitivity the Xsens gyro has, said as the command line warns it
    mag = shared_data / "ckexplorer-holds" / "acc_mag_log.csv"
    code, _, err = run(["calibrate", mag, "--sensor", "mag", "-o", tmp_path / "cli_mag.json"], capsys)
    assert code == 0, err
    fitted = optcal.calibrate_mag(mag)
    fitted.save(tmp_path / "py_mag.json")
    assert (_without_run_details(json.loads((tmp_path / "py_mag.json").read_text()))
            == _without_run_details(json.loads((tmp_path / "cli_mag.json").read_text())))
    assert optcal.load_calibration(tmp_path / "py_mag.json").field_strength == fitted.calibration.field_strength
    with pytest.raises(InputError, match="known orientations"):
        optcal.calibrate_mag(mag, method="sixpos")
    with pytest.raises(InputError, match="no moves"):
        optcal.calibrate_imu(optcal.load(shared_data / "imutk-xsens" / "xsens_imutk.csv").poses)


def test_calibrate_accepts_a_path_a_reading_or_poses_and_saves_what_load_calibration_reads(tmp_path, shared_data):
    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    from_path = optcal.calibrate(path)
    reading = optcal.load(path)
    assert optcal.calibrate(reading.poses).calibration.theta.tolist() == from_path.calibration.theta.tolist()
    from_path.save(tmp_path / "c.json")
    loaded = optcal.load_calibration(tmp_path / "c.json")
    applied = optcal.apply(loaded, path, tmp_path / "out.csv")
    assert (tmp_path / "out.csv").exists() and applied.status_counts.get("ok", 0) > 0


def test_an_unknown_keyword_names_the_valid_ones(tmp_path, pose_csv):
    with pytest.raises(InputError, match="takes: allow_degenerate"):
        optcal.calibrate(pose_csv, method="svd", loss="huber")
    with pytest.raises(InputError, match="step"):
        optcal.calibrate(pose_csv, method="gd", stepsize=1.0)
    with pytest.raises(InputError, match="unknown method"):
        optcal.calibrate(pose_csv, method="magic")
    with pytest.raises(InputError, match="Reading"):
        optcal.calibrate(42)


@pytest.fixture
def pose_csv(tmp_path):
    from optcal.families.simulate.poses import simulate_poses, uniform_directions
    import numpy as np

    poses = simulate_poses(optcal.lu2017_reference_model(), uniform_directions(20, 1), 0.002, rng=3)
    path = tmp_path / "poses.csv"
    np.savetxt(path, poses.acc, delimiter=",", header="ax,ay,az", comments="")
    return path
