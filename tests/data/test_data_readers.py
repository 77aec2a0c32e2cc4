"""Readers: CSV (header names, --columns, metadata header), Parquet, ROS 1/2 bags, PX4 ULog;
pose table vs raw recording; units; bad input (one error line, exit code 2, or a counted exclusion)."""

from __future__ import annotations

import builtins
import json
import sys

import numpy as np
import pandas as pd
import pytest

from helpers.cli_run import run
from optcal.data import decide_kind, load, load_pose_table, load_recording, load_with_segmentation
from optcal.data.readers import read_source
from optcal.data.recording import DUPLICATED, GYRO_SATURATED, NON_FINITE, REPEATED_TIME, SATURATED
from optcal.families.simulate.recording import synthesize_recording
from optcal.data.units import decide_units, nominal_conversion
from optcal.data.writers import write_recording
from optcal.errors import InputError
from optcal.core.model import STANDARD_GRAVITY, LumpedModel, lu2017_reference_model
from optcal.families.simulate.poses import simulate_poses, uniform_directions


def ms2_model() -> LumpedModel:
    return LumpedModel.from_physical([9.70, 9.90, 9.80], 0.01, -0.01, 0.02, [0.10, -0.20, 0.30])


@pytest.fixture(scope="module")
def recording():
    """12 poses, m/s² and rad/s (the ROS / PX4 conventions), temperature, t0 = 1000 s."""
    return synthesize_recording(
        ms2_model(), uniform_directions(12, rng=3), dwell_s=3.0, transition_s=1.5, sigma=0.02,
        gyro_units="rad/s", temperature=(30.0, 0.02), rng=4, units="m/s^2", t0=1000.0,
    )



# ----------------------------------------------------------------------------- formats
SUFFIX = {"csv": "rec.csv", "parquet": "rec.parquet", "ros1": "rec.bag", "ros2": "rec_ros2", "ulog": "rec.ulg"}


@pytest.mark.parametrize("fmt", ["csv", "parquet", "ros1", "ros2", "ulog"])
def test_every_format_round_trips_to_the_same_poses(recording, tmp_path, fmt):
    path = write_recording(recording.frame, tmp_path / SUFFIX[fmt], fmt)
    poses = load(path)
    assert poses.source == "raw recording"
    assert poses.n == len(recording.dwells)
    assert poses.units == "m/s^2"
    assert poses.temp is not None and poses.gyro is not None
    truth = recording.true_pose_means()
    # float32 in ULog: 1e-6 relative; otherwise noise of the mean (σ/√n ≈ 0.02/√270)
    assert np.max(np.abs(poses.acc - truth)) < 6 * 0.02 / np.sqrt(250)
    assert np.allclose(poses.temp, [recording.frame["temp"].iloc[a:b].mean() for a, b in recording.dwells], atol=0.05)
    assert poses.t[0] > 1000.0  # time is the file's, not re-based


def test_ros_bag_topic_selection_and_errors(recording, tmp_path):
    path = write_recording(recording.frame, tmp_path / "two.bag", "ros1", topic="/imu0")
    assert load(path, topic="/imu0").n == len(recording.dwells)
    with pytest.raises(InputError, match=r"no sensor_msgs/Imu topic '/imu9' \(Imu topics: /imu0\)"):
        load(path, topic="/imu9")


def test_ulog_instance_and_clip_counter(recording, tmp_path):
    from optcal.data.writers import write_ulog

    clipped = np.zeros(len(recording.frame), dtype=bool)
    clipped[[5, 6, 7]] = True
    write_ulog(recording.frame, tmp_path / "c.ulg", clipped=clipped)
    rec = load_recording(tmp_path / "c.ulg")
    assert rec.exclusions[SATURATED] == 3
    assert GYRO_SATURATED not in rec.exclusions and rec.gyro_rail is None
    gyro_clipped = np.zeros(len(recording.frame), dtype=bool)
    gyro_clipped[[40, 41]] = True  # the gyro's own clip counters: its samples flagged, not the accelerometer's
    write_ulog(recording.frame, tmp_path / "g.ulg", gyro_clipped=gyro_clipped)
    rec = load_recording(tmp_path / "g.ulg")
    assert SATURATED not in rec.exclusions and rec.exclusions[GYRO_SATURATED] == 2
    assert rec.gyro_rail is not None and list(np.flatnonzero(rec.gyro_rail.samples)) == [40, 41]
    with pytest.raises(InputError, match="no ULog topic sensor_accel instance 1"):
        load(tmp_path / "c.ulg", topic="sensor_accel:1")


def test_missing_extra_says_how_to_install(recording, tmp_path, monkeypatch):
    path = write_recording(recording.frame, tmp_path / "r.bag", "ros1")
    ulg = write_recording(recording.frame, tmp_path / "r.ulg", "ulog")
    real_import = builtins.__import__

    def no_extras(name, *args, **kwargs):
        if name.startswith(("rosbags", "pyulog")):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_extras)
    for mod in [m for m in sys.modules if m.startswith(("rosbags", "pyulog"))]:
        monkeypatch.delitem(sys.modules, mod)
    with pytest.raises(InputError, match=r"pip install 'optcal\[ros\]'"):
        load(path)
    with pytest.raises(InputError, match=r"pip install 'optcal\[px4\]'"):
        load(ulg)


# ----------------------------------------------------------------------------- CSV columns
def test_column_names_with_unit_words_are_recognised(tmp_path):
    f = pd.DataFrame({"t_ms": np.arange(5) * 10.0, "acc_x_counts": [1, 2, 3, 4, 5], "acc_y_counts": [0] * 5,
                      "acc_z_counts": [16000] * 5, "gyro_x_dps": [0.0] * 5, "gyro_y_dps": [0.0] * 5,
                      "gyro_z_dps": [0.0] * 5, "label": list("abcde")})
    f.to_csv(tmp_path / "a.csv", index=False)
    src = read_source(tmp_path / "a.csv")
    assert src.column_map == {"t": "t_ms", "ax": "acc_x_counts", "ay": "acc_y_counts", "az": "acc_z_counts",
                              "gx": "gyro_x_dps", "gy": "gyro_y_dps", "gz": "gyro_z_dps"}
    assert src.units_hint == "counts" and src.gyro_units == "deg/s"
    assert np.allclose(src.column("t"), np.arange(5) * 0.01)  # ms → s
    assert src.ignored_columns == ["label"]


def test_columns_option_maps_other_names(recording, tmp_path):
    f = recording.frame.rename(columns={"t": "zeit", "ax": "A1", "ay": "A2", "az": "A3", "gx": "W1", "gy": "W2", "gz": "W3"})
    f.to_csv(tmp_path / "odd.csv", index=False)
    with pytest.raises(InputError, match=r"no accelerometer column\(s\) for ax, ay, az .*--columns"):
        load(tmp_path / "odd.csv")
    poses = load(tmp_path / "odd.csv", columns="t=zeit,ax=A1,ay=A2,az=A3,gx=W1,gy=W2,gz=W3")
    assert poses.n == len(recording.dwells) and poses.gyro is not None
    with pytest.raises(InputError, match=r"there is no column 'A9'"):
        load(tmp_path / "odd.csv", columns="ax=A9,ay=A2,az=A3")
    with pytest.raises(InputError, match=r"unknown name 'acc'"):
        load(tmp_path / "odd.csv", columns="acc=A1")


def test_metadata_header_gives_the_rate(tmp_path):
    """The MPU-6050 logs: 'Fs,100' and other key,value lines above the header, no time column."""
    syn = synthesize_recording(LumpedModel.from_physical([16384] * 3, 0, 0, 0, [500, -300, 100]),
                               uniform_directions(10, rng=1), sigma=60, quantum=1, units="counts", rng=2, gyro=False)
    body = syn.frame[["ax", "ay", "az"]].astype(int).to_csv(index=False)
    (tmp_path / "mpu.csv").write_text("Fs,100\nLogging Type,0\nInitialization time,36.5\nWaiting time,3\n" + body)
    loaded = load_with_segmentation(tmp_path / "mpu.csv")
    assert loaded.kind.value == "raw recording" and "Fs,100" in loaded.kind.reason
    assert "100 Hz" in loaded.poses.meta["time"]
    assert loaded.poses.n == 10
    assert loaded.poses.units == "counts"
    # --rate overrides the header
    half = load(tmp_path / "mpu.csv", rate=50.0)
    assert half.meta["duration_s"] == pytest.approx(2 * loaded.poses.meta["duration_s"])


def test_index_column_and_rate(recording, tmp_path):
    f = recording.frame.drop(columns="t")
    f.insert(0, "n_samples", np.arange(len(f)))
    f.to_csv(tmp_path / "idx.csv", index=False)
    with pytest.raises(InputError, match=r"no time column and no sampling rate; pass --rate HZ"):
        load(tmp_path / "idx.csv")
    poses = load(tmp_path / "idx.csv", rate=100.0)
    assert poses.source == "raw recording" and poses.n == len(recording.dwells)
    assert "column 'n_samples' / 100 Hz (--rate)" in poses.meta["time"]


# ----------------------------------------------------------------------------- kind and units
def test_pose_table_and_recording_are_told_apart(recording, tmp_path):
    table = simulate_poses(lu2017_reference_model(), uniform_directions(40, rng=5), 1e-3, rng=6)
    pd.DataFrame(table.acc, columns=["ax", "ay", "az"]).to_csv(tmp_path / "poses.csv", index=False)
    recording.frame.to_csv(tmp_path / "raw.csv", index=False)
    p = load_with_segmentation(tmp_path / "poses.csv")
    r = load_with_segmentation(tmp_path / "raw.csv")
    assert p.poses.source == "pose table" and p.segmentation is None
    assert "as different poses do" in p.kind.reason
    assert r.poses.source == "raw recording" and "regular time column" in r.kind.reason
    forced = load(tmp_path / "raw.csv", kind="poses")
    assert forced.source == "pose table" and forced.n == len(recording.frame)
    assert load(tmp_path / "poses.csv", kind="poses").n == 40
    with pytest.raises(InputError, match="a ulog holds a raw recording"):
        decide_kind(read_source(write_recording(recording.frame, tmp_path / "x.ulg", "ulog")), "poses")


def test_static_single_pose_log_is_a_recording(tmp_path):
    rng = np.random.default_rng(0)
    acc = np.array([0.01, -0.02, 1.0]) + 1e-3 * rng.standard_normal((3000, 3))
    pd.DataFrame({"t": np.arange(3000) / 100, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(tmp_path / "s.csv", index=False)
    poses = load(tmp_path / "s.csv")
    assert poses.source == "raw recording" and poses.n == 1 and poses.n_samples[0] > 2900


def test_load_pose_table_keeps_working(tmp_path):
    table = simulate_poses(lu2017_reference_model(), uniform_directions(20, rng=1), 1e-3, rng=2)
    f = pd.DataFrame(table.acc, columns=["ax", "ay", "az"])
    f["sigma"] = 1e-3
    f["roll_deg"] = np.arange(20.0)
    f.to_csv(tmp_path / "p.csv", index=False)
    p = load_pose_table(tmp_path / "p.csv")
    assert p.source == "pose table" and p.units == "g" and np.allclose(p.sigma, 1e-3)
    assert np.allclose(p.acc, table.acc) and "roll_deg" in p.extra
    assert list(p.rows[:3]) == [1, 2, 3]


@pytest.mark.parametrize(("scale", "units"), [(1.0, "g"), (STANDARD_GRAVITY, "m/s^2"), (16384.0, "counts")])
def test_units_from_the_norm(scale, units):
    d = uniform_directions(30, rng=0)
    assert decide_units(d * scale).units == units


def test_ambiguous_units_need_the_option():
    d = uniform_directions(30, rng=0) * 30.0
    with pytest.raises(InputError, match="pass --units g, m/s\\^2 or counts"):
        decide_units(d)
    assert decide_units(d, requested="counts").reason == "given with --units"


def test_nominal_conversion_baselines():
    d = uniform_directions(30, rng=0)
    assert np.allclose(nominal_conversion("m/s^2", d * STANDARD_GRAVITY).apply(d * STANDARD_GRAVITY), d)
    unsigned = nominal_conversion("counts", 32768 + 4000 * d)
    assert np.allclose(unsigned.offset, 32768) and unsigned.sensitivity == pytest.approx(4000)
    signed = nominal_conversion("counts", 16384 * d)
    assert np.allclose(signed.offset, 0) and signed.sensitivity == pytest.approx(16384)


# ----------------------------------------------------------------------------- bad input
def test_truncated_csv_counts_the_incomplete_row(recording, tmp_path):
    text = recording.frame.to_csv(index=False, float_format="%.9g")
    cut = text[: len(text) - 40]  # ends in the middle of the last row
    (tmp_path / "cut.csv").write_text(cut)
    poses = load(tmp_path / "cut.csv")
    assert poses.exclusions[NON_FINITE] == 1
    assert poses.n == len(recording.dwells)


@pytest.mark.parametrize("fmt", ["parquet", "ros1", "ulog"])
def test_truncated_binary_files_give_one_error_line(recording, tmp_path, capsys, fmt):
    path = write_recording(recording.frame, tmp_path / SUFFIX[fmt], fmt)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3] if fmt != "ulog" else data[:10])
    code, out, err = run(["segment", str(path)], capsys)
    assert code == 2 and out == ""
    assert err.startswith("error: ") and "truncated or corrupt" in err and "Traceback" not in err
    assert err.count("\n") == 1


def test_backwards_time_is_an_error(recording, tmp_path, capsys):
    f = recording.frame.copy()
    t = f["t"].to_numpy().copy()
    t[500:] -= 3.0
    f["t"] = t
    f.to_csv(tmp_path / "back.csv", index=False)
    code, out, err = run(["segment", str(tmp_path / "back.csv")], capsys)
    assert code == 2
    assert "time runs backwards at data row 501" in err and "split or sort it" in err


def test_duplicated_samples_and_timestamps_are_counted(recording, tmp_path):
    f = recording.frame.copy()
    dup = f.iloc[[100, 200, 300]]
    changed = f.iloc[[400]].copy()
    changed["ax"] += 1.0
    f = pd.concat([f, dup, changed]).sort_values("t", kind="stable").reset_index(drop=True)
    f.to_csv(tmp_path / "dup.csv", index=False)
    poses = load(tmp_path / "dup.csv")
    assert poses.exclusions[DUPLICATED] == 3
    assert poses.exclusions[REPEATED_TIME] == 1
    assert poses.n == len(recording.dwells)


def test_saturated_samples_are_excluded_and_counted(tmp_path):
    model = LumpedModel.from_physical([16384] * 3, 0, 0, 0, [300, -200, 100])
    syn = synthesize_recording(model, uniform_directions(12, rng=1), sigma=40, quantum=1, units="counts",
                               shocks=6, shock_g=3.0, full_scale=(-32768, 32767), rng=5)
    assert syn.saturated.sum() > 0
    syn.frame.to_csv(tmp_path / "sat.csv", index=False)
    poses = load(tmp_path / "sat.csv")
    assert poses.exclusions[SATURATED] == syn.saturated.sum()
    assert poses.n == len(syn.dwells)


def test_saturation_rail_in_float_data(tmp_path):
    syn = synthesize_recording(ms2_model(), uniform_directions(12, rng=1), sigma=0.02, units="m/s^2",
                               shocks=6, shock_g=3.0, full_scale=2 * 9.8, rng=5)
    syn.frame.to_csv(tmp_path / "sat.csv", index=False, float_format="%.9g")
    rec = load_recording(tmp_path / "sat.csv")
    assert rec.exclusions[SATURATED] == syn.saturated.sum() > 0


def test_whole_numbers_probe_decides_as_the_whole_column():
    """The integer-rail check's whole-number test looks at a strided sample first: a column whose sample is all
    whole numbers but one value between them is not is not whole (counts at a rail are told from a float log
    only by the whole column), and one whose sample is not decides at once."""
    from optcal.data.rails import WHOLE_NUMBER_PROBE, _whole_numbers

    counts = np.round(np.random.default_rng(2).normal(0.0, 300.0, 50 * WHOLE_NUMBER_PROBE + 7))
    assert _whole_numbers(counts)
    between = counts.copy()
    between[1] += 0.5  # not on the probe's stride
    assert not _whole_numbers(between) and not np.all(between == np.round(between))
    assert not _whole_numbers(counts + 0.25) and _whole_numbers(np.zeros(3))


def test_no_static_interval_is_one_error(tmp_path, capsys):
    t = np.arange(0, 30, 0.01)
    a = np.column_stack([np.cos(0.8 * t), np.sin(0.8 * t) * np.cos(0.3 * t), np.sin(0.8 * t) * np.sin(0.3 * t)])
    pd.DataFrame({"t": t, "ax": a[:, 0], "ay": a[:, 1], "az": a[:, 2]}).to_csv(tmp_path / "spin.csv", index=False)
    # a noise-free continuous rotation: no window is quiet
    code, out, err = run(["segment", str(tmp_path / "spin.csv"), "--format", "raw"], capsys)
    assert code == 2 and "no static interval found" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", "the file is empty"),
        ("1,2,3,4,5\n4,5,6,7,8\n", "has no header row (comma-separated, no header, 5 columns), and 5 unnamed columns fit no common layout; name them by 1-based position, e.g. --columns t=1,ax=2,ay=3,az=4"),
        ("x,y,z\n1,2,3\n4,5,6\n", "no accelerometer column(s) for ax, ay, az"),
        ("ax,ay,az\n", "no data rows"),
        ("ax,ay,az\n1,2\n", "line 1 looks like the header (3 columns: ax, ay, az) but line 2 has 2 fields"),
    ],
)
def test_bad_csv_files(tmp_path, capsys, content, message):
    (tmp_path / "bad.csv").write_text(content)
    code, out, err = run(["segment", str(tmp_path / "bad.csv")], capsys)
    assert code == 2 and message in err and "Traceback" not in err


def test_missing_file_and_non_bag_directory(tmp_path, capsys):
    code, _, err = run(["segment", str(tmp_path / "nope.csv")], capsys)
    assert code == 2 and "no such file" in err
    code, _, err = run(["segment", str(tmp_path)], capsys)
    assert code == 2 and "not a ROS 2 bag" in err


def test_non_numeric_cell_in_a_pose_table_is_named(tmp_path, capsys):
    (tmp_path / "p.csv").write_text("ax,ay,az,sigma\n" + "\n".join(f"{i},1,0,0.001" for i in range(9)) + "\noops,1,0,0.001\n")
    code, _, err = run(["segment", str(tmp_path / "p.csv")], capsys)
    assert code == 2 and "non-numeric value 'oops' on data row 10" in err


def test_segment_json_is_one_object(recording, tmp_path, capsys):
    recording.frame.to_csv(tmp_path / "r.csv", index=False)
    code, out, err = run(["segment", str(tmp_path / "r.csv"), "--json", "--plot", str(tmp_path / "seg.png")], capsys)
    assert code == 0
    d = json.loads(out)
    assert d["data"]["kind"] == "raw recording"
    assert len(d["segmentation"]["intervals"]) == len(recording.dwells)
    assert (tmp_path / "seg.png").stat().st_size > 1000


def test_ulog_cut_mid_file_is_read_and_counted(recording, tmp_path):
    from optcal.data.readers import TRUNCATED_MESSAGE

    path = write_recording(recording.frame, tmp_path / "r.ulg", "ulog")
    data = path.read_bytes()
    (tmp_path / "cut.ulg").write_bytes(data[: len(data) * 2 // 3 + 7])  # ends inside a message
    loaded = load_with_segmentation(tmp_path / "cut.ulg")
    assert loaded.poses.exclusions[TRUNCATED_MESSAGE] == 1
    assert any("truncated" in n for n in loaded.poses.meta["notes"])
    assert 0 < loaded.segmentation.recording.n < len(recording.frame)
    assert TRUNCATED_MESSAGE not in load(path).exclusions
