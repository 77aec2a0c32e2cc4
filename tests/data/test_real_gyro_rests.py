"""Real IMUs at rest (issue 36): a gyro's bias as a real gyro's, decisions by relevance, the gyro's unit from the moves.

Effects planted in IMU-TK's Xsens log (../shared/data/imutk-xsens; skipped without it): g-sensitivity, a bias step
after a knock, a slow turn inside a rest; the gyro rewritten in rad/s, deg/s and counts, with and without units in
its column names.  The bias model (:func:`optcal.data.bias_model.fit_bias_model`) and the scale measured on the
moves (:func:`optcal.data.static_stretches.scale_from_moves`) on their own.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from optcal.data.readers import source_from_frame
from optcal.data.recording import recording_from_source
from optcal.data.bias_model import fit_bias_model
from optcal.data.static import StaticSettings, detect_static
from optcal.data.static_stretches import scale_from_moves

from helpers.common import SHARED

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
ACC = ["acc_x_counts", "acc_y_counts", "acc_z_counts"]
GYRO = ["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]
# IMUTK_REFERENCE.md: imu_tk's own calibration of this log
GYRO_SCALE = np.array([0.000209295, 0.000209899, 0.000209483])  # rad/s per count
GYRO_ZERO = np.array([32777.1, 32459.8, 32511.8])
ACC_SCALE = np.array([0.00241278463, 0.00242712280, 0.00241168028])  # m/s² per count
ACC_ZERO = np.array([33124.1826, 33275.1794, 32364.4156])
G = 9.81744


@pytest.fixture(scope="module")
def xsens() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not XSENS.exists():
        pytest.skip(f"{XSENS} is not present")
    f = pd.read_csv(XSENS)
    return f["t_s"].to_numpy(), f[ACC].to_numpy(float), (f[GYRO].to_numpy(float) - GYRO_ZERO) * GYRO_SCALE


def _frame(t, acc, gyro_rad, unit: str | None, plain: bool) -> pd.DataFrame:
    """The log written with its gyro in ``unit`` (None: no gyro), its columns named plainly or with their units."""
    out = {"t" if plain else "t_s": t}
    for j, a in enumerate("xyz"):
        out[f"a{a}" if plain else f"acc_{a}_counts"] = acc[:, j]
    if unit is not None:
        values = {"counts": gyro_rad / GYRO_SCALE + GYRO_ZERO, "deg/s": np.degrees(gyro_rad), "rad/s": gyro_rad}[unit]
        suffix = {"counts": "counts", "deg/s": "deg_s", "rad/s": "rad_s"}[unit]
        for j, a in enumerate("xyz"):
            out[f"g{a}" if plain else f"gyro_{a}_{suffix}"] = values[:, j]
    return pd.DataFrame(out)


def _segment(t, acc, gyro_rad, unit, plain=False, settings=None):
    return detect_static(recording_from_source(source_from_frame(_frame(t, acc, gyro_rad, unit, plain), "xsens", "csv")),
                         settings or StaticSettings())


def _g_sensitive_and_knocked(t, acc, gyro_rad) -> np.ndarray:
    """The gyro with 0.1 °/s/g g-sensitivity (a full matrix, as measured parts have) and a 0.3 °/s bias step half-way."""
    f = (acc - ACC_ZERO) * ACC_SCALE / G
    gs = np.radians(0.1) * np.array([[1.0, 0.5, -0.3], [-0.4, -1.0, 0.6], [0.7, 0.2, 1.0]])
    out = gyro_rad + f @ gs.T
    out[t.size // 2:] += np.radians(0.3) * np.array([0.6, -0.64, 0.48])
    return out


@pytest.mark.parametrize("unit", ["counts", "deg/s", "rad/s"])
@pytest.mark.parametrize("plain", [False, True])
def test_g_sensitivity_and_a_bias_step_keep_the_38_poses(xsens, unit, plain) -> None:
    t, acc, gyro = xsens
    assert len(_segment(t, acc, gyro, unit, plain).intervals) == 38
    assert len(_segment(t, acc, _g_sensitive_and_knocked(t, acc, gyro), unit, plain).intervals) == 38


def _slow_turn(t, acc, gyro_rad, rest, dps=0.5, deg=3.0):
    """A turn at ``dps`` through ``deg`` planted from the middle of ``rest``, about an axis across gravity: the
    accelerometer turns with it, and the gyro reads it."""
    a, z = rest.start, rest.stop
    mid = (a + z) // 2
    angle = np.radians(dps) * np.clip(t[mid:z] - t[mid], 0.0, deg / dps)
    f = (acc[mid:z] - ACC_ZERO) * ACC_SCALE
    m = f.mean(axis=0) / np.linalg.norm(f.mean(axis=0))
    axis = np.cross(m, [1.0, 0.0, 0.0])
    axis /= np.linalg.norm(axis)
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    turned = f * c + np.cross(axis, f) * s + np.outer(f @ axis, axis) * (1.0 - c)
    acc2, gyro2 = acc.copy(), gyro_rad.copy()
    acc2[mid:z] = turned / ACC_SCALE + ACC_ZERO
    gyro2[mid:z][angle < np.radians(deg)] += np.radians(dps) * axis
    return acc2, gyro2, mid


@pytest.mark.parametrize("unit", ["counts", None])
@pytest.mark.parametrize("which", [0, 10, 30])
def test_a_slow_turn_inside_a_rest_is_cut_out(xsens, unit, which) -> None:
    """0.5 °/s through 3° from the middle of a rest: no pose spans the turn, with the gyro and without it."""
    t, acc, gyro = xsens
    before = _segment(t, acc, gyro, "counts")
    rest = sorted(before.intervals, key=lambda iv: -iv.n_samples)[which]
    acc2, gyro2, mid = _slow_turn(t, acc, gyro, rest)
    turn_end = mid + int(np.searchsorted(t[mid:] - t[mid], 6.0))
    after = _segment(t, acc2, gyro2, unit)
    over = [iv for iv in after.intervals if iv.start < rest.stop and iv.stop > rest.start]
    assert over, "the rest before the turn is kept"
    for iv in over:  # what is kept lies before the turn, or after it has ended
        assert iv.stop <= mid + int(0.5 * 100) or iv.start >= turn_end - int(0.5 * 100), (iv.start, iv.stop, mid, turn_end)


@pytest.mark.parametrize("unit,plain,expected", [
    ("counts", False, "counts"), ("counts", True, "counts"), ("deg/s", True, "deg/s"), ("rad/s", True, "rad/s"),
])
def test_the_gyro_unit_is_measured_on_the_moves_and_printed(xsens, unit, plain, expected) -> None:
    """Names that do not say the unit: the moves say it (imu_tk's scale to 2 %), the decision names its evidence and
    the flag; a unit the names state is taken as stated."""
    t, acc, gyro = xsens
    seg = _segment(t, acc, gyro, unit, plain)
    decision = seg.gyro_unit
    assert decision.startswith(expected) and "--gyro-units" in decision
    if plain or unit == "counts":
        assert "the rate integral across" in decision
    scale = seg.evidence["gyro_rad_per_unit"]
    truth = {"counts": GYRO_SCALE.mean(), "deg/s": np.radians(1.0), "rad/s": 1.0}[unit]
    tolerance = 0.02 if unit == "counts" else 1e-12  # a named unit is the unit's exact scale
    assert scale == pytest.approx(truth, rel=tolerance)


def test_the_segment_report_prints_the_gyro_decision(xsens, tmp_path, capsys) -> None:
    from helpers.cli_run import run

    t, acc, gyro = xsens
    _frame(t, acc, gyro, "rad/s", True).to_csv(tmp_path / "plain.csv", index=False)
    code, out, err = run(["segment", tmp_path / "plain.csv"], capsys)
    assert code == 0, err
    assert "gyro: rad/s from the rate integral across" in out
    code, out, err = run(["segment", tmp_path / "plain.csv", "--gyro-units", "deg/s"], capsys)
    assert code == 0, err
    assert "gyro: deg/s as stated; the moves say" in out


# ----------------------------------------------------------------------------- the pieces on their own
def test_the_bias_model_recovers_g_sensitivity_and_a_step_and_ignores_a_turning_rest() -> None:
    rng = np.random.default_rng(1)
    k = 40
    d = rng.standard_normal((k, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = np.sort(rng.uniform(0.0, 600.0, k))
    gs = np.radians(0.1) * rng.uniform(-1.0, 1.0, (3, 3))
    rates = np.radians([0.3, -0.2, 0.1]) + d @ gs.T + np.radians(0.01) * rng.standard_normal((k, 3))
    step = np.radians(0.3) * np.array([0.6, -0.64, 0.48])
    rates[t > 300.0] += step
    rates[5] += np.radians(0.5)  # a rest that turned about gravity
    model = fit_bias_model(t, d, rates, np.full((k, 3), np.radians(0.01) ** 2), g_limit=np.radians(0.5))
    assert np.abs(np.degrees(model.g_sensitivity - gs)).max() < 0.01
    assert model.step_times.size == 1 and 280.0 < model.step_times[0] < 320.0
    assert np.degrees(np.abs(model.step_levels[1] - model.step_levels[0] - step)).max() < 0.01
    # a turn about gravity in every rest reads as G = ψ̇ I: beyond any gyro's g-sensitivity, not fitted as one
    yaw = fit_bias_model(t, d, np.radians(1.0) * d, np.full((k, 3), np.radians(0.01) ** 2), g_limit=np.radians(0.5))
    assert np.all(yaw.g_sensitivity == 0.0)
    # a unit unknown: no G
    assert np.all(fit_bias_model(t, d, rates, np.full((k, 3), 1e-10)).g_sensitivity == 0.0)


def test_the_bias_comes_back_after_a_slow_turn_is_no_step() -> None:
    """Rests whose rate is off for 8 s and then back (pieces of a slow turn) leave no step."""
    t = np.arange(40) * 2.0
    rates = np.zeros((40, 3)) + 1e-4 * np.random.default_rng(2).standard_normal((40, 3))
    rates[10:14] += np.radians(1.0) * np.array([0.0, 0.0, 1.0])
    model = fit_bias_model(t, np.tile([0.0, 0.0, 1.0], (40, 1)), rates, np.full((40, 3), 1e-8))
    assert model.step_times.size == 0


def _turntable(scale_true: float, angles_deg: list[float], rng) -> tuple:
    """Moves about a body axis across gravity by the given angles at 90 °/s, 100 Hz, rates in units of ``scale_true``."""
    t_all, w_all, spans, before, after = [], [], [], [], []
    u = np.array([0.0, 0.0, 1.0])
    n = 0
    for ang in angles_deg:
        m = int(round(abs(ang) / 90.0 * 100)) + 1
        rate = np.zeros((m, 3))
        rate[:, 0] = np.radians(90.0) * np.sign(ang)
        w_all.append(rate / scale_true + 1e-3 * rng.standard_normal((m, 3)))
        t_all.append((n + np.arange(m)) / 100.0)
        spans.append((n, n + m))
        a = np.radians(ang) * (m - 1) / m * (m / (m - 1)) if m > 1 else 0.0
        c, s = np.cos(np.radians(ang)), np.sin(np.radians(ang))
        rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])  # body turned about x: gravity turns the other way
        before.append(u)
        u = rot.T @ u
        after.append(u)
        n += m
    return np.concatenate(t_all), np.concatenate(w_all), spans, np.array(before), np.array(after)


def test_the_scale_from_moves_takes_the_turn_without_extra_revolutions() -> None:
    """A table's turns by 90° fit as well with a whole revolution more (scale × 5): the smallest scale is taken."""
    rng = np.random.default_rng(3)
    truth = np.radians(1.0) / 131.0  # a 16-bit gyro at ±250 °/s
    t, w, spans, before, after = _turntable(truth, [90.0, 90.0, -90.0, 90.0, 180.0, -90.0], rng)
    ev = scale_from_moves(t, w, np.zeros(3), spans, before, after)
    assert ev is not None and ev.rad_per_unit == pytest.approx(truth, rel=0.03) and ev.moves == 6
    # no motion samples between two holds (a logger that stores only holds): no scale
    jumps = [(a, a + 2) for a, _ in spans]
    assert scale_from_moves(t, np.zeros_like(w), np.zeros(3), jumps, before, after) is None
