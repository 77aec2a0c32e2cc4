"""The typed reading API: ReadOptions validated, optcal.load the one path, the CLI's flags mapped in one place."""

from __future__ import annotations

import math

import numpy as np
import pytest

import optcal
from optcal.cli.data_options import build_read_options
from optcal.data import load, load_with_segmentation
from optcal.data.options import MAX_RATE_HZ, READ_FIELDS, STATIC_FIELDS, Reading, ReadOptions
from optcal.data.static import StaticSettings
from optcal.errors import InputError
from optcal.families.simulate.poses import simulate_poses, uniform_directions


@pytest.fixture
def pose_csv(tmp_path):
    poses = simulate_poses(optcal.lu2017_reference_model(), uniform_directions(20, 1), 0.002, rng=3)
    path = tmp_path / "poses.csv"
    np.savetxt(path, poses.acc, delimiter=",", header="ax,ay,az", comments="")
    return path


def test_unknown_override_names_the_valid_ones(pose_csv):
    with pytest.raises(InputError) as err:
        optcal.load(pose_csv, rte=100)
    message = str(err.value)
    assert "rte" in message and "rate" in message and "min_dwell_s" in message


@pytest.mark.parametrize("rate", [math.inf, -1.0, 0.0, 1e308, math.nan, "fast"])
def test_rate_out_of_range_refused(rate):
    with pytest.raises(InputError, match="rate"):
        ReadOptions(rate=rate)


def test_rate_bound_is_far_above_any_mems_rate():
    assert ReadOptions(rate=MAX_RATE_HZ).rate == MAX_RATE_HZ
    assert ReadOptions(rate="100").rate == 100.0  # a number given as text, as a flag would


@pytest.mark.parametrize("field, value", [("kind", "table"), ("timing", "never"), ("time_unit", "min"),
                                          ("gyro_units", "rpm")])
def test_choices_refused_with_their_flag(field, value):
    with pytest.raises(InputError, match=value):
        ReadOptions(**{field: value})


def test_static_settings_by_name_and_non_finite_refused():
    options = ReadOptions.build(None, min_dwell_s=2.0, use_gyro=False)
    assert options.static == StaticSettings(min_dwell_s=2.0, use_gyro=False)
    with pytest.raises(InputError, match="min_dwell_s"):
        ReadOptions.build(None, min_dwell_s=math.inf)
    with pytest.raises(InputError, match="not both"):
        ReadOptions.build(None, static=StaticSettings(), window_s=1.0)
    assert ReadOptions.build(options, rate=None) is options  # None leaves a field as it is


def test_options_are_frozen():
    with pytest.raises(AttributeError):
        ReadOptions().rate = 5.0  # type: ignore[misc]


def test_load_returns_a_reading_whose_poses_are_the_data_layer_s(pose_csv):
    reading = optcal.load(pose_csv)
    assert isinstance(reading, Reading)
    assert reading.kind.value == "pose table" and reading.kind.reason
    assert reading.poses == load(pose_csv)
    assert reading.poses.n == 20 and reading.recording is None and reading.segmentation is None
    assert reading.lines() == reading.decisions.lines()
    assert load_with_segmentation(pose_csv).poses == reading.poses
    assert optcal.load(pose_csv, units="g").options.units == "g"


def test_cli_flags_mapped_to_fields():
    options = build_read_options({"data_format": "raw", "static_window": 0.5, "min_dwell": 1.0, "trim": 0.1,
                                  "no_gyro_gate": True, "rate": 200.0, "static_threshold": None})
    assert options.kind == "raw" and options.rate == 200.0
    assert options.static == StaticSettings(window_s=0.5, min_dwell_s=1.0, trim_s=0.1, use_gyro=False)
    assert options.describe() == {"kind": "raw", "rate": 200.0, "window_s": 0.5, "min_dwell_s": 1.0, "trim_s": 0.1,
                                  "use_gyro": False}


def test_every_field_is_a_flag_or_a_static_setting():
    assert set(READ_FIELDS) == {"columns", "units", "topic", "rate", "kind", "time_unit", "timing", "gyro_file",
                                "gyro_units", "keep_gyro_rail", "keep_unhealthy", "keep_clipped", "keep_held", "gyro_range_dps",
                                "static"}
    assert "min_dwell_s" in STATIC_FIELDS


def test_recording_read_through_one_path_equals_the_command_line_s(shared_data):
    files = [shared_data / "imutk-xsens" / "xsens_imutk.csv"]
    reading = optcal.load(files[0])
    assert reading.kind.value == "raw recording" and reading.segmentation is not None
    assert reading.poses.n == len(reading.segmentation.intervals)
    assert reading.poses == load(files[0])


def test_gyro_units_given_reach_the_recording(shared_data, tmp_path):
    """The Xsens log with plain names, its gyro converted to rad/s (imu_tk's own scale): gyro_units='rad/s' is the
    recording's unit (the rest model reads its wander in rad/s), the same 38 poses; a unit given overrides the
    file's own (here wrongly, and the rest model's refusal shows it was read)."""
    import pandas as pd

    x = pd.read_csv(shared_data / "imutk-xsens" / "xsens_imutk.csv")
    gyro = x[["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]].to_numpy(float)
    rad_s = (gyro - [32777.1, 32459.8, 32511.8]) * [0.000209295, 0.000209899, 0.000209483]  # IMUTK_REFERENCE.md
    frame = pd.DataFrame({"t": x["t_s"], "ax": x["acc_x_counts"], "ay": x["acc_y_counts"], "az": x["acc_z_counts"],
                          "gx": rad_s[:, 0], "gy": rad_s[:, 1], "gz": rad_s[:, 2]})
    frame.to_csv(tmp_path / "plain.csv", index=False)
    reading = optcal.load(tmp_path / "plain.csv", gyro_units="rad/s")
    assert reading.recording is not None and reading.recording.gyro_units == "rad/s"
    assert reading.poses.n == 38
    # the file's counts given as deg/s reach the rest model, which says that the moves measure another scale
    # (0.000209 rad/s per count, imu_tk's); the accelerometer's rests are kept
    wrong = optcal.load(shared_data / "imutk-xsens" / "xsens_imutk.csv", gyro_units="deg/s")
    assert wrong.recording is not None and wrong.recording.gyro_units == "deg/s"
    assert wrong.segmentation is not None
    decision = wrong.segmentation.gyro_unit
    assert decision.startswith("deg/s as stated; the moves say") and "check the columns' unit" in decision
    measured = float(decision.split("the moves say ")[1].split()[0])
    assert measured == pytest.approx(0.000209, rel=0.1)
