"""Every numeric flag and every number read from a calibration file validated: finite, in its range (issue 40)."""

from __future__ import annotations

import json

import pytest

from optcal.core.model import lu2017_reference_model
from optcal.families.simulate.poses import uniform_directions
from optcal.families.simulate.recording import synthesize_recording
from tests.helpers.cli_run import run


@pytest.fixture(scope="module")
def raw_without_time(tmp_path_factory):
    """A 12-pose raw recording in g without a time column (its rate given by --rate): about 42 s at 100 Hz."""
    frame = synthesize_recording(lu2017_reference_model(), uniform_directions(12, rng=3), dwell_s=2.0, transition_s=1.5,
                                 sigma=0.002, rng=4).frame
    path = tmp_path_factory.mktemp("raw") / "raw.csv"
    frame[["ax", "ay", "az"]].to_csv(path, index=False)
    return path


def _one_error(code: int, err: str) -> str:
    lines = [line for line in err.strip().splitlines() if line]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("rate", ["1e308", "inf", "nan"])
def test_rate_out_of_range_is_one_line(rate, raw_without_time, capsys):
    code, _, err = run(["segment", raw_without_time, "--rate", rate], capsys)
    if rate == "nan":  # click refuses nan itself
        assert code == 2 and "Traceback" not in err
        return
    assert "--rate" in _one_error(code, err)


def test_min_dwell_longer_than_the_recording_is_refused_with_its_length(raw_without_time, capsys):
    code, out, err = run(["segment", raw_without_time, "--rate", "100", "--min-dwell", "1e6"], capsys)
    line = _one_error(code, err)
    assert "--min-dwell" in line and "longer than the recording" in line


def test_export_counts_per_g_inf_refused(cal_json, tmp_path, capsys):
    code, _, err = run(["export", cal_json, "--format", "px4", "--counts-per-g", "inf", "--max-loss", "1000",
                        "-o", tmp_path / "p.params"], capsys)
    assert "counts_per_g" in _one_error(code, err) or "--counts-per-g" in err
    assert not (tmp_path / "p.params").exists()


@pytest.mark.parametrize("command", ["apply", "check"])
@pytest.mark.parametrize("broken", ["huge T", "Infinity"])
def test_a_calibration_with_an_absurd_number_is_refused(command, broken, cal_json, pose_csv, tmp_path, capsys):
    d = json.loads(cal_json.read_text())
    if broken == "huge T":
        d["T"] = [[1e308, 0.0, 0.0], [0.0, 1e308, 0.0], [0.0, 0.0, 1e308]]
        text = json.dumps(d)
    else:
        text = json.dumps(d).replace(str(d["o"][0]), "Infinity", 1)
    bad = tmp_path / "bad.json"
    bad.write_text(text)
    argv = ["apply", bad, pose_csv, "-o", tmp_path / "a.csv"] if command == "apply" else ["check", bad, pose_csv]
    code, _, err = run(argv, capsys)
    line = _one_error(code, err)
    assert ("row norms" in line) if broken == "huge T" else ("finite" in line)
    assert not (tmp_path / "a.csv").exists()


def test_ros_export_takes_the_accelerometer_of_a_both_sensors_allan_result(cal_json, tmp_path, capsys):
    axis = {"velocity_random_walk": 1e-4, "bias_instability": 1e-5}
    part = {"log": {"rate_hz": 100.0}, **{a: dict(axis) for a in "xyz"}}
    allan = tmp_path / "allan.json"
    # as `optcal allan --sensor both --json` writes it: each part says its sensor
    allan.write_text(json.dumps({"sensor": "both", "accelerometer": {**part, "sensor": "accelerometer"},
                                 "gyroscope": {**part, "sensor": "gyro"}}))
    code, out, err = run(["export", cal_json, "--format", "ros", "--allan", allan], capsys)
    assert code == 0, err
    assert "Allan" in out
