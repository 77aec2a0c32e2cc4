"""``optcal calibrate --imu``, ``optcal check`` and ``optcal apply`` on an IMU calibration, end to end."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import optcal
import optcal.families.calibration_files
from optcal.cli.main import main
from optcal.families.simulate.gyro import reference_gyro, simulate_imu


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, object]:
    rec = simulate_imu(optcal.lu2017_reference_model(), reference_gyro(1.0, rng=1), 14, rng=21, dwell_s=2.0,
                       move_s=1.0, acc_noise=0.001, gyro_noise=0.002)
    path = tmp_path_factory.mktemp("imu") / "imu.csv"
    frame = pd.DataFrame({"t": rec.t, "ax": rec.acc[:, 0], "ay": rec.acc[:, 1], "az": rec.acc[:, 2],
                          "gx": rec.gyro[:, 0], "gy": rec.gyro[:, 1], "gz": rec.gyro[:, 2]})
    frame.to_csv(path, index=False)
    return str(path), rec


def test_calibrate_imu_check_apply(recording, tmp_path, capsys) -> None:
    path, rec = recording
    cal_path = tmp_path / "imu.json"
    assert main(["calibrate", path, "--imu", "--json", "-o", str(cal_path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cal_type"] == "imu" and out["gyro_units"]["input"] == "rad/s"
    assert out["gravity_prediction"]["n_moves"] == 13
    assert out["gravity_prediction"]["rms_deg_after"] < 0.1 * out["gravity_prediction"]["rms_deg_before"]
    cal = optcal.families.calibration_files.load(cal_path)
    assert cal.cal_type == "imu"

    assert main(["check", str(cal_path), path, "--json"]) == 0
    checked = json.loads(capsys.readouterr().out)["gravity_prediction"]
    assert checked["rms_deg_after"] == pytest.approx(out["gravity_prediction"]["rms_deg_after"], rel=1e-9)

    out_csv = tmp_path / "applied.csv"
    assert main(["apply", str(cal_path), path, "-o", str(out_csv)]) == 0
    applied = pd.read_csv(out_csv)
    assert {"gx_rad_s", "gy_rad_s", "gz_rad_s"} <= set(applied.columns) and len(applied) == rec.t.size
    rate = applied[["gx_rad_s", "gy_rad_s", "gz_rad_s"]].to_numpy()
    assert np.allclose(rate, cal.correct_gyro(rec.gyro, rec.acc))


def test_apply_reads_the_gyro_from_its_own_file(recording, tmp_path, capsys) -> None:
    """imu_tk's layout (acc and gyro in two files, ``t x y z``): ``apply --gyro-file`` writes the calibrated gyro."""
    path, rec = recording
    acc_file, gyro_file = tmp_path / "acc.txt", tmp_path / "gyro.txt"
    np.savetxt(acc_file, np.column_stack([rec.t, rec.acc]), fmt="%.9g")
    np.savetxt(gyro_file, np.column_stack([rec.t, rec.gyro]), fmt="%.9g")
    cal_path = tmp_path / "imu.json"
    assert main(["calibrate", str(acc_file), "--gyro-file", str(gyro_file), "--imu", "-o", str(cal_path)]) == 0
    cal = optcal.families.calibration_files.load(cal_path)
    out_csv = tmp_path / "applied.csv"
    assert main(["apply", str(cal_path), str(acc_file), "--gyro-file", str(gyro_file), "-o", str(out_csv)]) == 0
    applied = pd.read_csv(out_csv)
    assert len(applied) == rec.t.size and list(applied.columns)[-4:] == ["gx_rad_s", "gy_rad_s", "gz_rad_s",
                                                                          "optcal_status"]
    rate = applied[["gx_rad_s", "gy_rad_s", "gz_rad_s"]].to_numpy()
    assert np.allclose(rate, cal.correct_gyro(rec.gyro, rec.acc), atol=1e-7)  # the files' 9 digits
    capsys.readouterr()


def test_imu_options_need_imu(recording, capsys) -> None:
    path, _ = recording
    assert main(["calibrate", path, "--joint"]) == 2
    assert capsys.readouterr().err.startswith("error: --joint and --g-sensitivity apply with --imu only")


def test_imu_without_gyro_columns(tmp_path, capsys) -> None:
    rec = simulate_imu(optcal.lu2017_reference_model(), reference_gyro(1.0, rng=1), 12, rng=22, acc_noise=0.001)
    path = tmp_path / "acc_only.csv"
    pd.DataFrame({"t": rec.t, "ax": rec.acc[:, 0], "ay": rec.acc[:, 1], "az": rec.acc[:, 2]}).to_csv(path, index=False)
    assert main(["calibrate", str(path), "--imu"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "no gyro columns" in err and err.count("\n") == 1


def test_allan_gyro_angle_random_walk(tmp_path, capsys) -> None:
    """A still log with white gyro noise σ at f_s: angle random walk N = σ/√f_s, in rad/s/√Hz (Kalibr's units)."""
    rng = np.random.default_rng(5)
    n, fs, sigma = 60000, 100.0, 0.002
    t = np.arange(n) / fs
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * rng.normal(size=(n, 3))
    gyro = np.array([0.01, -0.02, 0.005]) + sigma * rng.normal(size=(n, 3))
    path = tmp_path / "still.csv"
    pd.DataFrame({"t": t, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
                  "gx": gyro[:, 0], "gy": gyro[:, 1], "gz": gyro[:, 2]}).to_csv(path, index=False)
    assert main(["allan", str(path), "--sensor", "gyro", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["sensor"] == "gyro" and out["units"]["input"] == "rad/s"
    for axis in "xyz":
        assert out[axis]["angle_random_walk"] == pytest.approx(sigma / np.sqrt(fs), rel=0.1)
        # white noise only: no rate random walk, and its upper bound σ(τ)√(3/τ) = N√3/τ at the longest τ
        tau = out[axis]["rate_random_walk_largest_consistent_tau_s"]
        assert out[axis]["rate_random_walk"] is None and out[axis]["ci"]["rate_random_walk"] is None
        assert out[axis]["rate_random_walk_largest_consistent"] == pytest.approx(sigma / np.sqrt(fs) * np.sqrt(3) / tau, rel=0.5)
        assert out[axis]["rate_random_walk_bound"]["value"] > out[axis]["rate_random_walk_largest_consistent"]
    assert out["kalibr"]["gyroscope_noise_density"] == pytest.approx(sigma / np.sqrt(fs), rel=0.1)
    assert out["kalibr"]["gyroscope_random_walk"] is None
    assert main(["allan", str(path), "--sensor", "gyro", "--gyro-units", "counts"]) == 2
    assert "counts-per-rad/s" in capsys.readouterr().err
