"""``optcal export``: each format checked against an independent re-implementation of its upstream convention."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pandas as pd
import pytest
import yaml

import optcal.families.calibration_files as calibration_files
from helpers.cli_run import run
from optcal.families.caltypes import ExtendedCalibration, FitPoses, LumpedCalibration, SixPositionCalibration
from optcal.cli.main import main
from optcal.core.extended_model import ExtendedModel
from optcal.core.model import STANDARD_GRAVITY as G
from optcal.core.model import LumpedModel, lu2017_reference_model
from optcal.families.simulate.poses import uniform_directions

COUNTS_PER_G = 16384.0



def poses_of(model: ExtendedModel, n: int = 24, seed: int = 5):
    d = uniform_directions(n, rng=seed)
    temp = np.linspace(20.0, 45.0, n)
    t = np.linspace(0.0, 600.0, n)
    return model.measure(d, temp, t), temp, t


def axis_aligned_sensor(**coefficients) -> ExtendedModel:
    """A counts sensor with diagonal C (no cross-axis terms) and the given extension coefficients."""
    base = LumpedModel(np.diag([16300.0, 16450.0, 16700.0]), np.array([700.0, -360.0, -1830.0]))
    return ExtendedModel(base, coefficients, temp_ref=31.0, t_ref=300.0)


def extended_file(path, model: ExtendedModel, seed: int = 5) -> ExtendedCalibration:
    acc, temp, t = poses_of(model, seed=seed)
    cal = ExtendedCalibration.from_model(model, "counts", fitted_on=FitPoses(acc, temp, t))
    cal.save(path)
    return cal


def read_params(text: str, sep: str) -> dict[str, float]:
    out = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            fields = line.replace("param set ", "").split(sep)
            out[fields[0].strip()] = float(fields[1])
    return out


# ----------------------------------------------------------------------------- ArduPilot
def ardupilot_correct(p: dict[str, float], raw_ms2: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """ArduPilot's accel correction, re-implemented from upstream.

    libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp (TCal::correct_sensor, polynomial_eval):
    clamp T and CALTEMP to [TMIN, TMAX]; v -= p(T - 35) - p(CALTEMP - 35), p(x) = (c1 + (c2 + c3 x) x) x * 1e-6.
    libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp (_rotate_and_correct_accel): v -= OFFS; v *= SCAL.
    """
    v = raw_ms2.copy()
    if p.get("INS_TCAL1_ENABLE") == 1:
        c = [np.array([p[f"INS_TCAL1_ACC{n}_{a}"] for a in "XYZ"]) for n in (1, 2, 3)]

        def poly(x):
            x = np.asarray(x, float)[..., None]
            return (c[0] + (c[1] + c[2] * x) * x) * x * 1e-6

        lo, hi = p["INS_TCAL1_TMIN"], p["INS_TCAL1_TMAX"]
        v = v - poly(np.clip(temp, lo, hi) - 35.0) + poly(np.clip(p["INS_ACC1_CALTEMP"], lo, hi) - 35.0)
    v = v - np.array([p[f"INS_ACCOFFS_{a}"] for a in "XYZ"])
    return v * np.array([p[f"INS_ACCSCAL_{a}"] for a in "XYZ"])


def test_ardupilot_reproduces_an_axis_aligned_calibration_with_a_thermal_polynomial(tmp_path, capsys):
    model = axis_aligned_sensor(temperature_bias=[[0.4e-3, 0, 0], [0, 0, 0], [-0.9e-3, 2e-5, -1e-6]])
    cal = extended_file(tmp_path / "cal.json", model)
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "ardupilot", "--counts-per-g", COUNTS_PER_G], capsys)
    assert code == 0, err
    p = read_params(out, ",")
    acc, temp, t = cal.fitted_on.acc, cal.fitted_on.temp, cal.fitted_on.t
    firmware_g = ardupilot_correct(p, acc * G / COUNTS_PER_G, temp) / G
    # no cross-axis terms and a pure offset polynomial: the exported model is the calibration itself
    np.testing.assert_allclose(firmware_g, cal.correct(acc, temp, t), atol=2e-8)
    assert "loss 0.0000 mg" in err and "temperature_bias on z (order 3)" in err


def test_ardupilot_loss_is_measured_on_the_poses_and_refused_above_max_loss(tmp_path, capsys):
    model = lu2017_reference_model()  # large non-orthogonality: a per-axis model loses a lot
    d = uniform_directions(30, rng=2)
    cal = LumpedCalibration.from_model(model, "g", FitPoses(model.measure(d)))
    cal.save(tmp_path / "lu.json")
    code, out, err = run(["export", tmp_path / "lu.json", "--format", "ardupilot"], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "more than --max-loss 5 mg" in err and "cross-axis terms" in err
    code, out, err = run(["export", tmp_path / "lu.json", "--format", "ardupilot", "--max-loss", "1000"], capsys)
    assert code == 0, err
    firmware_g = ardupilot_correct(read_params(out, ","), model.measure(d) * G, np.zeros(len(d))) / G
    rms = np.sqrt(np.mean((np.linalg.norm(firmware_g, axis=1) - 1) ** 2))
    assert f"exported {rms * 1e3:.4f} mg" in err and "full model 0.0000 mg" in err
    assert rms > 5e-3


# ----------------------------------------------------------------------------- PX4
def px4_correct(p: dict[str, float], raw_ms2: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """PX4's accel correction, re-implemented from upstream.

    src/modules/temperature_compensation/TemperatureCompensation.cpp (calc_thermal_offsets_3D):
    dT = clamp(T, TMIN, TMAX) - TREF; offset = X0 + X1 dT + X2 dT^2 + X3 dT^3.
    src/lib/sensor_calibration/Accelerometer.hpp (Correct): (data - thermal_offset - offset) * scale.
    """
    v = raw_ms2.copy()
    if p.get("TC_A_ENABLE") == 1:
        dT = np.clip(temp, p["TC_A0_TMIN"], p["TC_A0_TMAX"]) - p["TC_A0_TREF"]
        for k in range(3):
            v[:, k] -= sum(p[f"TC_A0_X{n}_{k}"] * dT**n for n in range(4))
    v = v - np.array([p[f"CAL_ACC0_{a}OFF"] for a in "XYZ"])
    return v * np.array([p[f"CAL_ACC0_{a}SCALE"] for a in "XYZ"])


def test_px4_reproduces_the_thermal_offsets_and_lists_what_it_drops(tmp_path, capsys):
    model = axis_aligned_sensor(temperature_bias=[[0, 0, 0], [0.7e-3, -3e-5, 0], [0, 0, 0]])
    cal = extended_file(tmp_path / "cal.json", model)
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "px4-shell", "--counts-per-g", COUNTS_PER_G],
                         capsys)
    assert code == 0, err
    p = read_params(out, " ")
    acc, temp, t = cal.fitted_on.acc, cal.fitted_on.temp, cal.fitted_on.t
    np.testing.assert_allclose(px4_correct(p, acc * G / COUNTS_PER_G, temp) / G, cal.correct(acc, temp, t), atol=2e-8)
    # terms with no PX4 parameter are named, and their cost is in the loss
    model = axis_aligned_sensor(temperature_scale=[[0], [300e-6], [0]], bias_drift=[[0], [0], [2e-6]])
    extended_file(tmp_path / "dropped.json", model)
    code, out, err = run(["export", tmp_path / "dropped.json", "--format", "px4", "--counts-per-g", COUNTS_PER_G,
                          "--max-loss", "100"], capsys)
    assert code == 0, err
    assert "not exported: temperature_scale on y (order 1): the firmware's thermal correction is an offset only" in err
    assert "not exported: bias_drift on z (order 1): the firmware has no time-dependent correction" in err
    assert "TC_A_ENABLE" not in out


def test_firmware_formats_need_counts_per_g_for_counts(tmp_path, capsys):
    extended_file(tmp_path / "cal.json", axis_aligned_sensor())
    code, _, err = run(["export", tmp_path / "cal.json", "--format", "px4"], capsys)
    assert code == 2 and "give --counts-per-g" in err


def test_firmware_export_of_unsigned_counts_subtracts_mid_scale(tmp_path, capsys):
    # an unsigned 16-bit sensor: zero force reads 32768 + bias; the driver outputs (counts - 32768) g/16384
    base = axis_aligned_sensor().base
    model = LumpedModel(base.C, base.o + 32768.0)
    d = uniform_directions(30, rng=4)
    raw = model.measure(d)
    LumpedCalibration.from_model(model, "counts", FitPoses(raw)).save(tmp_path / "cal.json")
    argv = ["export", tmp_path / "cal.json", "--format", "ardupilot", "--counts-per-g", COUNTS_PER_G]
    code, out, err = run(argv, capsys)
    assert code == 0, err
    assert "note: the poses are unsigned 16-bit counts around mid-scale 32768" in err and "--counts-zero VALUE" in err
    p = read_params(out, ",")
    k = G / COUNTS_PER_G
    offsets = np.array([p[f"INS_ACCOFFS_{a}"] for a in "XYZ"])
    np.testing.assert_allclose(offsets, k * base.o, rtol=1e-8)  # 700 counts, not 33468 counts (8 g)
    firmware_g = ardupilot_correct(p, (raw - 32768.0) * k, np.zeros(len(d))) / G
    np.testing.assert_allclose(np.linalg.norm(firmware_g, axis=1), 1.0, atol=1e-8)  # diagonal sensor: exact
    # a driver that does not subtract mid-scale: --counts-zero 0 keeps the offsets as fitted, without the note
    code, out, err = run(argv + ["--counts-zero", 0], capsys)
    assert code == 0 and "mid-scale" not in err
    np.testing.assert_allclose(read_params(out, ",")["INS_ACCOFFS_X"], k * (base.o[0] + 32768.0), rtol=1e-8)
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "px4-shell", "--counts-per-g", COUNTS_PER_G,
                          "--counts-zero", 32000], capsys)
    assert code == 0 and "counts zero 32000 (given)" in out + err
    np.testing.assert_allclose(read_params(out, " ")["CAL_ACC0_XOFF"], k * (base.o[0] + 768.0), rtol=1e-8)


# ----------------------------------------------------------------------------- Kalibr and ROS
@pytest.fixture(scope="module")
def allan_json(tmp_path_factory):
    """A real ``optcal allan --json`` result of a simulated static log (white noise and a bias random walk)."""
    d = tmp_path_factory.mktemp("allan")
    rng = np.random.default_rng(7)
    rate, n = 100.0, 40_000
    walk = np.cumsum(rng.standard_normal((n, 3)), axis=0) * 5e-6
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * rng.standard_normal((n, 3)) + walk
    pd.DataFrame({"t_s": np.arange(n) / rate, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(
        d / "static.csv", index=False)
    code = main(["allan", str(d / "static.csv"), "--json"])
    assert code == 0
    return d


def test_kalibr_imu_yaml_from_an_allan_result(allan_json, tmp_path, capsys):
    main(["allan", str(allan_json / "static.csv"), "--json"])
    allan = json.loads(capsys.readouterr().out)
    (tmp_path / "allan.json").write_text(json.dumps(allan))
    LumpedCalibration(np.eye(3), np.zeros(3)).save(tmp_path / "cal.json")
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "kalibr", "--allan", tmp_path / "allan.json",
                          "--rostopic", "/imu/data"], capsys)
    assert code == 0, err
    imu = yaml.safe_load(out)
    # kalibr_common/ConfigReader.py (ImuParameters) reads these keys; both statistics must be positive
    assert imu["rostopic"] == "/imu/data" and imu["update_rate"] == pytest.approx(100.0)
    vrw = max(allan[a]["velocity_random_walk"] for a in "xyz")
    rrw = max(allan[a]["rate_random_walk"] for a in "xyz" if allan[a]["rate_random_walk"] is not None)
    assert imu["accelerometer_noise_density"] == pytest.approx(vrw, rel=1e-8) and vrw > 0
    assert imu["accelerometer_random_walk"] == pytest.approx(rrw, rel=1e-8) and rrw > 0
    # the simulated white noise: 1e-3 g per sample at 100 Hz is 1e-4 g/√Hz
    assert imu["accelerometer_noise_density"] == pytest.approx(1e-3 * G / 10, rel=0.15)
    code, _, err = run(["export", tmp_path / "cal.json", "--format", "kalibr"], capsys)
    assert code == 2 and "needs the noise model" in err
    # the kalibr format writes the measured noise: an inflation is refused, from the command line and the library
    code, _, err = run(["export", tmp_path / "cal.json", "--format", "kalibr", "--allan", tmp_path / "allan.json",
                        "--inflate", "2,2"], capsys)
    assert code == 2 and "use kalibr-imu for an inflated Kalibr file" in err
    from optcal.applications.export import kalibr
    from optcal.applications.export.base import ExportOptions
    from optcal.errors import InputError

    with pytest.raises(InputError, match="the kalibr format writes the measured noise"):
        kalibr.export(calibration_files.load(tmp_path / "cal.json"), ExportOptions(allan=allan, inflate=(2.0, 2.0)))


def save_allan_results(gyro: np.ndarray, acc: np.ndarray, rate: float, allan_json, tmp_path, capsys) -> dict:
    """Write a still log of ``gyro`` and ``acc``, its ``optcal allan --sensor gyro --json`` result (``gyro.json``,
    returned), the accelerometer's result of ``allan_json`` (``acc.json``) and an identity calibration (``cal.json``)."""
    pd.DataFrame({"t": np.arange(len(gyro)) / rate, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
                  "gx": gyro[:, 0], "gy": gyro[:, 1], "gz": gyro[:, 2]}).to_csv(tmp_path / "still.csv", index=False)
    code, out, err = run(["allan", tmp_path / "still.csv", "--sensor", "gyro", "--json"], capsys)
    assert code == 0, err
    (tmp_path / "gyro.json").write_text(out)
    main(["allan", str(allan_json / "static.csv"), "--json"])
    (tmp_path / "acc.json").write_text(capsys.readouterr().out)
    LumpedCalibration(np.eye(3), np.zeros(3)).save(tmp_path / "cal.json")
    return json.loads(out)


def test_kalibr_gyroscope_keys_from_a_gyro_allan_result(allan_json, tmp_path, capsys):
    """``--gyro-allan``: Kalibr's gyroscope keys from ``optcal allan --sensor gyro --json`` (white noise and a bias walk)."""
    rng = np.random.default_rng(11)
    rate, n, sigma, step = 100.0, 40_000, 0.002, 1e-5  # rad/s per sample; bias random walk rad/s per sample
    gyro = np.array([0.01, -0.02, 0.005]) + sigma * rng.standard_normal((n, 3))
    gyro += np.cumsum(rng.standard_normal((n, 3)), axis=0) * step
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * rng.standard_normal((n, 3))
    gyro_allan = save_allan_results(gyro, acc, rate, allan_json, tmp_path, capsys)
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "kalibr", "--allan", tmp_path / "acc.json",
                          "--gyro-allan", tmp_path / "gyro.json"], capsys)
    assert code == 0, err
    imu = yaml.safe_load(out)
    assert imu["gyroscope_noise_density"] == pytest.approx(gyro_allan["kalibr"]["gyroscope_noise_density"], rel=1e-8)
    assert imu["gyroscope_random_walk"] == pytest.approx(gyro_allan["kalibr"]["gyroscope_random_walk"], rel=1e-8)
    # white noise σ at f_s is σ/√f_s rad/s/√Hz; a bias walk of s per sample is s·√f_s rad/s²/√Hz
    assert imu["gyroscope_noise_density"] == pytest.approx(sigma / np.sqrt(rate), rel=0.15)
    assert imu["gyroscope_random_walk"] == pytest.approx(step * np.sqrt(rate), rel=0.5)
    assert imu["accelerometer_noise_density"] > 0 and "gyroscope random walk" in err
    # the two results swapped are refused, each with what to pass instead
    code, _, err = run(["export", tmp_path / "cal.json", "--format", "kalibr", "--allan", tmp_path / "gyro.json"], capsys)
    assert code == 2 and "pass it as gyro_allan" in err
    code, _, err = run(["export", tmp_path / "cal.json", "--format", "kalibr", "--allan", tmp_path / "acc.json",
                        "--gyro-allan", tmp_path / "acc.json"], capsys)
    assert code == 2 and "--sensor gyro --json" in err


def test_kalibr_gyroscope_random_walk_bound_from_a_short_still_log(allan_json, tmp_path, capsys):
    """A gyro still log too short to show the +1/2 slope: refused without ``--random-walk-bound``, and with it
    the gyro Allan result's upper bound is written, labelled as a bound in the file and the notes."""
    rng = np.random.default_rng(3)
    rate, n, sigma = 100.0, 30_000, 0.002
    gyro = np.array([0.01, -0.02, 0.005]) + sigma * rng.standard_normal((n, 3))
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * rng.standard_normal((n, 3))
    gyro_allan = save_allan_results(gyro, acc, rate, allan_json, tmp_path, capsys)
    assert all(gyro_allan[a]["rate_random_walk"] is None for a in "xyz")
    args = ["export", tmp_path / "cal.json", "--format", "kalibr", "--allan", tmp_path / "acc.json",
            "--gyro-allan", tmp_path / "gyro.json"]
    code, _, err = run(args, capsys)
    assert code == 2 and "gyroscope_random_walk > 0" in err and "--random-walk-bound" in err
    code, out, err = run([*args, "--random-walk-bound"], capsys)
    assert code == 0, err
    imu = yaml.safe_load(out)
    bound = max(gyro_allan[a]["rate_random_walk_bound"]["value"] for a in "xyz")
    assert imu["gyroscope_random_walk"] == pytest.approx(bound, rel=1e-8)
    assert imu["gyroscope_noise_density"] == pytest.approx(gyro_allan["kalibr"]["gyroscope_noise_density"], rel=1e-8)
    assert "gyroscope_random_walk: " in out and out.split("gyroscope_random_walk: ")[1].splitlines()[0].endswith("UPPER BOUND")
    assert "gyroscope_random_walk is an upper bound" in err


def test_ros_covariance_from_the_allan_noise_else_the_residual(allan_json, tmp_path, capsys):
    model = lu2017_reference_model()
    d = uniform_directions(20, rng=3)
    acc = model.measure(d) + 2e-3 * np.random.default_rng(4).standard_normal((20, 3))
    cal = LumpedCalibration.from_model(model, "g", FitPoses(acc))
    cal.save(tmp_path / "cal.json")
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "ros"], capsys)
    assert code == 0, err
    cov = np.array(yaml.safe_load(out)["linear_acceleration_covariance"]).reshape(3, 3)  # sensor_msgs/msg/Imu.msg
    sigma = np.sqrt(np.mean((np.linalg.norm(cal.correct(acc), axis=1) - 1) ** 2)) * G
    np.testing.assert_allclose(cov, np.eye(3) * sigma**2, rtol=1e-8)
    main(["allan", str(allan_json / "static.csv"), "--json"])
    allan = json.loads(capsys.readouterr().out)
    (tmp_path / "allan.json").write_text(json.dumps(allan))
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "ros", "--allan", tmp_path / "allan.json"], capsys)
    assert code == 0, err
    cov = np.array(yaml.safe_load(out)["linear_acceleration_covariance"]).reshape(3, 3)
    white = np.array([allan[a]["velocity_random_walk"] ** 2 * 100.0 for a in "xyz"])
    # the Allan noise is preferred: the per-sample sensor noise, the residual (systematic) left out and said so
    np.testing.assert_allclose(cov, np.diag(white), rtol=1e-8)
    assert "is a systematic error and is not included" in out
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "ros"], capsys)
    assert "NOT the sensor's sample noise" in out and "note: no Allan result given" in err and "--allan FILE" in err


def test_kalibr_writes_a_labelled_random_walk_bound_only_when_asked(tmp_path, capsys):
    # white noise only (1e-3 g per sample at 100 Hz): no +1/2 slope, so no rate random walk in the Allan result
    rate, n = 100.0, 20_000
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * np.random.default_rng(9).standard_normal((n, 3))
    pd.DataFrame({"t_s": np.arange(n) / rate, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(
        tmp_path / "white.csv", index=False)
    assert main(["allan", str(tmp_path / "white.csv"), "--json"]) == 0
    allan = json.loads(capsys.readouterr().out)
    assert all(allan[a]["rate_random_walk"] is None for a in "xyz")
    (tmp_path / "allan.json").write_text(json.dumps(allan))
    LumpedCalibration(np.eye(3), np.zeros(3)).save(tmp_path / "cal.json")
    argv = ["export", tmp_path / "cal.json", "--format", "kalibr", "--allan", tmp_path / "allan.json"]
    code, out, err = run(argv, capsys)
    assert code == 2 and "pass --random-walk-bound to write the upper bound" in err
    code, out, err = run(argv + ["--random-walk-bound"], capsys)
    assert code == 0, err
    imu = yaml.safe_load(out)
    bound = max(allan[a]["rate_random_walk_bound"]["value"] for a in "xyz")
    assert imu["accelerometer_random_walk"] == pytest.approx(bound, rel=1e-8)
    assert "UPPER BOUND" in out and "note: accelerometer_random_walk is an upper bound, not a measurement" in err
    assert "95% one-sided confidence limit" in err
    # white noise σ(τ) = N/√τ: the largest K consistent with the curve, min σ(τ)√(3/τ), is N√3/τ at the longest τ;
    # the 95 % confidence bound reads σ's upper limit there, χ² with the edf: above it, by √(edf/χ²_0.05(edf))
    from scipy.stats import chi2

    for a in "xyz":
        tau = allan[a]["rate_random_walk_largest_consistent_tau_s"]
        assert tau > 0.05 * n / rate
        expected = allan[a]["velocity_random_walk"] * np.sqrt(3.0) / tau
        assert allan[a]["rate_random_walk_largest_consistent"] == pytest.approx(expected, rel=0.5)
        b = allan[a]["rate_random_walk_bound"]
        assert b["confidence"] == 0.95 and b["tau_s"] == pytest.approx(tau)
        factor = np.sqrt(b["edf"] / chi2.ppf(0.05, b["edf"]))
        assert b["value"] == pytest.approx(allan[a]["rate_random_walk_largest_consistent"] * factor, rel=1e-9)


# ----------------------------------------------------------------------------- C header
def every_type(tmp_path):
    rich = axis_aligned_sensor(
        temperature_bias=[[0.4e-3, 1e-5, 0], [0, 0, 0], [-0.9e-3, 0, 0]],
        temperature_scale=[[0, 0], [300e-6, 0], [0, 0]],
        bias_drift=[[0, 0, 0], [0, 0, 0], [2e-6, 0, 0]],
        scale_nonlinearity=[[5e-3], [0], [-3e-3]],
    )
    rich = ExtendedModel(LumpedModel.from_physical([16300, 16450, 16700], 0.003, -0.002, 0.004, [700, -360, -1830]),
                         rich.coefficients, rich.temp_ref, rich.t_ref)
    W = np.linalg.inv(lu2017_reference_model().C)
    cals = {
        "lumped": LumpedCalibration.from_model(lu2017_reference_model(), "g"),
        "sixpos": SixPositionCalibration(W, [0.01, -0.02, 0.03], "g"),
        "extended": extended_file(tmp_path / "extended.json", rich),
    }
    for name, cal in cals.items():
        cal.save(tmp_path / f"{name}.json")
    return cals


C_MAIN = r"""
#include <stdio.h>
#include "cal.h"
int main(void)
{
    double raw[3], temp, t, out[3];
    while (scanf("%lf %lf %lf %lf %lf", &raw[0], &raw[1], &raw[2], &temp, &t) == 5) {
        %CALL%;
        printf("%.17g %.17g %.17g\n", out[0], out[1], out[2]);
    }
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) on this machine")
@pytest.mark.parametrize("name", ["lumped", "sixpos", "extended"])
def test_c_header_compiles_and_reproduces_optcal_apply(name, tmp_path, capsys):
    cal = every_type(tmp_path)[name]
    code, _, err = run(["export", tmp_path / f"{name}.json", "--format", "c", "-o", tmp_path / "cal.h"], capsys)
    assert code == 0, err
    call = "optcal_apply_accel_tt(raw, temp, t, out)" if name == "extended" else "optcal_apply_accel(raw, out)"
    (tmp_path / "main.c").write_text(C_MAIN.replace("%CALL%", call))
    subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-pedantic", "-o", str(tmp_path / "apply"),
                    str(tmp_path / "main.c"), "-lm"], check=True, cwd=tmp_path)
    # a recording around the fitted range (temperature, time) with `optcal apply`
    rng = np.random.default_rng(11)
    n = 200
    scale = 16500.0 if cal.units == "counts" else 1.0
    acc = cal.lumped().o + rng.standard_normal((n, 3)) * scale
    frame = pd.DataFrame({"t_s": np.linspace(0, 600, n), "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
                          "temp": np.linspace(20, 45, n)})
    frame.to_csv(tmp_path / "rec.csv", index=False)
    code, _, err = run(["apply", tmp_path / f"{name}.json", tmp_path / "rec.csv", "-o", tmp_path / "out.csv",
                        "--format", "raw", "--data-units", cal.units], capsys)
    assert code == 0, err
    applied = pd.read_csv(tmp_path / "out.csv")[["ax_g", "ay_g", "az_g"]].to_numpy()
    stdin = "\n".join(" ".join(repr(float(v)) for v in row) for row in frame[["ax", "ay", "az", "temp", "t_s"]].to_numpy())
    c_out = np.loadtxt(subprocess.run([str(tmp_path / "apply")], input=stdin, capture_output=True, text=True,
                                      check=True).stdout.splitlines())
    np.testing.assert_allclose(c_out, applied, rtol=0, atol=1e-9)
    # the test vector in the comment is what the compiled function returns
    header = (tmp_path / "cal.h").read_text()
    vector = header.split("Test vector: raw = {")[1]
    raw = [float(v) for v in vector.split("}")[0].split(",")]
    temp_t = [float(v.split("=")[1].split(" ")[1].strip(",")) for v in vector.split("}")[1].split(",")[1:3]] \
        if name == "extended" else [0.0, 0.0]
    expected = [float(v) for v in header.split("-> out_g = {")[1].split("}")[0].split(",")]
    run_vector = subprocess.run([str(tmp_path / "apply")], input=" ".join(map(repr, raw + temp_t)), capture_output=True,
                                text=True, check=True).stdout.split()
    np.testing.assert_allclose([float(v) for v in run_vector], expected, rtol=0, atol=1e-12)
    assert calibration_files.load(tmp_path / f"{name}.json") == cal
