"""``optcal export`` for the firmwares and C, on calibrations of real recordings, read by the consumers' own readers.

* PX4: QGroundControl's parameter-file reader re-implemented (:func:`qgc_load`, citing its source) and
  PX4's correction formulas (``Accelerometer::Correct``, ``Gyroscope::Correct``).
* ArduPilot: pymavlink's own loader (``pymavlink.mavparm.MAVParmDict.load``) and the firmware's formulas.
* C: the header compiled with the machine's C compiler and run against ``optcal apply``.

The calibrations come from ``optcal calibrate --imu`` on two shared recordings: mikoff's MPU-9150
log ``imu0.log`` (m/s², rad/s) and imu_tk's Xsens log (counts, with ``--g-sensitivity``).
"""

from __future__ import annotations

import io
import re
import shutil
import subprocess
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import optcal.families.calibration_files as calibration_files
from helpers.cli_run import run
from helpers.common import SHARED
from optcal.core.model import STANDARD_GRAVITY as G
from optcal.families.caltypes import ExtendedCalibration, FitPoses
from optcal.core.extended_model import ExtendedModel
from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import uniform_directions

#: Device ids as the firmwares report them (an unsigned 32-bit number each; the values are arbitrary).
ACC_ID, GYRO_ID = 2753028, 2752772
#: Xsens counts: the sensitivities its driver would divide by (arbitrary datasheet-like values, stated per run).
XSENS_COUNTS_PER_G, XSENS_COUNTS_PER_DPS = 6000.0, 83.0


@pytest.fixture(scope="module")
def imu_cals(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``optcal calibrate --imu`` on mikoff's imu0 (m/s², rad/s) and on imu_tk's Xsens log (counts, g-sensitivity)."""
    shared_data = SHARED / "data"
    if not shared_data.is_dir():
        pytest.skip("../shared/data is not present")
    d = tmp_path_factory.mktemp("imucal")
    from optcal.cli.main import main

    assert main(["calibrate", str(shared_data / "mikoff-mpu9150" / "imu0.log"), "--rate", "100", "--imu",
                 "-o", str(d / "mikoff.json")]) == 0
    assert main(["calibrate", str(shared_data / "imutk-xsens" / "xsens_imutk.csv"), "--imu", "--g-sensitivity",
                 "-o", str(d / "xsens.json")]) == 0
    return {"mikoff": d / "mikoff.json", "xsens": d / "xsens.json"}


# ----------------------------------------------------------------------------- QGroundControl / PX4
#: PX4's int32 parameters among those written (src/modules/sensors/module.yaml: CAL_ACC${i}_ID, CAL_GYRO${i}_ID
#: type int32; temp_comp_params_accel_${i}.yaml: TC_A${i}_ID int32; temp_comp_params_accel.yaml: TC_A_ENABLE
#: boolean, stored as int32); every other one is a float.
PX4_INT32 = re.compile(r"(CAL_(ACC|GYRO)[0-3]_ID|TC_A[0-3]_ID|TC_A_ENABLE)")


def px4_type(name: str) -> int:
    """The MAV_PARAM_TYPE of a PX4 parameter: 6 (INT32) or 9 (REAL32)."""
    return 6 if PX4_INT32.fullmatch(name) else 9


def qgc_load(text: str, vehicle_id: int = 1) -> tuple[dict[str, str], list[str]]:
    """QGroundControl's parameter-file reader, re-implemented: (loaded name → value text, lines not loaded).

    src/FactSystem/ParameterManager.cc, ParameterManager::readParametersFromStream (lines 990-1044 of the
    2025-12 tree, ElsabethKahsay/qgroundcontrol af70ef9; the same code in mavlink/qgroundcontrol e7680e0):
    a line starting with '#' is skipped (line 997); the others are split on tabs (998) and only a line
    of exactly five fields is read (1000); a vehicle id other than the vehicle's refuses the whole
    stream (1001-1003); component id, name, value and MAV_PARAM_TYPE follow (1005-1008); a parameter
    whose type differs from the vehicle's own is skipped (1018-1024).  Every written parameter is a
    component-1 (autopilot) parameter that PX4 has.
    """
    loaded: dict[str, str] = {}
    skipped: list[str] = []
    for line in text.splitlines():
        if line.startswith("#"):
            continue
        fields = line.split("\t")
        if len(fields) != 5:
            skipped.append(line)
            continue
        if int(fields[0]) != vehicle_id:
            raise AssertionError(f"QGroundControl refuses the file: saved from System Id {fields[0]}")
        component, name, value, mav_type = int(fields[1]), fields[2], fields[3], int(fields[4])
        if component != 1 or mav_type != px4_type(name):
            skipped.append(line)
            continue
        loaded[name] = value
    return loaded, skipped


def px4_accel(p: dict[str, float], raw_ms2: np.ndarray, slot: int = 0) -> np.ndarray:
    """src/lib/sensor_calibration/Accelerometer.hpp, Correct: (data - thermal_offset - offset) * scale (no thermal)."""
    return (raw_ms2 - [p[f"CAL_ACC{slot}_{a}OFF"] for a in "XYZ"]) * [p[f"CAL_ACC{slot}_{a}SCALE"] for a in "XYZ"]


def px4_gyro(p: dict[str, float], raw_rad_s: np.ndarray, slot: int = 0) -> np.ndarray:
    """src/lib/sensor_calibration/Gyroscope.hpp, Correct: data - thermal_offset - offset (no thermal)."""
    return raw_rad_s - [p[f"CAL_GYRO{slot}_{a}OFF"] for a in "XYZ"]


def rms_norm_error_g(acc_ms2: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.linalg.norm(acc_ms2, axis=1) / G - 1.0) ** 2)))


#: Half a unit of the last digit of the reported percentages (three decimals), as a fraction.
PERCENT_ROUNDING = 0.0005 / 100


def reported_rate_error(err: str) -> tuple[float, float]:
    """The worst-direction and rms rate errors (fractions of the rate) the export reports."""
    m = re.search(r"rate error ([\d.]+)% of the rate in the worst direction \(([\d.]+)% rms over directions\)", err)
    assert m, err
    return float(m.group(1)) / 100, float(m.group(2)) / 100


def test_px4_qgc_file_loads_every_line_and_reproduces_the_losses(imu_cals, capsys):
    """A real imu calibration: QGroundControl's reader loads every line; PX4's formulas give the reported losses."""
    path = imu_cals["mikoff"]
    cal = calibration_files.load(path)
    code, out, err = run(["export", path, "--format", "px4", "--device-id", ACC_ID, "--gyro-device-id", GYRO_ID], capsys)
    assert code == 0, err
    loaded, skipped = qgc_load(out)
    n_lines = sum(1 for line in out.splitlines() if not line.startswith("#"))
    assert skipped == [] and len(loaded) == n_lines == 11
    # QGroundControl's header lines (ParameterManager::writeParametersToStream, lines 1048-1061)
    assert out.startswith("# Onboard parameters for Vehicle 1\n#\n# Stack: PX4 Pro\n")
    assert "\n# Vehicle-Id Component-Id Name Value Type\n1\t1\t" in out
    p = {name: float(value) for name, value in loaded.items()}
    assert p["CAL_ACC0_ID"] == ACC_ID and p["CAL_GYRO0_ID"] == GYRO_ID
    assert "not apply the calibration until" not in err and "CAL_GYRO0_ID is not written" not in err
    # the accelerometer: PX4's formula on the calibration's poses gives the reported rms |a|-1
    acc = cal.fitted_on.acc  # m/s^2, the driver's output
    exported = rms_norm_error_g(px4_accel(p, acc))
    assert f"exported {exported * 1e3:.4f} mg" in err and exported > 0
    # the gyroscope: PX4 keeps the bias only; its error on rates through the calibration's own model
    worst, rms = reported_rate_error(err)
    omega = uniform_directions(4000, rng=1) * np.radians(100.0)
    firmware = px4_gyro(p, cal.gyro.measure(omega))
    ratio = np.linalg.norm(firmware - omega, axis=1) / np.linalg.norm(omega, axis=1)
    # 4000 directions come within 0.5% of the worst one
    assert worst * 0.995 - PERCENT_ROUNDING < ratio.max() <= worst + PERCENT_ROUNDING
    assert np.sqrt(np.mean(ratio**2)) == pytest.approx(rms, rel=0.03)
    assert f"{worst * 100:.4g} deg/s at 100 deg/s" in err
    # each axis's scale error: PX4's reading of a turn about that gyro's own sensing axis, per rad/s
    axes = cal.gyro.physical().axes
    per_axis = np.diag(px4_gyro(p, cal.gyro.measure(axes))) - 1.0
    assert "gyro scale (" + ", ".join(f"{100 * e:+.3f}%" for e in per_axis) + " on x, y, z)" in err
    assert "not exported: gyro scale" in err and "not exported: gyro temperature terms: the calibration has none" in err


def test_px4_without_ids_says_the_firmware_will_not_apply_it_and_writes_other_slots(imu_cals, capsys):
    path = imu_cals["mikoff"]
    code, out, err = run(["export", path, "--format", "px4", "--instance", 1], capsys)
    assert code == 0, err
    loaded, skipped = qgc_load(out)
    assert skipped == [] and "CAL_ACC1_ID" not in loaded
    assert {f"CAL_ACC1_{a}{w}" for a in "XYZ" for w in ("OFF", "SCALE")} | {f"CAL_GYRO1_{a}OFF" for a in "XYZ"} \
        == set(loaded)
    assert ("note: PX4 applies a calibration only to the sensor whose device id is in CAL_ACC1_ID" in err
            and "will not apply the calibration until CAL_ACC1_ID holds the accelerometer's device id (--device-id N"
            in err)
    assert "note: CAL_GYRO1_ID is not written" in err and "--gyro-device-id N" in err
    # QGroundControl refuses a file saved from another system id: --vehicle-id writes the vehicle's
    code, out, err = run(["export", path, "--format", "px4", "--vehicle-id", 7], capsys)
    assert code == 0 and len(qgc_load(out, vehicle_id=7)[0]) == 9
    with pytest.raises(AssertionError, match="QGroundControl refuses"):
        qgc_load(out, vehicle_id=1)
    # px4-shell keeps the console commands, the same parameters
    code, shell, err = run(["export", path, "--format", "px4-shell", "--instance", 1], capsys)
    assert code == 0
    commands = [line.split() for line in shell.splitlines() if not line.startswith("#")]
    assert all(c[:2] == ["param", "set"] and len(c) == 4 for c in commands)
    assert {c[2]: c[3] for c in commands} == qgc_load(run(["export", path, "--format", "px4", "--instance", 1],
                                                          capsys)[1])[0]


def test_px4_thermal_block_carries_the_device_id_and_loads(tmp_path, capsys):
    """An extended calibration with a temperature polynomial: TC_A0_ID with --device-id, int32 types QGC accepts."""
    base = LumpedModel(np.diag([16300.0, 16450.0, 16700.0]), np.array([700.0, -360.0, -1830.0]))
    model = ExtendedModel(base, {"temperature_bias": [[0, 0, 0], [0.7e-3, -3e-5, 0], [0, 0, 0]]}, temp_ref=31.0)
    d = uniform_directions(24, rng=5)
    temp = np.linspace(20.0, 45.0, 24)
    ExtendedCalibration.from_model(model, "counts", fitted_on=FitPoses(model.measure(d, temp), temp)).save(
        tmp_path / "cal.json")
    argv = ["export", tmp_path / "cal.json", "--format", "px4", "--counts-per-g", 16384]
    code, out, err = run(argv + ["--device-id", 3 * 2**30], capsys)  # above 2^31: the int32 PX4 stores
    assert code == 0, err
    loaded, skipped = qgc_load(out)
    assert skipped == [] and int(loaded["TC_A0_ID"]) == int(loaded["CAL_ACC0_ID"]) == 3 * 2**30 - 2**32
    assert loaded["TC_A_ENABLE"] == "1" and f"CAL_ACC0_ID = {3 * 2**30} is written as the int32" in err
    code, out, err = run(argv, capsys)
    assert "TC_A0_ID" not in qgc_load(out)[0] and "note: TC_A0_ID is not written" in err


# ----------------------------------------------------------------------------- ArduPilot with pymavlink
def mavparm_load(path: Path) -> tuple[dict[str, float], str]:
    """pymavlink's own parameter-file loader (MAVParmDict.load, no vehicle): the parameters and what it printed."""
    mavparm = pytest.importorskip("pymavlink.mavparm")
    params = mavparm.MAVParmDict()
    printed = io.StringIO()
    with redirect_stdout(printed):
        assert params.load(str(path))
    return dict(params), printed.getvalue()


def test_ardupilot_file_loads_in_pymavlink_and_reproduces_the_losses(imu_cals, tmp_path, capsys):
    path = imu_cals["mikoff"]
    cal = calibration_files.load(path)
    code, err, _ = run(["export", path, "--format", "ardupilot", "--device-id", ACC_ID, "--gyro-device-id", GYRO_ID,
                        "--instance", 2, "-o", tmp_path / "imu3.param"], capsys)  # the report: on stdout
    assert code == 0, err
    p, printed = mavparm_load(tmp_path / "imu3.param")
    lines = [line for line in (tmp_path / "imu3.param").read_text().splitlines() if not line.startswith("#")]
    assert "Invalid line" not in printed and f"Loaded {len(lines)} parameters" in printed and len(p) == len(lines) == 11
    names = {f"INS_ACC3OFFS_{a}" for a in "XYZ"} | {f"INS_ACC3SCAL_{a}" for a in "XYZ"} | {f"INS_GYR3OFFS_{a}" for a in
                                                                                          "XYZ"}
    assert set(p) == names | {"INS_ACC3_ID", "INS_GYR3_ID"}
    assert p["INS_ACC3_ID"] == ACC_ID and p["INS_GYR3_ID"] == GYRO_ID
    # values round-trip: what pymavlink read is what the file says (9 significant digits)
    for line in lines:
        name, value = line.split(",")
        assert p[name] == float(value)
    # ArduPilot's formulas (AP_InertialSensor_Backend.cpp: _rotate_and_correct_accel, _rotate_and_correct_gyro)
    acc = cal.fitted_on.acc
    firmware = (acc - [p[f"INS_ACC3OFFS_{a}"] for a in "XYZ"]) * [p[f"INS_ACC3SCAL_{a}"] for a in "XYZ"]
    assert f"exported {rms_norm_error_g(firmware) * 1e3:.4f} mg" in err
    worst, _ = reported_rate_error(err)
    omega = uniform_directions(4000, rng=2) * np.radians(100.0)
    gyro = cal.gyro.measure(omega) - [p[f"INS_GYR3OFFS_{a}"] for a in "XYZ"]
    ratio = np.linalg.norm(gyro - omega, axis=1) / np.linalg.norm(omega, axis=1)
    assert worst * 0.995 - PERCENT_ROUNDING < ratio.max() <= worst + PERCENT_ROUNDING
    assert "INS_GYR_CAL = 1" in err and "replacing INS_GYR3OFFS_*" in err
    # without the ids: said plainly
    code, out, err = run(["export", path, "--format", "ardupilot"], capsys)
    assert "INS_ACC_ID" not in out and "the firmware will not apply the calibration until INS_ACC_ID holds" in err


def test_ardupilot_gyro_in_counts_needs_its_sensitivity_and_reports_the_g_sensitivity(imu_cals, tmp_path, capsys):
    """imu_tk's Xsens log (unsigned 16-bit counts, g-sensitivity fitted): offsets in rad/s of the driver's output."""
    path = imu_cals["xsens"]
    cal = calibration_files.load(path)
    argv = ["export", path, "--format", "ardupilot", "--counts-per-g", XSENS_COUNTS_PER_G, "--max-loss", 100]
    code, _, err = run(argv, capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and "give --counts-per-dps (" in err
    code, err, _ = run(argv + ["--counts-per-dps", XSENS_COUNTS_PER_DPS, "-o", tmp_path / "x.param"], capsys)
    assert code == 0, err
    p, printed = mavparm_load(tmp_path / "x.param")
    assert "Invalid line" not in printed
    k = np.radians(1.0) / XSENS_COUNTS_PER_DPS
    # the driver subtracts the same mid-scale 32768 from the gyro counts as from the accelerometer's
    assert "mid-scale 32768" in err
    np.testing.assert_allclose([p[f"INS_GYROFFS_{a}"] for a in "XYZ"], k * (cal.gyro.bias - 32768.0), rtol=1e-8)
    # the g-sensitivity's rate error under 1 g: ArduPilot's output at rest, every direction of gravity
    m = re.search(r"rate error up to ([\d.]+) deg/s under a 1 g specific force", err)
    assert m, err
    f = uniform_directions(4000, rng=3)
    raw = cal.gyro.measure(np.zeros_like(f), f)
    at_rest = (raw - 32768.0) * k - [p[f"INS_GYROFFS_{a}"] for a in "XYZ"]
    worst = np.degrees(np.linalg.norm(at_rest, axis=1)).max()
    assert float(m.group(1)) * 0.995 < worst <= float(m.group(1)) * (1 + 1e-3)


def test_gyro_options_refused_for_an_accelerometer_calibration(tmp_path, capsys):
    model = LumpedModel(np.diag([1.01, 0.99, 1.0]), np.array([0.01, -0.02, 0.03]))
    from optcal.families.caltypes import LumpedCalibration

    LumpedCalibration.from_model(model, "g", FitPoses(model.measure(uniform_directions(20, rng=1)))).save(
        tmp_path / "cal.json")
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "px4", "--gyro-device-id", GYRO_ID], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and "which has no gyroscope" in err
    code, out, err = run(["export", tmp_path / "cal.json", "--format", "px4"], capsys)
    assert code == 0 and "CAL_GYRO" not in out + err and "gyro" not in out


# ----------------------------------------------------------------------------- C header of an imu calibration
C_MAIN = r"""
#include <stdio.h>
#include "cal.h"
int main(void)
{
    double a[3], g[3], out_g[3], out_w[3];
    while (scanf("%lf %lf %lf %lf %lf %lf", &a[0], &a[1], &a[2], &g[0], &g[1], &g[2]) == 6) {
        optcal_apply_accel(a, out_g);
        %GYRO%;
        printf("%.17g %.17g %.17g %.17g %.17g %.17g\n", out_g[0], out_g[1], out_g[2], out_w[0], out_w[1], out_w[2]);
    }
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc) on this machine")
@pytest.mark.parametrize("name", ["mikoff", "xsens"])
def test_c_header_applies_the_gyroscope_too(name, imu_cals, shared_data, tmp_path, capsys):
    """The header of a real imu calibration, compiled: accelerometer and gyroscope as ``optcal apply`` gives them."""
    path = imu_cals[name]
    code, report, err = run(["export", path, "--format", "c", "-o", tmp_path / "cal.h"], capsys)
    assert code == 0, err
    g_sens = name == "xsens"
    assert "exported: the whole gyroscope model T_g (g - b_g" + (" - G_g a)" if g_sens else ")") in report
    call = "optcal_apply_gyro(g, a, out_w)" if g_sens else "optcal_apply_gyro(g, out_w)"
    (tmp_path / "main.c").write_text(C_MAIN.replace("%GYRO%", call))
    subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-pedantic", "-o", str(tmp_path / "apply"),
                    str(tmp_path / "main.c"), "-lm"], check=True, cwd=tmp_path)
    # every 50th sample of the recording, through optcal apply and through the compiled header
    if g_sens:
        frame = pd.read_csv(shared_data / "imutk-xsens" / "xsens_imutk.csv").iloc[::50]
        frame.to_csv(tmp_path / "rec.csv", index=False)
        raw = frame.iloc[:, 1:7].to_numpy(float)
    else:
        raw = np.loadtxt(shared_data / "mikoff-mpu9150" / "imu0.log")[::50]
        np.savetxt(tmp_path / "rec.csv", raw, fmt="%.5f")
    extra = [] if g_sens else ["--rate", 100]
    code, _, err = run(["apply", path, tmp_path / "rec.csv", "-o", tmp_path / "out.csv", "--format", "raw", *extra],
                       capsys)
    assert code == 0, err
    applied = pd.read_csv(tmp_path / "out.csv")[["ax_g", "ay_g", "az_g", "gx_rad_s", "gy_rad_s", "gz_rad_s"]].to_numpy()
    stdin = "\n".join(" ".join(repr(float(v)) for v in row) for row in raw)
    c_out = np.loadtxt(subprocess.run([str(tmp_path / "apply")], input=stdin, capture_output=True, text=True,
                                      check=True).stdout.splitlines())
    assert len(c_out) == len(applied) > 100
    np.testing.assert_allclose(c_out[:, :3], applied[:, :3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(c_out[:, 3:], applied[:, 3:], rtol=0, atol=1e-12)
    assert np.abs(applied[:, 3:]).max() > 0.5  # the recording's moves, not only its rests


def test_ardupilot_thermal_terms_of_the_second_imu_load_in_pymavlink(tmp_path, capsys):
    """``--instance 1``: INS_ACC2OFFS/SCAL, INS_TCAL2_* and INS_ACC2_CALTEMP; TCal::correct_sensor reproduces the model."""
    base = LumpedModel(np.diag([16300.0, 16450.0, 16700.0]), np.array([700.0, -360.0, -1830.0]))
    model = ExtendedModel(base, {"temperature_bias": [[0.4e-3, 0, 0], [0, 0, 0], [-0.9e-3, 2e-5, -1e-6]]}, temp_ref=31.0)
    d = uniform_directions(24, rng=6)
    temp = np.linspace(20.0, 45.0, 24)
    cal = ExtendedCalibration.from_model(model, "counts", fitted_on=FitPoses(model.measure(d, temp), temp))
    cal.save(tmp_path / "cal.json")
    code, _, err = run(["export", tmp_path / "cal.json", "--format", "ardupilot", "--counts-per-g", 16384,
                        "--instance", 1, "-o", tmp_path / "imu2.param"], capsys)
    assert code == 0, err
    p, printed = mavparm_load(tmp_path / "imu2.param")
    assert "Invalid line" not in printed and not any(name.startswith(("INS_TCAL1", "INS_ACC1", "INS_ACCOFFS"))
                                                     for name in p)
    # AP_InertialSensor_tempcal.cpp, TCal::correct_sensor: v -= p(T - 35) - p(CALTEMP - 35), T and CALTEMP clamped
    c = [np.array([p[f"INS_TCAL2_ACC{n}_{a}"] for a in "XYZ"]) for n in (1, 2, 3)]

    def poly(x):
        x = np.asarray(x, float)[..., None]
        return (c[0] + (c[1] + c[2] * x) * x) * x * 1e-6

    lo, hi = p["INS_TCAL2_TMIN"], p["INS_TCAL2_TMAX"]
    assert p["INS_TCAL2_ENABLE"] == 1
    v = cal.fitted_on.acc * G / 16384 - poly(np.clip(temp, lo, hi) - 35.0) + poly(np.clip(p["INS_ACC2_CALTEMP"], lo, hi) - 35.0)
    v = (v - [p[f"INS_ACC2OFFS_{a}"] for a in "XYZ"]) * [p[f"INS_ACC2SCAL_{a}"] for a in "XYZ"]
    np.testing.assert_allclose(v / G, cal.correct(cal.fitted_on.acc, temp), atol=2e-8)  # axis-aligned: exact


def test_gyro_loss_across_the_recordings_moves(imu_cals, shared_data, capsys):
    """``--poses RECORDING``: the firmware's gyro (bias only, rad/s as read) carries gravity across the moves as the
    fit's own "before" (bias removed, nominal rad/s scale) did, and the full model as its "after"."""
    path = imu_cals["mikoff"]
    fit = calibration_files.load(path)
    code, out, err = run(["export", path, "--format", "ardupilot", "--poses", shared_data / "mikoff-mpu9150" / "imu0.log",
                          "--poses-rate", 100], capsys)
    assert code == 0, err
    assert fit.before == "bias removed, nominal rad/s scale"
    line = (f"gravity carried across the recording's {fit.angles_after_deg.size} moves, rms angle to the next pose: "
            f"full gyro model {fit.rms_angle_after_deg:.3f} deg, the firmware's offsets only "
            f"{fit.rms_angle_before_deg:.3f} deg")
    assert f"note: {line}" in err and f"# {line}" in out
    assert fit.rms_angle_before_deg > 3 * fit.rms_angle_after_deg
