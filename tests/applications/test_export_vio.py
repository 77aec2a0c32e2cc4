"""Issue 27: the Kalibr / VIO / noise exports, each read back by a few-line re-implementation of its consumer.

Real data: the Xsens MTi log imu_tk ships (``imutk-xsens``), calibrated with ``optcal calibrate --imu`` (and
``--g-sensitivity``), its first 50 s (the initial rest imu_tk's own app uses) analysed with
``optcal allan --sensor both --window :50 --calibration CAL``.  For every intrinsics format the consumer's
equation, applied to the exported numbers, must give back optcal's ``|a| = 1 g`` on the calibration's
poses and optcal's corrected rates on the log's raw gyro samples (or the loss the export reports).

Upstream sources re-implemented here (cited at each reader):
- Kalibr: ethz-asl/kalibr @1f60227 ``aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py``
  (``ImuParameters``) and ``kalibr_imu_camera_calibration/IccSensors.py`` (``IccScaledMisalignedImu``).
- OpenVINS: rpng/open_vins @6948812 ``ov_msckf/src/core/VioManagerOptions.h`` and ``ov_msckf/src/state/Propagator.cpp``.
- Basalt: VladyslavUsenko/basalt-headers @a585db3 ``include/basalt/calibration/calib_bias.hpp``.
- imu_tk: Kyle-ak/imu_tk @7780270 ``include/imu_tk/calibration.h`` (``CalibratedTriad_::load``, ``unbiasNormalize``).
- VINS-Fusion @be55a93 ``vins_estimator/src/estimator/parameters.cpp``; ORB-SLAM3 ``src/Tracking.cc``
  (``ParseIMUParamFile``); OKVIS ``VioParametersReader.cpp`` (``imu_params``).
"""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.stats import chi2

import optcal.families.calibration_files as calibration_files
from helpers.cli_run import run
from helpers.common import SHARED

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
#: The Xsens MTi's driver sensitivities the test assumes for the topic (imu_tk's test app and imu_tk_matlab's
#: datasheet values, PROVENANCE.md): 415 counts per m/s², 6258 counts per rad/s, unsigned 16-bit around 32768.
COUNTS_PER_G = 415.0 * 9.80665
GYRO_COUNTS_PER_RAD_S = 6258.0
ZERO = 32768.0
G = 9.80665
DRIVER = ["--counts-per-g", str(COUNTS_PER_G), "--gyro-counts-per-rad-s", str(GYRO_COUNTS_PER_RAD_S)]

pytestmark = pytest.mark.skipif(not XSENS.is_file(), reason="../shared/data/imutk-xsens is not present")


@pytest.fixture(scope="module")
def xsens(tmp_path_factory) -> dict:
    """The Xsens log's imu calibrations (without and with the g-sensitivity), its Allan result, raw gyro samples."""
    from optcal.cli.main import main

    d = tmp_path_factory.mktemp("xsens")
    assert main(["calibrate", str(XSENS), "--imu", "-o", str(d / "imu.json")]) == 0
    assert main(["calibrate", str(XSENS), "--imu", "--g-sensitivity", "-o", str(d / "imu_g.json")]) == 0
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["allan", str(XSENS), "--sensor", "both", "--window", ":50", "--calibration", str(d / "imu.json"),
                     "--json", "--plot", str(d / "figs")])
    assert code == 0
    (d / "allan.json").write_text(out.getvalue())
    raw = pd.read_csv(XSENS)
    moving = raw.iloc[6000:9000]  # after the initial rest: moves and rests
    return {"dir": d, "cal": d / "imu.json", "cal_g": d / "imu_g.json", "allan": d / "allan.json",
            "allan_json": json.loads(out.getvalue()),
            "gyro": moving[["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]].to_numpy(float),
            "acc": moving[["acc_x_counts", "acc_y_counts", "acc_z_counts"]].to_numpy(float)}


def optcal_rates(cal, gyro: np.ndarray, acc: np.ndarray) -> np.ndarray:
    return cal.correct_gyro(gyro, acc)


def topic_acc(raw: np.ndarray) -> np.ndarray:
    """The topic's accelerometer reading the export assumes: (raw − 32768) · g / counts_per_g, m/s²."""
    return (raw - ZERO) * G / COUNTS_PER_G


def topic_gyro(raw: np.ndarray) -> np.ndarray:
    return (raw - ZERO) / GYRO_COUNTS_PER_RAD_S


def comment_vector(text: str, label: str) -> np.ndarray:
    line = next(ln for ln in text.splitlines() if ln.strip().startswith(f"# {label}"))
    return np.array([float(v) for v in line.split(":")[-1].split(",")])


# ------------------------------------------------------------------------------------------- allan
def test_allan_both_sensors_from_the_still_part_with_the_calibrations_scales(xsens):
    """One JSON carries both sensors; the counts scales are the calibration's axis sensitivities; the rate random
    walk's bound is the 95 % one-sided chi-square bound at the longest τ, for the gyroscope as for the accelerometer."""
    out = xsens["allan_json"]
    assert out["sensor"] == "both" and out["gyroscope"]["sensor"] == "gyro" and "sensor" not in out["accelerometer"]
    cal = calibration_files.load(xsens["cal"])
    counts_per_g = np.linalg.norm(np.linalg.inv(cal.lumped().T), axis=1).mean()
    counts_per_rad_s = np.linalg.norm(np.linalg.inv(cal.gyro.T), axis=1).mean()
    assert out["accelerometer"]["units"]["si_per_input_unit"] == pytest.approx(G / counts_per_g, rel=1e-12)
    assert out["gyroscope"]["units"]["rad_s_per_input_unit"] == pytest.approx(1.0 / counts_per_rad_s, rel=1e-12)
    assert out["log"]["n_samples"] == pytest.approx(50 * 100, abs=10)  # the window, at 100 Hz
    for part in (out["accelerometer"], out["gyroscope"]):
        for axis in "xyz":
            b = part[axis]["rate_random_walk_bound"]
            factor = np.sqrt(b["edf"] / chi2.ppf(1 - b["confidence"], b["edf"]))
            assert b["value"] == pytest.approx(b["adev_upper"] * np.sqrt(3 / b["tau_s"]), rel=1e-12)
            assert b["value"] > part[axis]["rate_random_walk_largest_consistent"] * 0.999 and factor > 1
    assert (xsens["dir"] / "figs" / "allan.png").is_file() and (xsens["dir"] / "figs" / "allan_gyro.png").is_file()


def test_allan_calibration_conflicts_and_a_log_that_is_not_still(xsens, capsys):
    code, _, err = run(["allan", XSENS, "--calibration", xsens["cal"], "--counts-per-g", "4000"], capsys)
    assert code == 2 and err.startswith("error: --calibration gives the counts scales") and err.count("\n") == 1
    code, out, err = run(["allan", XSENS, "--sensor", "both", "--calibration", xsens["cal"]], capsys)
    assert code == 2 and "--window START:END" in err


# ------------------------------------------------------------------------------------------- kalibr
def kalibr_imu_parameters(path) -> dict:
    """kalibr_common/ConfigReader.py, ImuParameters: yaml.safe_load, then the getters' checks
    (checkRosTopic: a str; checkUpdateRate: > 0; check*Statistics: noise density and random walk > 0)."""
    data = yaml.safe_load(open(path))
    if "imu0" in data:  # an ImuSetParameters result (IccCalibrator.saveImuSetParametersYaml): imu0 is ImuParameters' data
        data = data["imu0"]
    assert isinstance(data["rostopic"], str)
    assert data["update_rate"] > 0.0
    for sensor in ("accelerometer", "gyroscope"):
        assert data[f"{sensor}_noise_density"] > 0.0 and data[f"{sensor}_random_walk"] > 0.0
    return data


def test_kalibr_file_from_the_xsens_calibration_and_its_still_part(xsens, capsys):
    """The issue's acceptance: optcal export on the Xsens imu calibration with the Allan result of its own still
    part writes a file Kalibr's reader accepts (the rate random walks as labelled confidence bounds)."""
    args = ["export", xsens["cal"], "--format", "kalibr", "--allan", xsens["allan"]]
    code, _, err = run(args, capsys)
    assert code == 2 and "--random-walk-bound" in err and err.count("\n") == 1
    out_file = xsens["dir"] / "imu.yaml"
    code, out, err = run([*args, "--random-walk-bound", "-o", out_file], capsys)
    assert code == 0, err
    imu = kalibr_imu_parameters(out_file)
    allan = xsens["allan_json"]
    assert imu["gyroscope_random_walk"] == pytest.approx(
        max(allan["gyroscope"][a]["rate_random_walk_bound"]["value"] for a in "xyz"), rel=1e-8)
    assert imu["accelerometer_noise_density"] == pytest.approx(
        max(allan["accelerometer"][a]["velocity_random_walk"] for a in "xyz"), rel=1e-8)
    assert "not exported: the calibration itself" in out and "upper bound" in out


def test_kalibr_imu_scale_misalignment_reproduces_optcal(xsens, capsys):
    """IccSensors.py (IccScaledMisalignedImu.addAccelerometerErrorTerms / addGyroscopeErrorTerms):
    alpha = M_a a_i + b_a;  omega_m = M_g C_gyro_i w_i + A C_gyro_i a_i + b_g;  M lower-triangular (MatrixBasicDv)."""
    path = xsens["dir"] / "kalibr_imu.yaml"
    code, out, err = run(["export", xsens["cal_g"], "--format", "kalibr-imu", "--allan", xsens["allan"],
                          "--random-walk-bound", *DRIVER, "-o", path], capsys)
    assert code == 0, err
    imu = kalibr_imu_parameters(path)
    text = path.read_text()
    assert imu["model"] == "scale-misalignment"
    M_a = np.array(imu["accelerometers"]["M"])
    M_g, A, C = (np.array(imu["gyroscopes"][k]) for k in ("M", "A", "C_gyro_i"))
    assert np.all(np.triu(M_a, 1) == 0) and np.all(np.triu(M_g, 1) == 0)
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-10)
    assert np.linalg.det(C) == pytest.approx(1.0)
    b_a = comment_vector(text, "accelerometer bias b_a")
    b_g = comment_vector(text, "gyroscope bias b_g")
    cal = calibration_files.load(xsens["cal_g"])
    poses = cal.fitted_on.acc
    a_i = np.linalg.solve(M_a, (topic_acc(poses) - b_a).T).T
    np.testing.assert_allclose(np.linalg.norm(a_i, axis=1) / G - 1, cal.norm_errors(poses), atol=1e-9)
    f = np.linalg.solve(M_a, (topic_acc(xsens["acc"]) - b_a).T).T
    w_i = (C.T @ np.linalg.solve(M_g, (topic_gyro(xsens["gyro"]) - b_g - f @ (A @ C).T).T)).T
    np.testing.assert_allclose(w_i, optcal_rates(cal, xsens["gyro"], xsens["acc"]), atol=1e-9)
    assert "loss 0.0000 mg" in out


def test_openvins_kalibr_model_reproduces_optcal(xsens, capsys):
    """VioManagerOptions.h: Dw = Tw^-1, Da = Ta^-1, the kalibr model keeping their lower triangles (vec_dw, vec_da);
    Propagator.cpp: a_I = R_ACCtoIMU Da (a_m - b_a); w_I = R_GYROtoIMU Dw (w_m - b_g - Tg a_I)."""
    path = xsens["dir"] / "kalibr_imu_chain.yaml"
    code, _, err = run(["export", xsens["cal_g"], "--format", "openvins", "--allan", xsens["allan"],
                        "--random-walk-bound", "--inflate", "10,10", *DRIVER, "-o", path], capsys)
    assert code == 0, err
    text = path.read_text()
    assert text.startswith("%YAML:1.0")
    imu = yaml.safe_load(text.split("\n", 1)[1])["imu0"]  # cv::FileStorage's directive stripped for PyYAML
    assert imu["model"] == "kalibr"
    Dw = np.tril(np.linalg.inv(np.array(imu["Tw"])))
    Da = np.tril(np.linalg.inv(np.array(imu["Ta"])))
    R_ACCtoIMU, R_GYROtoIMU = np.array(imu["R_IMUtoACC"]).T, np.array(imu["R_IMUtoGYRO"]).T
    Tg = np.array(imu["Tg"])
    b_a = comment_vector(text, "accelerometer bias b_a")
    b_g = comment_vector(text, "gyroscope bias b_g")
    cal = calibration_files.load(xsens["cal_g"])
    a_I = (topic_acc(cal.fitted_on.acc) - b_a) @ (R_ACCtoIMU @ Da).T
    np.testing.assert_allclose(np.linalg.norm(a_I, axis=1) / G - 1, cal.norm_errors(cal.fitted_on.acc), atol=1e-9)
    a_hat = (topic_acc(xsens["acc"]) - b_a) @ (R_ACCtoIMU @ Da).T
    w_I = (topic_gyro(xsens["gyro"]) - b_g - a_hat @ Tg.T) @ (R_GYROtoIMU @ Dw).T
    np.testing.assert_allclose(w_I, optcal_rates(cal, xsens["gyro"], xsens["acc"]), atol=1e-9)
    # the noise keys, inflated x10 and said so
    allan = xsens["allan_json"]
    assert imu["gyroscope_noise_density"] == pytest.approx(
        10 * max(allan["gyroscope"][a]["angle_random_walk"] for a in "xyz"), rel=1e-8)
    assert "inflation applied: white noise x10, random walk x10" in text


def test_basalt_calib_bias_vectors_reproduce_optcal_and_report_the_g_sensitivity(xsens, capsys):
    """calib_bias.hpp: CalibAccelBias a_c = (I + S_a) a_r - b (S_a lower-triangular from s_1..s_6 as getBiasAndScale
    fills it); CalibGyroBias w_c = (I + S_g) w_r - b (S_g column-major from s_1..s_9).  Basalt has no
    g-sensitivity: with it dropped the rates differ from optcal's by W S f, the loss the export reports."""
    path = xsens["dir"] / "calibration.json"
    code, out, err = run(["export", xsens["cal_g"], "--format", "basalt", "--allan", xsens["allan"],
                          "--random-walk-bound", *DRIVER, "-o", path], capsys)
    assert code == 0, err
    value = json.loads(path.read_text())["value0"]
    p = np.array(value["calib_accel_bias"])
    S_a = np.zeros((3, 3))
    S_a[:, 0] = p[3:6]
    S_a[1, 1], S_a[2, 1], S_a[2, 2] = p[6], p[7], p[8]
    q = np.array(value["calib_gyro_bias"])
    S_g = np.column_stack([q[3:6], q[6:9], q[9:12]])
    cal = calibration_files.load(xsens["cal_g"])
    a_c = topic_acc(cal.fitted_on.acc) @ (np.eye(3) + S_a).T - p[:3]
    np.testing.assert_allclose(np.linalg.norm(a_c, axis=1) / G - 1, cal.norm_errors(cal.fitted_on.acc), atol=1e-9)
    w_c = topic_gyro(xsens["gyro"]) @ (np.eye(3) + S_g).T - q[:3]
    full = optcal_rates(cal, xsens["gyro"], xsens["acc"])
    # what Basalt leaves in: T_g G_g a (rad/s) for the specific force a in g
    f = cal.correct(xsens["acc"])
    np.testing.assert_allclose(w_c - full, f @ (cal.gyro.T @ cal.gyro.g_sensitivity).T, atol=1e-9)
    reported = float(re.search(r"the rate it adds at 1 g is ([0-9.e-]+) deg/s rms", out).group(1))
    f_poses = cal.correct(cal.fitted_on.acc)
    f_poses /= np.linalg.norm(f_poses, axis=1, keepdims=True)
    missed = np.degrees(np.linalg.norm(f_poses @ (cal.gyro.T @ cal.gyro.g_sensitivity).T, axis=1))
    assert reported == pytest.approx(np.sqrt(np.mean(missed**2)), rel=1e-3) and reported > 0.05
    allan = xsens["allan_json"]
    assert value["gyro_noise_std"] == pytest.approx([allan["gyroscope"][a]["angle_random_walk"] for a in "xyz"], rel=1e-12)
    assert value["imu_update_rate"] == pytest.approx(100.0, rel=1e-3)


def imutk_load(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CalibratedTriad_::load: 9 numbers row-major into the misalignment T, 9 into the scale K, 3 into B."""
    v = [float(x) for x in text.split()]
    assert len(v) == 21
    return np.array(v[:9]).reshape(3, 3), np.array(v[9:18]).reshape(3, 3), np.array(v[18:])


def imutk_reference(text: str) -> dict[str, dict[str, np.ndarray]]:
    """The T matrices and K diagonals of IMUTK_REFERENCE.md's ``## Accelerometer`` and ``## Gyroscope`` sections."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for section in re.split(r"^## ", text.replace("\u2212", "-"), flags=re.M)[1:]:
        name = section.split()[0]
        T = re.search(r"- T = (\[\[.*\]\])", section)
        K = re.search(r"- K = diag\(([^)]*)\)", section)
        if T and K:
            out[name] = {"T": np.array(json.loads(T.group(1))), "K": np.array([float(v) for v in K.group(1).split(",")])}
    return out


def test_imutk_calib_pair_reproduces_optcal_and_imu_tk_s_own_calibration(xsens, capsys, shared_data):
    """unbiasNormalize: X' = T K (X - B).  The accelerometer's T unit upper-triangular and K diagonal, the gyroscope's
    T unit-diagonal: exact in imu_tk's body frame (optcal's turned by R); and close to imu_tk's own calibration of the
    same log (IMUTK_REFERENCE.md, computed by building imu_tk and running its test_imu_calib)."""
    path = xsens["dir"] / "xsens_acc.calib"
    code, out, err = run(["export", xsens["cal"], "--format", "imutk", "--gravity", "9.81744", "-o", path], capsys)
    assert code == 0, err
    T_a, K_a, B_a = imutk_load(path.read_text())
    T_g, K_g, B_g = imutk_load((xsens["dir"] / "xsens_acc_gyro.calib").read_text())
    assert np.all(np.diag(T_a) == 1) and np.all(np.tril(T_a, -1) == 0) and np.all(K_a == np.diag(np.diag(K_a)))
    assert np.all(np.diag(T_g) == 1) and np.all(K_g == np.diag(np.diag(K_g)))
    cal = calibration_files.load(xsens["cal"])
    a = (cal.fitted_on.acc - B_a) @ (T_a @ K_a).T
    np.testing.assert_allclose(np.linalg.norm(a, axis=1) / 9.81744 - 1, cal.norm_errors(cal.fitted_on.acc), atol=1e-9)
    w = (xsens["gyro"] - B_g) @ (T_g @ K_g).T
    full = optcal_rates(cal, xsens["gyro"], xsens["acc"])
    # one frame for both sensors, turned from optcal's: the rates' lengths and their angles with the force are kept
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), np.linalg.norm(full, axis=1), rtol=1e-9, atol=1e-12)
    f_imutk = (xsens["acc"] - B_a) @ (T_a @ K_a).T
    np.testing.assert_allclose(np.sum(w * f_imutk, axis=1) / 9.81744, np.sum(full * cal.correct(xsens["acc"]), axis=1),
                               atol=1e-9)
    # imu_tk's own numbers for this log (shared data IMUTK_REFERENCE.md): misalignments within 0.1 deg, scales 0.2 %
    reference = imutk_reference((shared_data / "imutk-xsens" / "IMUTK_REFERENCE.md").read_text())
    np.testing.assert_allclose(T_a, reference["Accelerometer"]["T"], atol=np.radians(0.1))
    np.testing.assert_allclose(np.diag(K_a), reference["Accelerometer"]["K"], rtol=2e-3)
    np.testing.assert_allclose(np.diag(K_g), reference["Gyroscope"]["K"], rtol=2e-3)
    np.testing.assert_allclose(T_g, reference["Gyroscope"]["T"], atol=np.radians(0.1))
    assert "turned by" in out and "_gyro" in out


# ------------------------------------------------------------------------------------------- noise blocks
def opencv_yaml(text: str) -> dict:
    assert text.startswith("%YAML:1.0\n")  # cv::FileStorage's YAML directive
    return yaml.safe_load(text.split("\n", 1)[1])


@pytest.mark.parametrize("fmt, keys", [
    ("vins", {"acc_n": ("accelerometer", "velocity_random_walk"), "gyr_n": ("gyroscope", "angle_random_walk"),
              "acc_w": ("accelerometer", "rrw"), "gyr_w": ("gyroscope", "rrw")}),
    ("orbslam3", {"IMU.NoiseAcc": ("accelerometer", "velocity_random_walk"),
                  "IMU.NoiseGyro": ("gyroscope", "angle_random_walk"),
                  "IMU.AccWalk": ("accelerometer", "rrw"), "IMU.GyroWalk": ("gyroscope", "rrw")}),
    ("okvis", {"sigma_a_c": ("accelerometer", "velocity_random_walk"), "sigma_g_c": ("gyroscope", "angle_random_walk"),
               "sigma_aw_c": ("accelerometer", "rrw"), "sigma_gw_c": ("gyroscope", "rrw")}),
])
def test_noise_blocks_in_each_estimators_keys_with_the_inflation_written(xsens, capsys, fmt, keys):
    """parameters.cpp (VINS: fsSettings["acc_n"] ...), Tracking.cc (ORB-SLAM3: IMU.Frequency isInt, the noise keys
    isReal), VioParametersReader.cpp (OKVIS: imu_params sigma_*_c): continuous-time densities, largest axis."""
    code, out, err = run(["export", xsens["cal"], "--format", fmt, "--allan", xsens["allan"], "--random-walk-bound",
                          "--inflate", "10,5"], capsys)
    assert code == 0, err
    data = opencv_yaml(out)
    data = data.get("imu_params", data)
    allan = xsens["allan_json"]
    for key, (sensor, figure) in keys.items():
        if figure == "rrw":
            expected = 5 * max(allan[sensor][a]["rate_random_walk_bound"]["value"] for a in "xyz")
        else:
            expected = 10 * max(allan[sensor][a][figure] for a in "xyz")
        assert data[key] == pytest.approx(expected, rel=1e-8), key
        assert re.search(rf"^\s*{re.escape(key)}: [-0-9.]+e[-+][0-9]+ ", out, re.M), f"{key} not a real for OpenCV"
    assert "inflation applied: white noise x10, random walk x5" in out
    assert "continuous time" in out and "UPPER BOUND" in out
    if fmt == "orbslam3":
        assert data["IMU.Frequency"] == 100 and isinstance(data["IMU.Frequency"], int)


def test_noise_blocks_refuse_a_single_sensor_and_bad_inflation(xsens, capsys, tmp_path):
    acc_only = tmp_path / "acc.json"
    acc_only.write_text(json.dumps(xsens["allan_json"]["accelerometer"]))
    code, _, err = run(["export", xsens["cal"], "--format", "vins", "--allan", acc_only, "--random-walk-bound"], capsys)
    assert code == 2 and "gyroscope's Allan result is missing" in err and err.count("\n") == 1
    code, _, err = run(["export", xsens["cal"], "--format", "vins", "--allan", xsens["allan"], "--inflate", "10"], capsys)
    assert code == 2 and "--inflate" in err
    code, _, err = run(["export", xsens["cal"], "--format", "imutk"], capsys)
    assert code == 2 and "give -o FILE" in err
    code, _, err = run(["export", xsens["cal"], "--format", "kalibr-imu"], capsys)
    assert code == 2 and "--counts-per-g" in err


# ------------------------------------------------------------------------------------------- factorisations
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_triangular_factorisations_rebuild_the_matrix_with_a_proper_rotation(seed):
    """lq (Kalibr's M C, OpenVINS's Tw R) and qr_upper (imu_tk's body frame) on full matrices, a reflection included."""
    from optcal.applications.export.intrinsics import lq, qr_upper

    M = np.eye(3) + 0.3 * np.random.default_rng(seed).standard_normal((3, 3))
    if seed == 2:
        M[:, 0] *= -1  # a left-handed set of axes
    L, Q = lq(M)
    np.testing.assert_allclose(L @ Q, M, atol=1e-12)
    assert np.all(np.triu(L, 1) == 0) and np.linalg.det(Q) == pytest.approx(1.0)
    Q2, U = qr_upper(M)
    np.testing.assert_allclose(Q2 @ U, M, atol=1e-12)
    assert np.all(np.tril(U, -1) == 0) and np.linalg.det(Q2) == pytest.approx(1.0)


def test_accelerometer_only_calibration_in_g_exports_identity_gyro_and_says_so(tmp_path, capsys):
    """A lumped calibration in g: no driver scale needed; Kalibr's gyroscope matrices are the identity, said so."""
    from optcal.core.model import lu2017_reference_model
    from optcal.families.caltypes import FitPoses, LumpedCalibration
    from optcal.families.simulate.poses import uniform_directions

    model = lu2017_reference_model()
    acc = model.measure(uniform_directions(20, rng=3))
    LumpedCalibration.from_model(model, "g", FitPoses(acc)).save(tmp_path / "cal.json")
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "kalibr-imu", "--rate", "200"], capsys)
    assert code == 0, err
    imu = yaml.safe_load(out)["imu0"]
    np.testing.assert_allclose(imu["gyroscopes"]["M"], np.eye(3))
    assert "gyroscope: the calibration has none" in err and "accelerometer_noise_density: FILL IN" in out
    a_i = np.linalg.solve(np.array(imu["accelerometers"]["M"]), (acc * G - comment_vector(out, "accelerometer bias b_a")).T).T
    cal = calibration_files.load(tmp_path / "cal.json")
    np.testing.assert_allclose(np.linalg.norm(a_i, axis=1) / G - 1, cal.norm_errors(acc), atol=1e-9)  # 12 digits in the file
    assert imu["update_rate"] == 200


def test_one_gyro_sensitivity_given_in_either_unit_serves_every_format() -> None:
    """ExportOptions holds the driver's gyro sensitivity once, per °/s or per rad/s: the VIO intrinsics take it given
    per °/s and the firmware formats given per rad/s (a library caller was refused unless the command line had
    copied it into the other field)."""
    import math
    from types import SimpleNamespace

    from optcal.applications.export.base import ExportOptions
    from optcal.applications.export.firmware_gyro import rad_s_per_gyro_unit
    from optcal.applications.export.intrinsics import gyro_driver

    per_dps = ExportOptions(counts_per_dps=131.0)
    per_rad = ExportOptions(gyro_counts_per_rad_s=131.0 * 180.0 / math.pi)
    assert per_rad.gyro_counts_per_dps() == pytest.approx(131.0) and per_dps.gyro_counts_per_rad() == pytest.approx(7505.747, rel=1e-6)
    assert ExportOptions().gyro_counts_per_dps() is None and ExportOptions().gyro_counts_per_rad() is None
    cal = SimpleNamespace(gyro_units="counts", gyro=SimpleNamespace(bias=np.array([10.0, -4.0, 3.0])))
    s, zero, _ = gyro_driver(cal, per_dps)
    assert s == pytest.approx(math.radians(1.0) / 131.0) and zero == 0.0
    assert rad_s_per_gyro_unit("counts", per_rad.gyro_counts_per_dps()) == pytest.approx(s)
