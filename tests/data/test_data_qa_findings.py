"""The data layer's QA findings (1, 4, 11, 12, 15, 16, 18, 19): each on a generated file with the
effect planted, through :func:`optcal.data.load` and the command line."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from helpers.cli_run import run
from optcal.data import load
from optcal.families.simulate.recording import synthesize_recording
from optcal.data.units import implied_sensitivity
from optcal.errors import InputError
from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import uniform_directions



@pytest.fixture(scope="module")
def recording():
    """12 poses in g at 100 Hz with a gyro in °/s."""
    model = LumpedModel.from_physical([1.01, 0.99, 1.0], 0.005, -0.004, 0.006, [0.01, -0.02, 0.015])
    return synthesize_recording(model, uniform_directions(12, rng=3), dwell_s=3.0, transition_s=1.0, sigma=0.002, rng=4)


def counts_frame(rec, gyro_noise_counts: float, rng: np.random.Generator) -> pd.DataFrame:
    """The recording in 16-bit counts (4096 counts/g); the gyro as integer counts with the given noise."""
    f = rec.frame
    out = pd.DataFrame({"t": f["t"]})
    for k in ("ax", "ay", "az"):
        out[k + "_counts"] = np.round(4096.0 * f[k].to_numpy())
    for k in ("gx", "gy", "gz"):
        out[k + "_counts"] = np.round(16.4 * f[k].to_numpy() + gyro_noise_counts * rng.standard_normal(len(f)))
    return out


# 1: gyro columns mapped as the accelerometer -------------------------------------------------------
def test_1_implied_sensitivity_of_a_sphere_of_poses_is_its_radius():
    d = uniform_directions(20, rng=1)
    assert implied_sensitivity(33000.0 + 4096.0 * d) == pytest.approx(4096.0, rel=1e-8)


def test_1_gyro_columns_as_accelerometer_are_refused(recording, tmp_path, capsys):
    f = counts_frame(recording, 20.0, np.random.default_rng(5))
    for k in ("gx", "gy", "gz"):  # an unsigned gyro at rest: mid-scale plus its bias and noise
        f[k + "_counts"] += 32768.0
    f.to_csv(tmp_path / "imu.csv", index=False)
    assert load(tmp_path / "imu.csv").n == 12  # the accelerometer's columns calibrate
    code, _, err = run(["segment", tmp_path / "imu.csv", "--columns", "ax=gx_counts,ay=gy_counts,az=gz_counts"],
                       capsys)
    assert code == 2
    # the rest model's conclusion: no still stretch is as quiet as a resting accelerometer, with the likely cause
    assert "noisier than 0.05 g per sample" in err and "gyroscope columns? map the accelerometer's with --columns" in err
    assert len(err.strip().splitlines()) == 1


# 4: a recording that never rests ------------------------------------------------------------------
def test_4_a_noisy_gyro_at_rest_is_no_motion(recording, tmp_path):
    """A gyro with 20 times a resting MEMS gyro's white noise (400 counts) beside a still accelerometer: its mean
    still sits at its bias, so the rests are found (the old detector refused them by a cap in converter steps)."""
    rng = np.random.default_rng(6)
    counts_frame(recording, 20.0, rng).to_csv(tmp_path / "rests.csv", index=False)
    assert load(tmp_path / "rests.csv").n == 12
    counts_frame(recording, 400.0, rng).to_csv(tmp_path / "noisy.csv", index=False)
    assert load(tmp_path / "noisy.csv").n == 12


def turning_in_every_rest(recording) -> pd.DataFrame:
    """The recording with every rest turning at 5 °/s about its own vertical (which the accelerometer does not see)."""
    from optcal.data.readers import source_from_frame
    from optcal.data.recording import recording_from_source
    from optcal.data.static import detect_static

    f = recording.frame.copy()
    seg = detect_static(recording_from_source(source_from_frame(f, "mem", "csv")))
    assert len(seg.intervals) == 12
    gyro = f[["gx", "gy", "gz"]].to_numpy(copy=True)
    for iv in seg.intervals:
        gyro[iv.start:iv.stop] += 5.0 * iv.mean / np.linalg.norm(iv.mean)
    f[["gx", "gy", "gz"]] = gyro
    return f


def test_4_a_recording_whose_rests_turn_about_the_vertical_never_rests(recording, tmp_path):
    f = turning_in_every_rest(recording)
    f.to_csv(tmp_path / "turns.csv", index=False)
    with pytest.raises(InputError, match="never rests by the model") as caught:
        load(tmp_path / "turns.csv")
    assert "turn by the gyro" in str(caught.value) and "--no-gyro-gate" in str(caught.value)
    assert "record the sensor at rest" in str(caught.value)
    # the override says what it assumes: without the gyro as evidence, the turns are rests
    assert load(tmp_path / "turns.csv", use_gyro=False).n == 12


def test_4_rejections_are_counted(recording):
    from optcal.data.readers import source_from_frame
    from optcal.data.recording import recording_from_source
    from optcal.data.static import MOVING, detect_static

    f = turning_in_every_rest(recording)
    seg = detect_static(recording_from_source(source_from_frame(f, "mem", "csv")))
    assert not seg.intervals and seg.evidence["blocks_turning"] > 0
    assert sum(v for k, v in seg.exclusions.items() if k.startswith("samples")) == len(f)
    assert seg.exclusions[MOVING] > 0


# 11: ignoring a recognised column -----------------------------------------------------------------
def test_11_index_none_ignores_a_restarting_samples_column(recording, tmp_path, capsys):
    """imucal's annotated session: parts each indexed from 0 in a 'samples' column, no time."""
    f = recording.frame[["ax", "ay", "az", "gx", "gy", "gz"]].copy()
    f.insert(0, "samples", np.arange(len(f)) % 1000)
    f.to_csv(tmp_path / "annotated.csv", index=False)
    with pytest.raises(InputError, match="runs backwards"):
        load(tmp_path / "annotated.csv", rate=100.0)
    poses = load(tmp_path / "annotated.csv", rate=100.0, columns="index=none")
    assert poses.n == 12 and "row number" in poses.decisions.time_base.reason
    code, out, _ = run(["segment", tmp_path / "annotated.csv", "--rate", 100, "--columns", "index=none"], capsys)
    assert code == 0 and "→ 12 static poses" in out


# 12, 15, 18, 19 -----------------------------------------------------------------------------------
def test_12_poses_on_a_recording_warns_with_the_evidence(recording, tmp_path, capsys):
    recording.frame.to_csv(tmp_path / "rec.csv", index=False)
    poses = load(tmp_path / "rec.csv", kind="poses")
    assert poses.source == "pose table" and poses.n == len(recording.frame)
    (warning,) = poses.decisions.warnings
    assert "evidence says raw recording" in warning and "regular time column" in warning
    code, out, _ = run(["segment", tmp_path / "rec.csv", "--format", "poses"], capsys)
    assert "warning: read as a pose table as given" in out
    assert not load(tmp_path / "rec.csv").decisions.warnings


def test_15_header_counts_usable_samples_and_their_duration(recording, tmp_path, capsys):
    f = recording.frame.copy()
    f.loc[len(f) - 100:, ["t", "ax", "ay", "az", "gx", "gy", "gz"]] = 0.0  # an unfilled buffer at the end
    f.to_csv(tmp_path / "zeros.csv", index=False)
    n = len(f) - 100
    code, out, _ = run(["segment", tmp_path / "zeros.csv"], capsys)
    duration = f["t"].iloc[n - 1] - f["t"].iloc[0]
    assert code == 0 and f"({n} samples of {len(f)} rows, {duration:.1f} s at" in out and "nan" not in out.split("\n")[0]


def test_16_allan_reason_is_the_command(tmp_path, capsys):
    rng = np.random.default_rng(9)
    n = 6000
    pd.DataFrame({"t": np.arange(n) / 100.0, "ax": 0.001 * rng.standard_normal(n), "ay": 0.001 * rng.standard_normal(n),
                  "az": 1.0 + 0.001 * rng.standard_normal(n)}).to_csv(tmp_path / "still.csv", index=False)
    code, out, err = run(["allan", tmp_path / "still.csv", "--json"], capsys)
    assert code == 0, err
    reason = json.loads(out)["log"]["decisions"]["kind"]["reason"]
    assert reason == "the allan command requires a raw recording" and "--format" not in reason


def test_18_rate_against_a_regular_time_column_warns(recording, tmp_path, capsys):
    recording.frame.to_csv(tmp_path / "rec.csv", index=False)
    poses = load(tmp_path / "rec.csv", rate=50.0)
    (warning,) = poses.decisions.warnings
    assert "50 Hz differs by 50 %" in warning and "100 Hz" in warning
    assert poses.decisions.rate.value == 50.0  # the user's rate wins
    assert not load(tmp_path / "rec.csv", rate=101.0).decisions.warnings  # within a few percent


def test_19_a_column_mapped_twice_is_refused_where_given(recording, tmp_path, capsys):
    recording.frame.to_csv(tmp_path / "rec.csv", index=False)
    code, _, err = run(["segment", tmp_path / "rec.csv", "--columns", "ax=2,ay=2,az=4"], capsys)
    assert code == 2 and err.strip() == "error: columns: ax and ay both map to column 2 ('ax'); give each name its own column"
    with pytest.raises(InputError, match="ax and az both map to column 'ay'"):
        load(tmp_path / "rec.csv", columns={"ax": "ay", "az": "ay"})
