"""The gyroscope's diagnosis (``optcal diagnose --imu``, issue 39) on real recordings with planted effects.

Each effect is planted in the raw gyro samples of a real recording (the Xsens log of imu_tk, gyro in counts; one of
mikoff's hand-held MPU-9150 units), in the raw units through the unplanted recording's own IMU calibration, and the
diagnosis must name it on the right axis with its estimate within 40 % -- over what the unplanted recording's own
diagnosis says of the same effect -- and name nothing the unplanted recording does not have.  The recordings' own
effects are part of the expectation: the Xsens log's g-sensitivity (all three axes; its gravity prediction 0.44° →
0.13°) and the MPU-9150's gyro stream about 15 ms behind its accelerometer's.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from helpers.common import SHARED

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
MIKOFF = SHARED / "data" / "mikoff-mpu9150" / "imu0.log"
ACC, GYRO = ["ax", "ay", "az"], ["gx", "gy", "gz"]


def _frame(name: str) -> pd.DataFrame:
    if name == "xsens":
        if not XSENS.exists():
            pytest.skip("../shared/data/imutk-xsens is not present")
        raw = pd.read_csv(XSENS)
        return pd.DataFrame({"t": raw["t_s"], **{a: raw[f"acc_{a[1]}_counts"] for a in ACC},
                             **{g: raw[f"gyro_{g[1]}_counts"] for g in GYRO}})
    if not MIKOFF.exists():
        pytest.skip("../shared/data/mikoff-mpu9150 is not present")
    raw = pd.read_csv(MIKOFF, sep=r"\s+", header=None, names=ACC + GYRO)
    raw.insert(0, "t", np.arange(len(raw)) / 100.0)  # 100 Hz (its PROVENANCE.md)
    return raw


def _diagnose(frame: pd.DataFrame, path: Path):
    from optcal.applications.diagnosis.gyro_diagnosis import diagnose_gyro
    from optcal.data import load_with_segmentation
    from optcal.families.gyro.estimator import GyroSettings, calibrate_imu_loaded
    from optcal.families.gyro.moves import moves_from_segmentation

    frame.to_csv(path, index=False)
    loaded = load_with_segmentation(path)
    imu = calibrate_imu_loaded(loaded, settings=GyroSettings(accept_gyro_fit=True))
    return imu, diagnose_gyro(moves_from_segmentation(loaded.segmentation), imu.accelerometer, imu.gyro)


@pytest.fixture(scope="module", params=["xsens", "mikoff"])
def unplanted(request, tmp_path_factory):
    frame = _frame(request.param)
    imu, diag = _diagnose(frame, tmp_path_factory.mktemp(request.param) / "unplanted.csv")
    return request.param, frame, imu, diag


def _named(diag) -> set[tuple[str, str]]:
    return {(f.effect, a) for f in diag.findings for a in (f.axes or ["-"])}


def _estimate(diag, effect: str, axis: str) -> float:
    for f in diag.findings:
        if f.effect == effect:
            return float(f.estimate["dt_s"] if effect == "time_offset" else f.estimate.get(axis, 0.0))
    return 0.0


def test_the_recordings_own_effects(unplanted):
    name, _, _, diag = unplanted
    if name == "xsens":
        # imu_tk's Xsens log: a g-sensitivity on every axis (calibrate --imu --g-sensitivity: 0.43° → 0.13°)
        assert {e for e, _ in _named(diag)} == {"g_sensitivity"} and len(diag.findings[0].axes) == 3
        assert diag.heldout_final_deg < 0.5 * diag.heldout_baseline_deg and diag.gain > 2.0
        # its gyro about 2 ms early: measured, not named at the family-wise level
        assert -3e-3 < diag.time_offset["dt_s"] < -1e-3 and diag.time_offset["significant"] is False
    else:
        assert ("time_offset", "-") in _named(diag) and 0.010 < diag.time_offset["dt_s"] < 0.020


# effect, axis, size (SI), the raw change: sizes a MEMS gyro shows (0.06 °/s/g, a bias moving by ±0.15 °/s over the
# session, 0.4 % at 1 rad/s, 0.017 °/s/°C, 5 ms)
PLANTS = [
    ("g_sensitivity", "z", 1e-3),          # rad/s per g, on z from the specific force on z
    ("gyro_bias_drift", "x", 2.6e-3),      # rad/s: the bias' change from the session's middle to its ends
    ("gyro_scale_nonlinearity", "y", -4e-3),  # measured = ω + k ω², k in (rad/s)⁻¹: the correction's s = −k
    ("gyro_temperature_bias", "x", 3e-4),  # rad/s per °C, with a temperature that rises and falls
    ("time_offset", "-", 5e-3),            # the gyro's samples late by 5 ms
]


@pytest.mark.parametrize("effect, axis, size", PLANTS, ids=[p[0] for p in PLANTS])
def test_a_planted_gyro_effect_is_named_on_its_axis(unplanted, tmp_path, effect, axis, size):
    name, frame, imu, before = unplanted
    planted = frame.copy()
    t = planted["t"].to_numpy()
    g = planted[GYRO].to_numpy(dtype=float, copy=True)
    T, b = imu.gyro.T, imu.gyro.bias
    f = imu.accelerometer.correct(planted[ACC].to_numpy(dtype=float))
    i = "xyz".index(axis) if axis != "-" else None
    expected = size
    if effect == "g_sensitivity":
        g[:, i] += size * f[:, i] / T[i, i]
        expected = size / 9.80665  # reported per m/s², the diagonal term
    elif effect == "gyro_bias_drift":
        expected = size / (0.5 * (t[-1] - t[0]))  # rad/s per s
        g[:, i] += expected * (t - t.mean()) / T[i, i]
    elif effect == "gyro_scale_nonlinearity":
        omega = (g - b) @ T.T
        g[:, i] += size * omega[:, i] ** 2 / T[i, i]
        expected = -size
    elif effect == "gyro_temperature_bias":
        temp = 25.0 + 8.0 * np.sin(2 * np.pi * (t - t[0]) / (t[-1] - t[0]))
        planted["temp"] = temp
        g[:, i] += size * (temp - temp.mean()) / T[i, i]
    else:
        for j in range(3):
            g[:, j] = np.interp(t - size, t, g[:, j])
    planted[GYRO] = np.round(g) if name == "xsens" else g  # the Xsens log's counts stay counts
    _, after = _diagnose(planted, tmp_path / "planted.csv")
    assert _named(after) == _named(before) | {(effect, axis)}, (after.steps, after.time_offset)
    found = _estimate(after, effect, axis) - _estimate(before, effect, axis)
    if effect == "time_offset" and ("time_offset", "-") not in _named(before):
        found = _estimate(after, effect, axis) - before.time_offset["dt_s"]  # measured though not named
    assert found == pytest.approx(expected, rel=0.4), (found, expected)
    assert after.gain >= 1.0


def test_diagnose_imu_from_the_command_line(tmp_path, capsys):
    from optcal.cli.main import main

    if not XSENS.exists():
        pytest.skip("../shared/data/imutk-xsens is not present")
    out = tmp_path / "imu.json"
    code = main(["diagnose", str(XSENS), "--imu", "--simulations", "0", "--json", "-o", str(out)])
    result = json.loads(capsys.readouterr().out)
    assert code in (0, None)
    gyro = [f for f in result["findings"] if f["sensor"] == "gyroscope"]
    assert gyro and all(set(f) >= {"sensor", "effect", "axes", "estimate"} for f in gyro)
    assert all(f["sensor"] == "accelerometer" for f in result["findings"] if f not in gyro)
    assert result["gain"] == pytest.approx(result["gyroscope"]["gain"]) and result["gain"] > 2.0
    assert len(result["gyroscope"]["moves"]) == 37
    saved = json.loads(out.read_text())
    assert saved["cal_type"] == "imu"
    # the saved calibration's g-sensitivity carries the gravity prediction the diagnosis found
    code = main(["check", str(out), str(XSENS), "--json"])
    check = json.loads(capsys.readouterr().out)
    assert check["gravity_prediction"]["rms_deg_after"] < 0.2
