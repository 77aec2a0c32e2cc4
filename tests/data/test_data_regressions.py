"""Issue 11: the eight failures of the data layer, one regression test each (each fails on the
data layer before issue 11), through the public API: :func:`optcal.data.load` and the command line."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from helpers.cli_run import run
from optcal.data import load, load_with_segmentation
from optcal.families.simulate.recording import synthesize_recording
from optcal.errors import InputError
from optcal.core.model import STANDARD_GRAVITY, LumpedModel
from optcal.families.simulate.poses import uniform_directions



@pytest.fixture(scope="module")
def rec_g():
    """10 poses in g at 100 Hz with gyro (°/s) and temperature."""
    model = LumpedModel.from_physical([1.01, 0.99, 1.0], 0.005, -0.004, 0.006, [0.01, -0.02, 0.015])
    return synthesize_recording(model, uniform_directions(10, rng=7), dwell_s=4.0, transition_s=1.5, sigma=0.002,
                                temperature=(25.0, 0.01), rng=8)


# 1 ------------------------------------------------------------------------------------------
def test_1_noisy_recording_with_a_regular_time_column_is_not_a_pose_table(tmp_path):
    """15 mg per-sample noise, no gyro: consecutive rows differ by ≈ 3.7 % of 1 g, but a regular
    100 Hz time column over 10⁴ rows says recording."""
    rng = np.random.default_rng(1)
    n = 10_000
    pose = np.repeat(uniform_directions(10, rng=2), n // 10, axis=0)
    acc = pose + 0.015 * rng.standard_normal((n, 3))
    pd.DataFrame({"t": np.arange(n) / 100.0, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(
        tmp_path / "phone.csv", index=False)
    loaded = load_with_segmentation(tmp_path / "phone.csv")
    assert loaded.poses.source == "raw recording"
    assert "regular time column" in loaded.decisions.kind.reason
    assert loaded.poses.n == 10


# 2 ------------------------------------------------------------------------------------------
def test_2_pose_table_time_stays_in_seconds(tmp_path):
    """A pose table's t is documented in seconds: poses 20-40 s apart are not milliseconds."""
    rng = np.random.default_rng(3)
    d = uniform_directions(30, rng=4)
    t = np.cumsum(rng.uniform(20, 40, 30))
    pd.DataFrame({"t": t, "ax": d[:, 0], "ay": d[:, 1], "az": d[:, 2]}).to_csv(tmp_path / "poses.csv", index=False)
    poses = load(tmp_path / "poses.csv")
    assert poses.source == "pose table"
    assert np.allclose(poses.t, t)
    assert "seconds" in poses.decisions.time_base.reason and "never rescaled" in poses.decisions.time_base.reason


# 3 ------------------------------------------------------------------------------------------
def burst_stamps(n: int, rate: float, rng: np.random.Generator) -> np.ndarray:
    """Host receive times: samples arrive in bursts of 4-8, 1-2 ms apart, one burst per 40-80 ms."""
    t, out = 0.0, []
    while len(out) < n:
        k = int(rng.integers(4, 9))
        t += k / rate  # the burst's samples were taken over k sample periods
        out.extend(t + np.cumsum(rng.uniform(0.001, 0.002, k)))
    return np.array(out[:n])


def test_3_bursty_host_stamps_are_retimed(rec_g, tmp_path):
    rng = np.random.default_rng(5)
    f = rec_g.frame.copy()
    f["t"] = burst_stamps(len(f), 100.0, rng)
    f.to_csv(tmp_path / "burst.csv", index=False, float_format="%.9g")
    loaded = load_with_segmentation(tmp_path / "burst.csv")
    rate = loaded.segmentation.recording.rate_hz
    assert rate == pytest.approx(100.0, rel=0.05)
    assert loaded.decisions.time_base.value == "uniform" and "bursts" in loaded.decisions.time_base.reason
    assert loaded.poses.n == len(rec_g.dwells)


def test_3_coarse_stamps_drop_no_sample(tmp_path):
    """200 Hz stamped with 10 ms resolution: every other stamp repeats; nothing is a duplicate."""
    model = LumpedModel.from_physical([1.0, 1.0, 1.0], 0, 0, 0, [0, 0, 0])
    syn = synthesize_recording(model, uniform_directions(8, rng=1), rate_hz=200.0, dwell_s=3.0, transition_s=1.0,
                               sigma=0.002, rng=2)
    f = syn.frame.copy()
    f["t"] = np.floor(f["t"].to_numpy() * 100.0 + 1e-9) / 100.0
    f.to_csv(tmp_path / "coarse.csv", index=False, float_format="%.9g")
    loaded = load_with_segmentation(tmp_path / "coarse.csv")
    assert loaded.segmentation.recording.rate_hz == pytest.approx(200.0, rel=0.01)
    assert not any("repeated" in k or "duplicated" in k for k in loaded.poses.exclusions)
    assert loaded.poses.n == len(syn.dwells)


# 4 ------------------------------------------------------------------------------------------
def test_4_headerless_files_are_read_by_position(rec_g, tmp_path):
    f = rec_g.frame
    acc = f[["t", "ax", "ay", "az"]].to_numpy()
    gyro = f[["t", "gx", "gy", "gz"]].to_numpy()
    np.savetxt(tmp_path / "acc.txt", acc, fmt="%.9g")  # imu_tk: 't ax ay az', whitespace, no header
    np.savetxt(tmp_path / "gyro.txt", gyro, fmt="%.9g")
    poses = load(tmp_path / "acc.txt", gyro_file=tmp_path / "gyro.txt")
    assert poses.n == len(rec_g.dwells) and poses.gyro is not None
    assert "no header" in poses.decisions.columns.reason
    # mikoff's layout: 'ax ay az wx wy wz', no header, no time: the rate settles the time
    np.savetxt(tmp_path / "imu.log", f[["ax", "ay", "az", "gx", "gy", "gz"]].to_numpy(), fmt="%.6f")
    assert load(tmp_path / "imu.log", rate=100.0).n == len(rec_g.dwells)
    # columns by 1-based position
    np.savetxt(tmp_path / "odd.txt", f[["ax", "t", "az", "ay"]].to_numpy(), fmt="%.9g", delimiter=",")
    assert load(tmp_path / "odd.txt", columns="t=2,ax=1,ay=4,az=3").n == len(rec_g.dwells)


def test_4_headerless_without_a_common_layout_shows_the_fix(tmp_path, capsys):
    np.savetxt(tmp_path / "five.txt", np.random.default_rng(0).normal(size=(50, 5)), fmt="%.5f")
    code, out, err = run(["segment", tmp_path / "five.txt"], capsys)
    assert code == 2 and "no header row" in err and "--columns t=1,ax=2,ay=3,az=4" in err


# 5 ------------------------------------------------------------------------------------------
def test_5_units_that_contradict_the_norm_are_refused(rec_g, tmp_path, capsys):
    f = rec_g.frame.copy()
    f[["ax", "ay", "az"]] *= STANDARD_GRAVITY
    f.to_csv(tmp_path / "ms2.csv", index=False)
    code, out, err = run(["calibrate", tmp_path / "ms2.csv", "--units", "g"], capsys)
    assert code == 2 and "contradict the data: the median |a| is 9.7" in err and "pass --units m/s^2" in err
    code, out, err = run(["calibrate", tmp_path / "ms2.csv", "--units", "counts"], capsys)
    assert code == 2 and "units counts (given with --units) contradict the data" in err


# 6 ------------------------------------------------------------------------------------------
def test_6_one_absurd_cell_is_excluded_and_counted(rec_g, tmp_path):
    f = rec_g.frame.copy()
    f.loc[1000, "ay"] = 1e308
    f.loc[2000, "az"] = np.inf
    f.to_csv(tmp_path / "absurd.csv", index=False, float_format="%.9g")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow warnings either
        poses = load(tmp_path / "absurd.csv")
    assert poses.n == len(rec_g.dwells)
    counted = {k: v for k, v in poses.exclusions.items() if "full scale" in k or "non-finite" in k}
    assert sum(counted.values()) == 2


# 7 ------------------------------------------------------------------------------------------
def test_7_outputs_into_missing_folders(rec_g, tmp_path, capsys):
    f = rec_g.frame
    f.to_csv(tmp_path / "r.csv", index=False)
    code, out, err = run(["calibrate", tmp_path / "r.csv", "-o", tmp_path / "new" / "deeper" / "cal.json"], capsys)
    assert code == 0 and (tmp_path / "new" / "deeper" / "cal.json").exists()
    code, out, err = run(["segment", tmp_path / "r.csv", "--plot", tmp_path / "figs"], capsys)
    assert code == 0 and (tmp_path / "figs" / "segments.png").stat().st_size > 1000
    code, out, err = run(["segment", tmp_path / "r.csv", "--plot", tmp_path / "more" / "seg.png"], capsys)
    assert code == 0 and (tmp_path / "more" / "seg.png").exists()
    (tmp_path / "afile").write_text("x")
    code, out, err = run(["calibrate", tmp_path / "r.csv", "-o", tmp_path / "afile" / "cal.json"], capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err


# 8 ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("style", ["pipe", "semicolon-decimal-comma", "tab-decimal-comma"])
def test_8_other_delimiters_and_decimal_commas(rec_g, tmp_path, style):
    f = rec_g.frame[["t", "ax", "ay", "az"]]
    sep, dec = {"pipe": ("|", "."), "semicolon-decimal-comma": (";", ","), "tab-decimal-comma": ("\t", ",")}[style]
    f.to_csv(tmp_path / "x.csv", index=False, sep=sep, decimal=dec, float_format="%.9g")
    poses = load(tmp_path / "x.csv")
    assert poses.source == "raw recording" and poses.n == len(rec_g.dwells)
    assert poses.units == "g"


@pytest.mark.parametrize("name", ["t_idx_s", "t_header_s", "timestamp", "time_us"])
def test_8_common_time_column_names(rec_g, tmp_path, name):
    f = rec_g.frame[["t", "ax", "ay", "az"]].copy()
    if name == "time_us":
        f["t"] = np.round(f["t"] * 1e6)
    f.rename(columns={"t": name}).to_csv(tmp_path / "x.csv", index=False, float_format="%.9g")
    poses = load(tmp_path / "x.csv")
    assert poses.meta["rate_hz"] == pytest.approx(100.0, rel=1e-3)


def test_8_hint_names_the_time_column_option(tmp_path, capsys):
    rng = np.random.default_rng(0)
    acc = np.array([0, 0, 1.0]) + 0.001 * rng.standard_normal((500, 3))
    pd.DataFrame({"zeit": np.arange(500) / 100, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(
        tmp_path / "z.csv", index=False)
    code, out, err = run(["segment", tmp_path / "z.csv"], capsys)
    assert code == 2 and "--columns t=NAME" in err


def still_log(n: int = 20_000, rate: float = 100.0) -> pd.DataFrame:
    rng = np.random.default_rng(11)
    acc = np.array([0.01, -0.02, 1.0]) + 0.001 * rng.standard_normal((n, 3))
    return pd.DataFrame({"t": np.arange(n) / rate, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]})


def test_8_allan_tolerates_one_dropped_sample(tmp_path, capsys):
    f = still_log().drop(index=7000)
    f.to_csv(tmp_path / "still.csv", index=False, float_format="%.9g")
    code, out, err = run(["allan", tmp_path / "still.csv", "--json"], capsys)
    assert code == 0, err
    log = json.loads(out)["log"]
    assert log["exclusions"]["samples missing from the log (gaps of a few samples, treated as uniformly sampled)"] == 1


def test_8_allan_refuses_a_moving_log(rec_g, tmp_path, capsys):
    rec_g.frame.to_csv(tmp_path / "moving.csv", index=False)
    code, out, err = run(["allan", tmp_path / "moving.csv"], capsys)
    assert code == 2 and "the log is not still" in err


def test_8_allan_refuses_a_long_gap(tmp_path, capsys):
    f = still_log().drop(index=range(7000, 7100))
    f.to_csv(tmp_path / "gap.csv", index=False, float_format="%.9g")
    code, out, err = run(["allan", tmp_path / "gap.csv"], capsys)
    assert code == 2 and "gap of" in err


def test_decisions_are_printed_and_in_the_json(rec_g, tmp_path, capsys):
    rec_g.frame.to_csv(tmp_path / "r.csv", index=False)
    code, out, err = run(["segment", tmp_path / "r.csv"], capsys)
    assert code == 0
    for word in ("kind: raw recording", "columns:", "units: g", "time: stamps"):
        assert word in out
    code, out, err = run(["segment", tmp_path / "r.csv", "--json"], capsys)
    d = json.loads(out)["data"]["decisions"]
    assert set(d) >= {"kind", "columns", "units", "time_base", "rate_hz", "exclusions"}
    assert d["kind"]["override"] == "--format" and d["units"]["override"] == "--units"
    # an override is taken and said so
    with pytest.raises(InputError, match="cannot be read as a pose table|pose table"):
        load(tmp_path / "r.csv", kind="poses", rate=100.0)


def test_8_allan_refuses_a_moving_log_before_what_its_analysis_refuses(rec_g, tmp_path, capsys):
    """The stillness check runs beside the analysis: a moving log whose analysis also fails (counts without their
    scale) is refused for its motion, as when the check ran first, and nothing is printed before the refusal."""
    frame = rec_g.frame.copy()
    frame[["ax", "ay", "az"]] = np.round(frame[["ax", "ay", "az"]] * 16384.0)
    frame.to_csv(tmp_path / "moving_counts.csv", index=False)
    code, out, err = run(["allan", tmp_path / "moving_counts.csv", "--units", "counts"], capsys)
    assert code == 2 and "the log is not still" in err and out == ""
