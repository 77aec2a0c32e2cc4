"""The magnetometer's diagnosis (``optcal diagnose --sensor mag``, issue 38) on a real hand-turned session with
planted effects: a local disturbance (a field of 4 % of the Earth's added for 15 % of the session, or the field
bent by 3° of dip at constant strength), a motor's current and a temperature through added columns.  The unplanted
session's own departures (two stretches of about 2.5 s whose norm residual leaves the rest's; leaving them out moves
the heading and the field by under one standard error, so they are not named) are part of the expectation, not
asserted away.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from helpers.common import SHARED

CK = SHARED / "data" / "ckexplorer-holds" / "acc_mag_log.csv"
MAG = ["mx", "my", "mz"]


@pytest.fixture(scope="module")
def frame() -> pd.DataFrame:
    if not CK.exists():
        pytest.skip("../shared/data/ckexplorer-holds is not present")
    return pd.read_csv(CK)


def _diagnose(fr: pd.DataFrame, path):
    from optcal.applications.magnetic.diagnosis import diagnose_mag
    from optcal.families.mag.calibration import calibrate_mag
    from optcal.families.mag.samples import read_mag

    fr.to_csv(path, index=False)
    samples = read_mag(path)
    return diagnose_mag(samples, calibrate_mag(samples))


def test_a_planted_disturbance_is_found_where_it_was(frame, tmp_path):
    fr = frame.copy()
    n = len(fr)
    a, b = int(0.66 * n), int(0.81 * n)
    field = 0.3086  # gauss: the session's field strength (optcal calibrate --sensor mag)
    delta = np.array([0.7, -0.45, 0.55]) * 0.04 * field / np.linalg.norm([0.7, -0.45, 0.55])
    fr.loc[a:b - 1, MAG] += delta
    diag = _diagnose(fr, tmp_path / "disturbed.csv")
    stretches = [f for f in diag.findings if "disturb" in f.effect]
    hit = [f for f in stretches if f.stretch["start_sample"] < b and f.stretch["stop_sample"] > a]
    assert hit, [f.to_dict() for f in diag.findings]
    f = hit[0]
    covered = min(b, f.stretch["stop_sample"]) - max(a, f.stretch["start_sample"])
    # the stretch found holds most of the planted one; its ends are found to within the planted length (the norm
    # residual of a field fixed to the sensor turns with it, so the stretch's ends are blurred by the session's turns)
    assert covered >= 0.7 * (b - a) and f.stretch["stop_sample"] - f.stretch["start_sample"] <= 2.0 * (b - a)
    assert diag.gain > 1.0 and diag.excluded >= covered
    assert f.to_dict()["sensor"] == "magnetometer" and "disturb" in f.to_dict()["effect"]
    # relevant in what a user reads: leaving it out turns the heading 0.29° (0.9 SE) and changes the field by 1.2 SE
    # of the calibration's own uncertainty, and the held-out residual gains 1.4 SE of that gain's uncertainty
    e = f.evidence
    assert max(e["moved_heading_se"], e["moved_field_se"]) > 1.0 and e["heldout_gain_se"] > 1.0
    assert e["heading_deg"] == pytest.approx(e["moved_heading_se"] * e["heading_se_deg"])


def test_a_coloured_noise_is_not_a_disturbance(frame, tmp_path):
    # ckexplorer's magnetometer every fourth sample (3000, the size of a short hand-turned session) with a coloured
    # noise added to each axis: a first-order autoregression of 300 samples' correlation and 0.01 gauss (3 % of the
    # field), nothing planted.  The search finds samples 1575-2525 (χ² 25.3 > 22.0; the noise colour 240); leaving
    # them out turns the heading 0.86° (0.95 SE) and the field +0.0025 gauss (1.4 SE), but the held-out residual gains
    # only 0.8 SE of that gain's uncertainty (0.0298 -> 0.0281): not named.  Before the held-out gain was weighed
    # against its own uncertainty (any gain counted) it was named, with the offsets moved 1.8 SE by batch means.
    from scipy.signal import lfilter

    fr = frame[MAG].iloc[::4].reset_index(drop=True)
    rho = math.exp(-1.0 / 300.0)
    noise = np.random.default_rng(1).standard_normal((len(fr), 3)) * 0.01 * math.sqrt(1.0 - rho**2)
    fr[MAG] += lfilter([1.0], [1.0, -rho], noise, axis=0)
    diag = _diagnose(fr, tmp_path / "coloured.csv")
    assert diag.colour > 100.0
    assert not diag.findings, [f.to_dict() for f in diag.findings]
    assert _departed(diag) == ["1575-2525"], diag.notes
    assert "SE of its gain" in next(n for n in diag.notes if n.startswith("samples 1575-2525"))


@pytest.mark.parametrize("column", ["current", "temp"])
def test_a_column_planted_offset_is_named_with_its_coefficient(frame, tmp_path, column):
    fr = frame.copy()
    n = len(fr)
    rng = np.random.default_rng(1)
    if column == "current":  # a motor's current held at levels of 0-15 A for 400 samples each
        x = np.repeat(rng.uniform(0.0, 15.0, n // 400 + 1), 400)[:n]
        k = np.array([0.002, -0.001, 0.0015])  # gauss per A (a few % of the field at full current)
    else:  # a temperature cycling by ±10 °C four times over the session (a heater's thermostat): a single slow rise
        # and fall is confounded with the session's own slow changes (fitted on the unplanted samples, such a column
        # takes a coefficient half the planted one's size), which four cycles are not (12 %)
        x = 25.0 + 10.0 * np.sin(np.linspace(0.0, 8.0 * np.pi, n))
        k = np.array([0.001, 0.0005, -0.0008])  # gauss per °C
    fr[column] = x
    fr[MAG] += np.outer(x - x.mean(), k)
    diag = _diagnose(fr, tmp_path / f"{column}.csv")
    effect = "current_interference" if column == "current" else "temperature_offset"
    named = [f for f in diag.findings if f.effect == effect]
    assert named, [f.to_dict() for f in diag.findings]
    est = np.array([named[0].estimate[a] for a in "xyz"])
    assert np.linalg.norm(est - k) <= 0.4 * np.linalg.norm(k), (est, k)
    assert diag.gain > 1.0


def test_diagnose_sensor_mag_json_and_saved_calibration(tmp_path, capsys):
    from optcal.cli.main import main

    if not CK.exists():
        pytest.skip("../shared/data/ckexplorer-holds is not present")
    out = tmp_path / "mag.json"
    code = main(["diagnose", str(CK), "--sensor", "mag", "--json", "-o", str(out)])
    result = json.loads(capsys.readouterr().out)
    assert code in (0, None)
    assert result["sensor"] == "magnetometer" and result["n_samples"] == 12000
    assert isinstance(result["findings"], list) and result["gain"] >= 1.0
    T, o = np.asarray(result["T"]), np.asarray(result["o"])
    m = pd.read_csv(CK)[MAG].to_numpy()
    assert abs(float(np.median(np.linalg.norm((m - o) @ T.T, axis=1))) - 1.0) < 0.01
    saved = json.loads(out.read_text())
    assert saved["cal_type"] == "magnetometer"
    # the frames' rotation and the dip refitted without the disturbed stretches, as the JSON's extended model
    assert np.allclose(saved["R_mag_to_acc"], result["extended"]["R_mag_to_acc"])
    assert saved["dip_deg"] == pytest.approx(result["extended"]["dip_deg"])
    assert main(["diagnose", str(CK), "--sensor", "mag", "--imu"]) == 2


def _bend(fr: pd.DataFrame, lo: int, hi: int, degrees: float) -> None:
    """Bend the field of rows ``lo:hi`` by ``degrees`` of dip at constant strength: the calibrated field (the
    session's own fit, in the accelerometer's frame) turned about each sample's east axis ``â × m̂`` (a world-frame
    turn about east, as steel beside the sensor bends the field), then back through ``T⁻¹`` and ``o``."""
    from optcal.core.rotations import exponential_map
    from optcal.families.mag.calibration import calibrate_mag
    from optcal.families.mag.samples import MagSamples
    from optcal.families.mag.units import decide_mag_units

    m = fr[MAG].to_numpy()
    acc = fr[["ax", "ay", "az"]].to_numpy()
    cal = calibrate_mag(MagSamples(m, decide_mag_units(m, None, "", None), acc=acc))
    T, o, R = cal.calibration.T, cal.calibration.o, cal.dip.R
    v = (m[lo:hi] - o) @ T.T @ R.T
    east = np.cross(acc[lo:hi], v)
    east /= np.linalg.norm(east, axis=1, keepdims=True)
    bent = np.stack([exponential_map(np.radians(degrees) * e) @ x for e, x in zip(east, v)])
    fr.loc[lo:hi - 1, MAG] = o + bent @ R @ np.linalg.inv(T).T


@pytest.mark.parametrize("degrees", [3.0, -3.0])
def test_a_planted_bend_of_the_dip_is_found_where_it_was(frame, tmp_path, degrees):
    # ckexplorer's dip residual: a block mean's σ about 0.7° (176 of 480 blocks at least half still): 3° is about 4
    # of them, over 15 % of the session; the field strength does not change at all (norms equal to 1e-15)
    fr = frame.copy()
    n = len(fr)
    a, b = int(0.66 * n), int(0.81 * n)
    before = np.linalg.norm(fr[MAG].to_numpy(), axis=1)
    _bend(fr, a, b, degrees)
    diag = _diagnose(fr, tmp_path / "bent.csv")
    assert diag.dip is not None and 0.2 < diag.dip.sigma_block < 2.0
    bends = [f for f in diag.findings if "disturb" in f.effect and f.stretch["channel"] == "dip"]
    assert len(bends) == 1, [f.to_dict() for f in diag.findings]
    f = bends[0]
    covered = min(b, f.stretch["stop_sample"]) - max(a, f.stretch["start_sample"])
    assert covered >= 0.7 * (b - a) and f.stretch["stop_sample"] - f.stretch["start_sample"] <= 2.0 * (b - a)
    # the bend's size within a third of the planted (the stretch's ends blurred by the turns, as the strength's)
    assert abs(f.stretch["dip_shift_deg"] - degrees) <= abs(degrees) / 3.0, f.to_dict()
    assert f.evidence["moved_dip_se"] > 1.0 and f.evidence["heldout_dip_ratio"] > 1.0
    assert "bent" in f.describe("gauss")
    assert np.allclose(np.linalg.norm(fr[MAG].to_numpy(), axis=1)[:a], before[:a])


def _departed(diag) -> list[str]:
    """The stretches found by the search: named, or said in a note not to be relevant."""
    named = [f"{f.stretch['start_sample']}-{f.stretch['stop_sample']}" for f in diag.findings if f.stretch is not None]
    return sorted(named + [n.split(":")[0].removeprefix("samples ") for n in diag.notes if n.startswith("samples ")])


def test_the_recording_as_it_is_has_no_bend_of_the_dip(frame, tmp_path):
    # the search finds the same two strength stretches as before the dip channel (4225-4500, 5575-5825); leaving
    # them out turns the heading by under one standard error (0.35 and 0.48; the field 0.45 and 0.35), so neither is
    # named (before the heading and field: the offsets by batch means, 0.5 and 0.7)
    # (with the AR(1) inflation's smaller standard errors they were, at 3.3 and 3.8); the dip's slow drift over the
    # session (about 1° from the first half to the second) is a majority, said in a note, not a disturbance
    diag = _diagnose(frame.copy(), tmp_path / "as_is.csv")
    assert diag.dip is not None
    assert not diag.findings, [f.to_dict() for f in diag.findings]
    assert _departed(diag) == ["4225-4500", "5575-5825"], diag.notes
    assert any("the dip departs over" in n and "majority" in n for n in diag.notes)
    assert diag.to_dict()["dip_channel"]["blocks_used"] >= 10


def test_without_an_accelerometer_only_the_strength_is_searched(frame, tmp_path):
    diag = _diagnose(frame.drop(columns=["ax", "ay", "az"]), tmp_path / "mag_only.csv")
    assert diag.dip is None and diag.to_dict()["dip_channel"] is None
    assert _departed(diag) == ["4225-4500", "5575-5825"], diag.notes


def test_a_column_without_numbers_is_said_not_tested(frame, tmp_path):
    fr = frame.copy()
    fr["temp"] = np.nan
    diag = _diagnose(fr, tmp_path / "nan_temp.csv")
    assert not [f for f in diag.findings if f.effect == "temperature_offset"]


def _tilt_gravity(fr: pd.DataFrame, lo: int, hi: int, degrees: float) -> None:
    """A turn's centripetal acceleration across gravity over rows ``lo:hi``: the accelerometer's vector turned by
    ``degrees`` about the horizontal axis ``a × m`` (7 % of g across gravity for 4°), so ``|a|`` is unchanged and
    the dip read from it is bent while the field is not."""
    from optcal.core.rotations import exponential_map

    acc = fr[["ax", "ay", "az"]].to_numpy()
    m = fr[MAG].to_numpy()
    axis = np.cross(acc[lo:hi], m[lo:hi])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    fr.loc[lo:hi - 1, ["ax", "ay", "az"]] = np.stack([exponential_map(np.radians(degrees) * e) @ x
                                                      for e, x in zip(axis, acc[lo:hi])])


@pytest.mark.parametrize("turning", [True, False])
def test_a_turn_with_a_near_g_is_not_a_bend_of_the_dip(frame, tmp_path, turning):
    # ckexplorer with a gyroscope planted (rad/s: white 0.005 rad/s at rest) and, over 15 % of the session, gravity's
    # direction tilted 4° at unchanged |a| (a turn's centripetal acceleration across gravity). Turning at 2 rad/s
    # there (rate bound about 0.3 rad/s: 0.5° of gravity's direction for a 0.3-m lever arm and a 0.02-s lag), those
    # samples are not near rest and no bend of the dip is named; the same tilt with the gyroscope at rest is named
    # (as the planted 3° bend is), so the gate and not the plant's size keeps it out
    fr = frame.copy()
    n = len(fr)
    a, b = int(0.66 * n), int(0.81 * n)
    _tilt_gravity(fr, a, b, 4.0)
    w = np.random.default_rng(11).normal(scale=0.005, size=(n, 3))
    if turning:
        w[a:b] += np.array([0.3, -0.5, 1.9])  # 2.0 rad/s
    fr[["gx", "gy", "gz"]] = w
    diag = _diagnose(fr, tmp_path / "turning.csv")
    assert diag.dip is not None
    bends = [f for f in diag.findings if "disturb" in f.effect and f.stretch["channel"] in ("dip", "both")
             and f.stretch["start_sample"] < b and f.stretch["stop_sample"] > a]
    d = diag.to_dict()["dip_channel"]
    if turning:
        assert not bends, [f.to_dict() for f in diag.findings]
        assert 0.2 < d["rate_bound_rad_s"] < 0.5 and d["turning_samples"] > 0.5 * (b - a) * d["still_samples"] / n
        assert "rate" in d["near_rest"] and "turning samples left out" in d["near_rest"]
        # the calibration's own dip (optcal calibrate --sensor mag) uses the same near rest
        from optcal.families.mag.calibration import calibrate_mag
        from optcal.families.mag.samples import read_mag

        dip = calibrate_mag(read_mag(str(tmp_path / "turning.csv"))).dip
        assert dip is not None and dip.n_still == d["still_samples"] and "turning samples" in dip.lines()[0]
    else:
        assert bends, [f.to_dict() for f in diag.findings]
        assert d["turning_samples"] == 0
