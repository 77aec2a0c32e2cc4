"""A gyro calibration the moves do not support is refused (issue 26, item 7), kept with --accept-gyro-fit and a warning.

The tests of :mod:`optcal.families.gyro.consistency`: the gravity-prediction residual against its noise model (angle
random walk, bias between the rests, accelerometer pose noise, time base, integration), a gyro that does not see the
moves, axes that are a column mapping or a sign, a scale that is a unit or a time base.  Before, every case below
gave exit 0, a saved ``imu`` calibration and no warning.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import optcal
import optcal.families.calibration_files
from helpers.cli_run import run_args
from optcal.core.poses import PoseTable
from optcal.data.units import GyroUnitsDecision
from optcal.errors import InputError
from optcal.families.gyro.consistency import REFUSAL_MARGIN
from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro
from optcal.families.gyro.moves import moves_from_arrays
from optcal.families.simulate.gyro import ImuRecording, reference_gyro, simulate_imu

RAD_S = GyroUnitsDecision("rad/s", "test")
#: The one-line refusal names the likely causes and the override, in the command line's words.
CAUSES = ("--columns", "--gyro-units", "--rate or the time column", "--accept-gyro-fit")


def simulated(seed: int) -> ImuRecording:
    """24 poses, 23 moves of 1.5 s at 100 Hz, noisy accelerometer (2 mg) and gyro (0.005 rad/s per sample)."""
    return simulate_imu(optcal.lu2017_reference_model(), reference_gyro(1.0, rng=seed), 24, rng=40 + seed,
                        dwell_s=2.0, move_s=1.5, acc_noise=0.002, gyro_noise=0.005)


def fit(t: np.ndarray, acc: np.ndarray, gyro: np.ndarray, rec: ImuRecording, **settings: object):
    moves = moves_from_arrays(t, acc, gyro, rec.intervals)
    accelerometer = optcal.calibrate(PoseTable(acc=moves.acc_means, sigma=moves.acc_sigma))
    return calibrate_gyro(moves, accelerometer, RAD_S, GyroSettings(**settings))


@pytest.fixture(scope="module")
def recording() -> ImuRecording:
    return simulated(1)


def test_noise_model_matches_simulated_residuals() -> None:
    """Right calibrations: χ²/dof near one (the model is the noise's), within the 99.9 % bound, no finding."""
    reduced = []
    for seed in range(4):
        rec = simulated(seed)
        cal = fit(rec.t, rec.acc, rec.gyro, rec)
        check = cal.fit_check
        assert check is not None and check["findings"] == [] and not check["residual"]["flagged"]
        assert cal.fit_warning is None
        reduced.append(check["residual"]["chi2"] / check["residual"]["dof"])
        assert any(note.startswith("fit check: ") and "within the noise model" in note for note in cal.notes)
    assert 0.5 < np.mean(reduced) < 1.3


@pytest.mark.parametrize("case, expected", [
    pytest.param("other recording's rates", r"gravity prediction .* the fit explains little of the moves",
                 id="other-rates"),
    pytest.param("noise for gyro", r"the gyro does not see the moves", id="noise"),
    pytest.param("x and y swapped",
                 r"gyro x senses 9\d\.\d° from the accelerometer's x axis, \d\.\d° from its \+y axis", id="swap-xy"),
    pytest.param("z reversed",
                 r"gyro z senses 1[78]\d\.\d° from the accelerometer's z axis, \d\.\d° from its -z axis",
                 id="minus-z"),
    pytest.param("time base doubled",
                 r"the fitted gyro scale is x 0\.[45]\d*×, y 0\.[45]\d*×, z 0\.[45]\d*× the nominal of rad/s",
                 id="time-x2"),
])
def test_unsupported_gyro_refused_then_kept_with_override(recording: ImuRecording, case: str, expected: str) -> None:
    rec = recording
    t, gyro = rec.t, rec.gyro
    if case == "other recording's rates":
        gyro = simulated(2).gyro
    elif case == "noise for gyro":
        gyro = np.random.default_rng(0).normal(0.0, 0.005, rec.gyro.shape)
    elif case == "x and y swapped":
        gyro = rec.gyro[:, [1, 0, 2]]
    elif case == "z reversed":
        gyro = rec.gyro * [1, 1, -1]
    else:
        t = 2.0 * rec.t
    with pytest.raises(InputError, match=r"^the gyro calibration cannot be right: .*" + expected
                       + r".*Likely causes: the gyro columns .*accept_gyro_fit=True"):
        fit(t, rec.acc, gyro, rec)
    kept = fit(t, rec.acc, gyro, rec, accept_gyro_fit=True)
    assert kept.fit_check["refused"] and kept.fit_check["accepted"]
    assert kept.fit_warning.startswith("gyro calibration kept (accept_gyro_fit) although it cannot be right")
    assert "assumes the gyro columns are this sensor's body rates" in kept.fit_warning
    assert any("KEPT DESPITE" in note for note in kept.notes)


def test_degenerate_moves_skip_the_axis_and_scale_tests() -> None:
    """Moves about two axes leave T_g's third column arbitrary: allowed through, its axes are not judged."""
    rec = simulate_imu(optcal.lu2017_reference_model(), reference_gyro(1.0, rng=2), 14, rng=11, dwell_s=1.0,
                       move_s=1.0, axes=[[1, 0, 0], [0, 1, 0]], gyro_noise=0.001, acc_noise=0.001)
    cal = fit(rec.t, rec.acc, rec.gyro, rec, allow_degenerate=True)
    assert cal.fit_check["findings"] == []


def test_saved_check_round_trip(recording: ImuRecording, tmp_path: Path) -> None:
    cal = fit(recording.t, recording.acc, recording.gyro, recording)
    cal.save(tmp_path / "imu.json")
    back = optcal.families.calibration_files.load(tmp_path / "imu.json")
    assert back == cal and back.fit_check["residual"]["dof"] == 2 * 23 - 9


# ----------------------------------------------------------------------------------------- real recordings, CLI
MIKOFF_LAYOUT = ("ax", "ay", "az", "gx", "gy", "gz")


def mikoff_variant(shared_data: Path, tmp_path: Path, unit: int, change: str) -> Path:
    """mikoff's headerless 'ax ay az gx gy gz' log of one unit, its gyro columns changed."""
    data = np.loadtxt(shared_data / "mikoff-mpu9150" / f"imu{unit}.log")
    if change == "swap x y":
        data[:, [3, 4]] = data[:, [4, 3]]
    elif change == "noise":  # white noise of the unit's own rest level (about 0.005 rad/s), 1e-5 steps
        data[:, 3:] = np.round(np.random.default_rng(3).normal(0.0, 0.005, (data.shape[0], 3)), 5)
    path = tmp_path / f"imu{unit}_{change.replace(' ', '_')}.log"
    np.savetxt(path, data, fmt="%.5f")
    return path


def test_mikoff_logs_pass(shared_data: Path, capsys) -> None:
    """The five MPU-9150 logs as recorded: calibrated, within the noise model, no warning."""
    for unit in range(5):
        code, out, err = run_args(capsys, "calibrate", str(shared_data / "mikoff-mpu9150" / f"imu{unit}.log"),
                                  "--rate", "100", "--imu", "--json")
        assert code == 0, err
        check = json.loads(out)["gyro_fit"]["fit_check"]
        assert check["findings"] == [] and check["residual"]["ratio_to_bound"] < 1.0
        assert "warning" not in err


@pytest.mark.parametrize("change, options, expected", [
    pytest.param("swap x y", [], r"gyro x senses 9\d\.\d° from the accelerometer's x axis, \d\.\d° from its \+y axis",
                 id="swap-xy"),
    pytest.param("noise", [], r"the gyro does not see the moves", id="noise"),
    pytest.param("as recorded", ["--rate", "50"], r"the fitted gyro scale is x 0\.[45]\d*×", id="100-Hz-read-at-50"),
])
def test_mikoff_unsupported_gyro_refused(shared_data: Path, tmp_path: Path, capsys, change: str, options: list[str],
                                         expected: str) -> None:
    path = mikoff_variant(shared_data, tmp_path, 0, change)
    cal_path = tmp_path / "imu.json"
    rate = [] if options else ["--rate", "100"]
    code, out, err = run_args(capsys, "calibrate", str(path), *rate, *options, "--imu", "-o", str(cal_path))
    assert code == 2 and not cal_path.exists()
    assert err.startswith("error: the gyro calibration cannot be right: ") and err.count("\n") == 1
    assert re.search(expected, err) and all(cause in err for cause in CAUSES)
    code, out, err = run_args(capsys, "calibrate", str(path), *rate, *options, "--imu", "--accept-gyro-fit", "-o",
                              str(cal_path))
    assert code == 0 and cal_path.exists()
    assert err.startswith("warning: gyro calibration kept (--accept-gyro-fit) although it cannot be right: ")
    assert re.search(expected, err) and "assumes the gyro columns are this sensor's body rates" in err


@pytest.mark.parametrize("change, expected", [
    pytest.param("permute", r"gyro x senses \d+\.\d° from the accelerometer's x axis, \d\.\d° from its \+y axis",
                 id="permute"),
    pytest.param("noise", r"the gyro does not see the moves", id="noise"),
])
def test_xsens_unsupported_gyro_refused(shared_data: Path, tmp_path: Path, capsys, change: str, expected: str) -> None:
    """imu_tk's Xsens log in counts, gyro columns permuted (y, z, x) or replaced by noise of its rest level."""
    frame = pd.read_csv(shared_data / "imutk-xsens" / "xsens_imutk.csv")
    gyro = ["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]
    if change == "permute":
        frame[gyro] = frame[["gyro_y_counts", "gyro_z_counts", "gyro_x_counts"]].to_numpy()
    else:
        rng = np.random.default_rng(4)
        frame[gyro] = np.round(32768 + rng.normal(0.0, 27.0, (len(frame), 3))).astype(int)
    path = tmp_path / "xsens.csv"
    frame.to_csv(path, index=False)
    code, _, err = run_args(capsys, "calibrate", str(path), "--imu")
    assert code == 2 and re.search(expected, err) and all(cause in err for cause in CAUSES)
    code, _, err = run_args(capsys, "calibrate", str(path), "--imu", "--accept-gyro-fit")
    assert code == 0 and "warning: gyro calibration kept (--accept-gyro-fit)" in err


def test_check_flags_another_units_calibration(shared_data: Path, tmp_path: Path, capsys) -> None:
    """mikoff imu2's calibration on imu3: 9.9° after against 0.44° before, far beyond imu3's noise model: flagged, and
    the bias named (with imu3's own rest bias the same T_g leaves 0.45°); on its own log it is within the model."""
    logs = shared_data / "mikoff-mpu9150"
    cal_path = tmp_path / "imu2.json"
    assert run_args(capsys, "calibrate", str(logs / "imu2.log"), "--rate", "100", "--imu", "-o", str(cal_path))[0] == 0
    code, out, _ = run_args(capsys, "check", str(cal_path), str(logs / "imu3.log"), "--rate", "100")
    assert code == 0
    flag = next(line for line in out.splitlines() if line.startswith("gyro: FLAG"))
    assert "this calibration does not fit DATA's gyro" in flag and "the bias differs" in flag
    code, out, _ = run_args(capsys, "check", str(cal_path), str(logs / "imu3.log"), "--rate", "100", "--json")
    test = json.loads(out)["gravity_prediction"]["test"]
    assert test["ratio_to_bound"] > 10 * REFUSAL_MARGIN / 3 and test["far_beyond"] and test["dof"] == 2 * 21
    code, out, _ = run_args(capsys, "check", str(cal_path), str(logs / "imu2.log"), "--rate", "100")
    assert "FLAG" not in out and "within the noise model" in out


def test_xsens_flagged_until_its_g_sensitivity_is_modelled(shared_data: Path, capsys) -> None:
    """imu_tk's Xsens log: 0.475° after, above the noise model's 99.9 % bound but well within the refusal margin:
    kept, with a warning that names the g-sensitivity; modelled, it leaves 0.13°, within the model, no warning."""
    path = str(shared_data / "imutk-xsens" / "xsens_imutk.csv")
    code, out, err = run_args(capsys, "calibrate", path, "--imu", "--json")
    check = json.loads(out)["gyro_fit"]["fit_check"]
    assert code == 0 and check["findings"] == [] and 1.0 < check["residual"]["ratio_to_bound"] < REFUSAL_MARGIN
    assert err.startswith("warning: gyro: gravity prediction") and "--g-sensitivity models it" in err
    code, out, err = run_args(capsys, "calibrate", path, "--imu", "--g-sensitivity", "--json")
    check = json.loads(out)["gyro_fit"]["fit_check"]
    assert code == 0 and check["residual"]["ratio_to_bound"] < 1.0 and "warning" not in err
