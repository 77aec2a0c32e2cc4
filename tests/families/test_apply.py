"""``optcal apply`` and ``optcal check`` with every cal_type, on a recording with a planted temperature coefficient."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import optcal.families.calibration_files as calibration_files
from helpers.cli_run import run
from optcal.families.caltypes import ExtendedCalibration, FitPoses, SixPositionCalibration
from optcal.families.caltypes.apply import STATUS_COLUMN
from optcal.data import load
from optcal.families.simulate.effects import recording_with_effect
from optcal.core.model import STANDARD_GRAVITY

#: 1 mg/°C on z over the 16 °C warm-up and cool-down of the generator: ±8 mg, far above the noise.
PLANTED = 1e-3


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A counts recording with a planted temperature bias, its lumped fit and the extended truth."""
    from optcal.families.accel.calibration import calibrate

    d = tmp_path_factory.mktemp("apply")
    frame, truth = recording_with_effect("temperature_bias", "z", PLANTED, n_poses=30, seed=3)
    frame.to_csv(d / "rec.csv", index=False)
    poses = load(d / "rec.csv")
    calibrate(poses, method="mle").save(d / "lumped.json")
    ExtendedCalibration.from_model(truth.model, "counts", fitted_on=FitPoses.of(poses)).save(d / "extended.json")
    return d, frame, poses



def rms_of_static_poses(path) -> float:
    poses = load(path)
    assert poses.units == "g"
    return float(np.sqrt(np.mean((np.linalg.norm(poses.acc, axis=1) - 1.0) ** 2)))


def test_extended_calibration_halves_the_error_of_the_lumped_one(files, capsys):
    """Acceptance: apply, then the static poses of the output: extended rms ≤ half the lumped rms."""
    d, frame, poses = files
    rms = {}
    for name in ("lumped", "extended"):
        code, out, err = run(["apply", d / f"{name}.json", d / "rec.csv", "-o", d / f"{name}.csv"], capsys)
        assert code == 0, err
        assert f"wrote {len(frame)} rows" in out
        rms[name] = rms_of_static_poses(d / f"{name}.csv")
    assert rms["extended"] <= 0.5 * rms["lumped"]
    # the same figures as the calibrations applied to the pose means directly
    ext = calibration_files.load(d / "extended.json")
    direct = ext.norm_errors(poses.acc, poses.temp, poses.t)
    assert rms["extended"] == pytest.approx(np.sqrt(np.mean(direct**2)), rel=1e-6)


def test_every_column_passes_through_and_no_row_is_dropped(files, capsys):
    d, frame, _ = files
    broken = frame.copy()
    broken.loc[5, "ax"] = np.nan
    broken["label"] = "still"
    broken.to_csv(d / "broken.csv", index=False)
    code, out, err = run(["apply", d / "extended.json", d / "broken.csv", "-o", d / "broken_out.csv"], capsys)
    assert code == 0, err
    result = pd.read_csv(d / "broken_out.csv")
    assert len(result) == len(frame)
    assert list(result.columns) == ["t", "ax_g", "ay_g", "az_g", "gx", "gy", "gz", "temp", "label", STATUS_COLUMN]
    for column in ("t", "gx", "gy", "gz", "temp"):
        np.testing.assert_array_equal(result[column].to_numpy(), frame[column].to_numpy())
    assert (result["label"] == "still").all()
    assert result.loc[5, STATUS_COLUMN] == "non_finite" and np.isnan(result.loc[5, "ax_g"])
    # samples colder than the poses' temperature span (the first of the warm-up) are marked, with the amount said
    assert "out_of_range" in set(result[STATUS_COLUMN]) and "below the fitted range" in out
    counts = result[STATUS_COLUMN].value_counts().to_dict()
    assert f"ok {counts['ok']}" in out and "non_finite 1" in out


def test_units_parquet_and_a_pose_table_with_a_sixpos_calibration(files, tmp_path, capsys):
    d, frame, _ = files
    code, _, err = run(["apply", d / "lumped.json", d / "rec.csv", "-o", tmp_path / "ms2.parquet", "--units", "m/s^2"], capsys)
    assert code == 0, err
    ms2 = pd.read_parquet(tmp_path / "ms2.parquet")
    cal = calibration_files.load(d / "lumped.json")
    expected = cal.correct(frame[["ax", "ay", "az"]].to_numpy(float)) * STANDARD_GRAVITY
    np.testing.assert_allclose(ms2[["ax_m_s2", "ay_m_s2", "az_m_s2"]].to_numpy(), expected, rtol=0, atol=1e-12)
    # a pose table in m/s^2 through a sixpos_full calibration for g input: converted, then W a + V
    W = np.array([[1.01, 0.002, -0.003], [0.001, 0.99, 0.004], [-0.002, 0.003, 1.02]])
    V = np.array([0.01, -0.02, 0.03])
    SixPositionCalibration(W, V, "g").save(tmp_path / "six.json")
    acc_g = np.array([[0, 0, 1.0], [0, 1.0, 0], [1.0, 0, 0], [0.6, 0.8, 0], [0, -0.6, 0.8]])
    table = pd.DataFrame(acc_g * STANDARD_GRAVITY, columns=["ax", "ay", "az"])
    table["sigma"] = 0.01
    table.to_csv(tmp_path / "poses.csv", index=False)
    code, out, err = run(["apply", tmp_path / "six.json", tmp_path / "poses.csv", "-o", tmp_path / "poses_out.csv"], capsys)
    assert code == 0, err
    assert "pose table" in out and "DATA converted from m/s^2 to g" in out
    result = pd.read_csv(tmp_path / "poses_out.csv")
    np.testing.assert_allclose(result[["ax_g", "ay_g", "az_g"]].to_numpy(), acc_g @ W.T + V, atol=1e-12)
    np.testing.assert_array_equal(result["sigma"], 0.01)


def test_apply_refuses_in_one_line(files, tmp_path, capsys):
    d, frame, _ = files
    frame.drop(columns=["temp"]).to_csv(tmp_path / "no_temp.csv", index=False)
    code, out, err = run(["apply", d / "extended.json", tmp_path / "no_temp.csv", "-o", tmp_path / "x.csv"], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("error: ") and "no temperature column" in err
    code, _, err = run(["apply", d / "lumped.json", d / "rec.csv", "-o", tmp_path / "x.txt"], capsys)
    assert code == 2 and ".csv or .parquet" in err
    code, _, err = run(["apply", d / "lumped.json", d / "rec.csv", "-o", tmp_path / "x.csv", "--data-units", "g"], capsys)
    # g declared on data in counts is refused when DATA is read (the norm contradicts it, issue 11)
    assert code == 2 and "units g (given with --units) contradict the data" in err


def test_check_accepts_every_cal_type(files, capsys):
    d, _, poses = files
    results = {}
    for name in ("lumped", "extended"):
        code, out, err = run(["check", d / f"{name}.json", d / "rec.csv", "--json"], capsys)
        assert code == 0, err
        results[name] = json.loads(out)
        assert results[name]["calibration"]["cal_type"] == name
    ext = calibration_files.load(d / "extended.json")
    after = [p["after_g"] for p in results["extended"]["poses"]]
    np.testing.assert_allclose(after, ext.norm_errors(poses.acc, poses.temp, poses.t), atol=1e-12)
    assert results["extended"]["rms_after_g"] <= 0.5 * results["lumped"]["rms_after_g"]


def test_a_headerless_file_keeps_its_columns_by_position(files, tmp_path, capsys):
    """A headerless `ax ay az gx gy gz` log (mikoff's layout): corrected in place, the gyro columns passed through."""
    d, frame, poses = files
    headerless = tmp_path / "log.txt"
    frame[["ax", "ay", "az", "gx", "gy", "gz"]].to_csv(headerless, sep=" ", header=False, index=False)
    code, out, err = run(["apply", d / "lumped.json", headerless, "--rate", "100", "-o", tmp_path / "out.csv"], capsys)
    assert code == 0, err
    result = pd.read_csv(tmp_path / "out.csv")
    assert list(result.columns) == ["ax_g", "ay_g", "az_g", "4", "5", "6", STATUS_COLUMN]
    assert len(result) == len(frame)
    np.testing.assert_array_equal(result["4"].to_numpy(), frame["gx"].to_numpy())
    lumped = calibration_files.load(d / "lumped.json")
    expected = lumped.correct(frame[["ax", "ay", "az"]].to_numpy(float))
    np.testing.assert_allclose(result[["ax_g", "ay_g", "az_g"]].to_numpy(), expected, rtol=1e-9, atol=1e-12)
