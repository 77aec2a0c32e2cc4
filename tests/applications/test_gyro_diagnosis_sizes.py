"""The gyroscope's diagnosis (issue 39) at the issue's sizes: each effect planted so that the gravity prediction's
residual over all moves rises by 4-15 standard deviations of its noise (a time offset: judged inside the moves), here
at the low end of that range, 4-5 SDs, where a diagnosis is weakest.

The sizing is measured, not assumed: under the unplanted recording's noise model (the moves' budget
:func:`optcal.applications.diagnosis.gyro_problem.measured_noise`, each move's two components across gravity of
variance ``E/2``), the paper's model's ``Σ angle² / (E/2)`` over the ``m`` moves is a χ² of ``2m`` degrees of freedom,
its standard deviation ``√(4m)``; a plant's rise is that sum after minus before, over it.  A time offset leaves the
moves' ends unchanged to first order (the whole turn is the same whichever way the samples shift), so its size is the
planted shift over the standard error of the inside-move estimate of the unplanted recording.

Each effect is planted in the raw gyro samples of the real recording as read (the Xsens log of imu_tk, gyro in
counts; mikoff's hand-held MPU-9150 imu0), through the unplanted recording's own calibration, and the moves rebuilt
on the recording's own rests (:func:`optcal.families.gyro.moves.moves_from_arrays`, no second read or segmentation:
each case costs one gyro fit and one diagnosis, 4-8 s on imu0, 15-20 s on the Xsens log).  The diagnosis must name
it on the right axis within 40 % (over what the unplanted recording's own diagnosis says of it) and nothing the
unplanted recording does not have.  The recordings' own effects are part of the expectation: the Xsens log's
g-sensitivity (all three axes; its gravity prediction 0.44° → 0.13°), imu0's gyro about 15 ms behind its
accelerometer.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from helpers.common import SHARED

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
MIKOFF = SHARED / "data" / "mikoff-mpu9150" / "imu0.log"

#: The issue's range of a planted effect's rise, in standard deviations of the residual's noise.
RISE_SD = (4.0, 15.0)


def _quick() -> object:
    from optcal.applications.diagnosis.gyro_diagnosis import GyroDiagnosisSettings

    return GyroDiagnosisSettings(simulations=0)  # the band is not what these cases test (its own test below)


QUICK = _quick()


@dataclass
class Base:
    """The unplanted recording, read once: its samples, rests, calibration, diagnosis and moves' noise."""

    name: str
    rec: Any
    intervals: list[tuple[int, int]]
    sigma: np.ndarray
    imu: Any
    units: Any
    diag: Any
    move_rad2: np.ndarray


def _chi2(diag: Any, move_rad2: np.ndarray) -> float:
    """The paper's model's gravity-prediction residual over the moves, over the noise (module docstring)."""
    return float(np.sum(np.radians(diag.angles_deg) ** 2 / (0.5 * move_rad2)))


@pytest.fixture(scope="module", params=["xsens", "mikoff"])
def base(request, tmp_path_factory) -> Base:
    from optcal.applications.diagnosis.gyro_diagnosis import diagnose_gyro
    from optcal.applications.diagnosis.gyro_problem import GyroParams, gyro_data, measured_noise
    from optcal.data import load_with_segmentation
    from optcal.data.units import decide_gyro_units
    from optcal.families.gyro.estimator import GyroSettings, calibrate_imu_loaded
    from optcal.families.gyro.moves import moves_from_segmentation

    path: Path
    if request.param == "xsens":
        if not XSENS.exists():
            pytest.skip("../shared/data/imutk-xsens is not present")
        path = XSENS
    else:
        if not MIKOFF.exists():
            pytest.skip("../shared/data/mikoff-mpu9150 is not present")
        raw = pd.read_csv(MIKOFF, sep=r"\s+", header=None, names=["ax", "ay", "az", "gx", "gy", "gz"])
        raw.insert(0, "t", np.arange(len(raw)) / 100.0)  # 100 Hz (its PROVENANCE.md)
        path = tmp_path_factory.mktemp("mikoff") / "imu0.csv"
        raw.to_csv(path, index=False)
    loaded = load_with_segmentation(path)
    imu = calibrate_imu_loaded(loaded, settings=GyroSettings(accept_gyro_fit=True))
    seg = loaded.segmentation
    rec = seg.recording
    moves = moves_from_segmentation(seg)
    units = decide_gyro_units(rec.gyro[rec.usable], moves.gyro_means.mean(axis=0), None, rec.gyro_units)
    diag = diagnose_gyro(moves, imu.accelerometer, imu.gyro, QUICK)
    noise = measured_noise(gyro_data(moves, imu.accelerometer),
                           GyroParams(np.asarray(imu.gyro.T), np.asarray(imu.gyro.bias), (), ()))
    return Base(request.param, rec, [(iv.start, iv.stop) for iv in seg.intervals],
                np.array([iv.sigma for iv in seg.intervals]), imu, units, diag, noise.move_rad2)


def _named(diag: Any) -> set[tuple[str, str]]:
    return {(f.effect, a) for f in diag.findings for a in (f.axes or ["-"])}


def _estimate(diag: Any, effect: str, axis: str) -> float:
    if effect == "time_offset":
        return float(diag.time_offset["dt_s"])  # measured whether named or not
    for f in diag.findings:
        if f.effect == effect:
            return float(f.estimate.get(axis, 0.0))
    return 0.0


def test_the_recordings_own_effects(base):
    if base.name == "xsens":
        # imu_tk's Xsens log: a g-sensitivity on every axis (calibrate --imu --g-sensitivity: 0.43° → 0.13°)
        assert {e for e, _ in _named(base.diag)} == {"g_sensitivity", "time_offset"}
        assert len(base.diag.findings[0].axes) == 3
        assert base.diag.heldout_final_deg < 0.5 * base.diag.heldout_baseline_deg and base.diag.gain > 2.0
        # and its gyro about 2 ms early (the figure), named once each move's lever arm is fitted beside the
        # offset (−2.01 ± 0.51 ms, t 4.0, its angular acceleration from the rates' 0.1 s running mean; −2.29 ± 0.56 ms
        # from the raw rates; without the lever arm −1.88 ± 0.75 ms, t 2.5 below the critical 3.1)
        assert -3e-3 < base.diag.time_offset["dt_s"] < -1.4e-3 and base.diag.time_offset["significant"] is True
    else:
        # imu0's gyro stream about 15 ms behind its accelerometer's (t 8.7), nothing else
        assert _named(base.diag) == {("time_offset", "-")} and 0.010 < base.diag.time_offset["dt_s"] < 0.020


# effect, axis, size on the Xsens log, size on imu0 (SI; g-sensitivity in rad/s per g on the axis' own specific
# force, drift as the bias' change from the session's middle to its ends, nonlinearity k in measured = ω + k ω²,
# temperature in rad/s per °C with a temperature that rises and falls, the time offset the gyro's lateness in s):
# each measured at 4-5 SDs of the rise (the test checks it)
PLANTS = [
    ("g_sensitivity", "z", 5e-3, 4.4e-3),
    ("gyro_bias_drift", "x", 2.4e-3, 4.2e-3),
    ("gyro_scale_nonlinearity", "y", -2.2e-3, -6.5e-3),
    ("gyro_temperature_bias", "x", 2.4e-4, 3.8e-4),
    ("time_offset", "-", -2.5e-3, 8e-3),
]


@pytest.mark.parametrize("effect, axis, xsens_size, mikoff_size", PLANTS, ids=[p[0] for p in PLANTS])
def test_an_effect_at_four_to_five_sds_is_named_on_its_axis(base, effect, axis, xsens_size, mikoff_size):
    from optcal.applications.diagnosis.gyro_diagnosis import diagnose_gyro
    from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro
    from optcal.families.gyro.moves import moves_from_arrays

    size = xsens_size if base.name == "xsens" else mikoff_size
    rec, T, b = base.rec, base.imu.gyro.T, base.imu.gyro.bias
    t = np.asarray(rec.t, dtype=float)
    g = np.array(rec.gyro, dtype=float, copy=True)
    temp = rec.temp
    i = "xyz".index(axis) if axis != "-" else 0
    expected = size
    if effect == "g_sensitivity":
        g[:, i] += size * base.imu.accelerometer.correct(rec.acc)[:, i] / T[i, i]
        expected = size / 9.80665  # reported per m/s², the diagonal term
    elif effect == "gyro_bias_drift":
        expected = size / (0.5 * (t[-1] - t[0]))  # rad/s per s
        g[:, i] += expected * (t - t.mean()) / T[i, i]
    elif effect == "gyro_scale_nonlinearity":
        g[:, i] += size * ((g - b) @ T.T)[:, i] ** 2 / T[i, i]
        expected = -size  # the correction's s = −k
    elif effect == "gyro_temperature_bias":
        temp = 25.0 + 8.0 * np.sin(2 * np.pi * (t - t[0]) / (t[-1] - t[0]))
        g[:, i] += size * (temp - temp.mean()) / T[i, i]
    else:
        g = np.column_stack([np.interp(t - size, t, g[:, j]) for j in range(3)])
    if base.name == "xsens":
        g = np.round(g)  # the Xsens log's counts stay counts
    settings = GyroSettings(accept_gyro_fit=True)
    moves = moves_from_arrays(t, rec.acc, g, base.intervals, rec.usable, base.sigma, temp)
    imu = calibrate_gyro(moves, base.imu.accelerometer, base.units, settings)
    after = diagnose_gyro(moves, base.imu.accelerometer, imu.gyro, QUICK)
    # the size follows the rule, at its low end
    if effect == "time_offset":
        rise = abs(size) / base.diag.time_offset["se_s"]
    else:
        rise = (_chi2(after, base.move_rad2) - _chi2(base.diag, base.move_rad2)) / np.sqrt(4 * base.move_rad2.size)
    assert RISE_SD[0] <= rise <= 5.5, rise
    assert _named(after) == _named(base.diag) | {(effect, axis)}, (after.steps, after.time_offset)
    found = _estimate(after, effect, axis) - _estimate(base.diag, effect, axis)
    assert found == pytest.approx(expected, rel=0.4), (found, expected)
    assert after.gain >= 1.0


def test_what_only_the_rests_carry_is_not_named(base):
    """A bias that wanders between the rests (bias instability sampled at each rest), its values following the pose
    on x (1e-3 rad/s per g of the specific force on x) and the moves carrying none of it: the rests' means alone say
    g-sensitivity, the moves' gravity prediction does not improve held out, and nothing new is named (before the
    held-out moves were required to improve by themselves, a g-sensitivity of x was named with a gain below 1, as on
    a stranger's imu_tk log)."""
    from optcal.applications.diagnosis.gyro_diagnosis import diagnose_gyro
    from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro
    from optcal.families.gyro.moves import moves_from_arrays

    if base.name != "mikoff":
        pytest.skip("one recording is enough for the rule (imu0: 4 s)")
    rec, T = base.rec, base.imu.gyro.T
    g = np.array(rec.gyro, dtype=float, copy=True)
    f = base.imu.accelerometer.correct(rec.acc)
    for start, stop in base.intervals:
        g[start:stop, 0] += 1e-3 * float(np.mean(f[start:stop, 0])) / T[0, 0]
    moves = moves_from_arrays(np.asarray(rec.t, dtype=float), rec.acc, g, base.intervals, rec.usable, base.sigma,
                              rec.temp)
    settings = GyroSettings(accept_gyro_fit=True)
    after = diagnose_gyro(moves, base.imu.accelerometer, calibrate_gyro(moves, base.imu.accelerometer, base.units,
                                                                         settings).gyro, QUICK)
    assert _named(after) == _named(base.diag), after.steps
    assert after.gain >= 1.0


def test_moves_beyond_the_band_unexplained_are_said_so():
    """Moves beyond the band with nothing named: the report says the candidates tested explain none of them and
    gives the best candidate's evidence, not "none named" alone (a stranger's log, ChanghyeonKim93's imu_good2:
    χ² 218 for 17 dof in calibrate --imu, which points to the diagnosis)."""
    from optcal.applications.diagnosis.gyro_diagnosis import GyroDiagnosis
    from optcal.applications.diagnosis.gyro_problem import GyroParams

    step = {"term": "gyro_scale_nonlinearity(y)", "lr": 14.9, "p": 1.1e-4, "level": 2.2e-3, "delta_bic": -10.7,
            "heldout_moves_t": -0.34, "heldout_critical_t": 1.71, "accepted": False}
    diag = GyroDiagnosis([], [step], np.array([1.7, 0.2]), np.array([1.4, 0.5]), np.array([1.7, 0.2]), 1.2, 1.2,
                         {"tested": True}, ["g_sensitivity(x)", "gyro_bias_drift(x)", "time_offset"], {},
                         GyroParams(np.eye(3), np.zeros(3), (), ()), [], {})
    text = "\n".join(diag.report_lines())
    assert "explained by none of the candidates tested (g_sensitivity, gyro_bias_drift, time_offset)" in text
    assert "best candidate: gyro_scale_nonlinearity(y)" in text and "held-out moves' t -0.34" in text
    inside = GyroDiagnosis([], [step], np.array([0.2]), np.array([1.4]), np.array([0.2]), 1.2, 1.2, {"tested": True},
                           ["time_offset"], {}, GyroParams(np.eye(3), np.zeros(3), (), ()), [], {})
    assert "none named (an effect below the tests' power" in "\n".join(inside.report_lines())


def test_the_band_is_simulated_along_the_recorded_moves(base):
    """The band: the paper's model integrated along each recorded move many times with the measured noise (white
    rate noise of the rests' angle random walk, the poses' direction noise, the budget's other sources as Gaussian
    tilts).  Its mean square per move agrees with the linearised budget's (which averages each move's axes against
    gravity as two thirds of an isotropic error) within what 400 runs resolve and the moves' geometry moves it
    (imu0, 21 moves: median ratio 1.01, 0.83-1.09 at 2,000 runs); the band the diagnosis reports is its Rayleigh
    bound at the family-wise level."""
    import math

    from optcal.applications.diagnosis.gyro_diagnosis import (GyroDiagnosisSettings, diagnose_gyro,
                                                              simulated_move_rad2)
    from optcal.applications.diagnosis.gyro_problem import GyroParams, gauss_newton, gyro_data, measured_noise
    from optcal.families.gyro.moves import moves_from_arrays

    if base.name != "mikoff":
        pytest.skip("one recording is enough (imu0: 21 moves, about 3 s)")
    rec = base.rec
    moves = moves_from_arrays(np.asarray(rec.t, dtype=float), rec.acc, rec.gyro, base.intervals, rec.usable,
                              base.sigma, rec.temp)
    data = gyro_data(moves, base.imu.accelerometer)
    paper = GyroParams(np.asarray(base.imu.gyro.T), np.asarray(base.imu.gyro.bias), (), ())
    ratio = simulated_move_rad2(data, paper, 400, seed=3) / base.move_rad2
    assert 0.9 < float(np.median(ratio)) < 1.1 and ratio.min() > 0.6 and ratio.max() < 1.5, ratio
    diag = diagnose_gyro(moves, base.imu.accelerometer, base.imu.gyro,
                         GyroDiagnosisSettings(simulations=60, effects=("time_offset",)))
    assert diag.band_runs == 60 and diag.linearised_band_deg is not None
    fitted = gauss_newton(data, measured_noise(data, paper), paper, iterations=4)  # the diagnosis's paper's model
    simulated = simulated_move_rad2(data, fitted, 60, 0)
    assert diag.band_deg == pytest.approx(np.degrees(np.sqrt(simulated * math.log(data.n_moves / 0.02))), rel=1e-9)
    assert "band of 60 simulations of the fitted model" in "\n".join(diag.report_lines())
