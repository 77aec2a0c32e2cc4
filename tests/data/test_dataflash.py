"""ArduPilot DataFlash logs read natively (they were refused, naming pymavlink's CSV export): a generated log with
two IMU instances, a VIBE clip count that rises, rows ArduPilot marked unhealthy and a compass, read through
pymavlink's DFReader.  The erlerobot/logs flights read the same samples, rate, |a| and poses as their mavlogdump
CSV export (docs/rest-model.md)."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.dataflash import DataFlashWriter
from optcal.data import load, load_recording
from optcal.data.recording import SATURATED
from optcal.errors import InputError
from optcal.families.mag.samples import read_mag


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    """IMU:0 and IMU:1 at 100 Hz: 3 rests of 3 s (z up, x up, y up) joined by 1-s turns; VIBE at 10 Hz whose clip
    count rises once (between 1.0 and 1.1 s), AH=0 on 5 rows of IMU:0; MAG at 10 Hz in milligauss."""
    w = DataFlashWriter()
    rng = np.random.default_rng(1)
    g = 9.80665
    poses = [(0, 0, g), (g, 0, 0), (0, g, 0)]
    t_us, acc = [], []
    for k, p in enumerate(poses):
        for i in range(300):
            t_us.append(1_000_000 + (k * 400 + i) * 10_000)
            acc.append(np.array(p) + rng.normal(0, 0.02, 3))
        if k < len(poses) - 1:
            for i in range(100):
                s = (i + 1) / 101
                t_us.append(1_000_000 + (k * 400 + 300 + i) * 10_000)
                acc.append((1 - s) * np.array(p) + s * np.array(poses[k + 1]) + rng.normal(0, 0.02, 3))
    sick = set(range(50, 55))
    for j, (t, a) in enumerate(zip(t_us, acc)):
        for inst in (0, 1):
            ah = 0 if inst == 0 and j in sick else 1
            w.add("IMU", t, inst, *rng.normal(0, 0.002, 3), *(a + inst * 0.1), 0, 0, 35.0, 1, ah, 100, 100)
        if j % 10 == 0:
            clip = 0 if t < 1_100_000 else 1
            w.add("VIBE", t, 0, 0.1, 0.1, 0.1, clip)
            field = np.array([200.0, 0.0, 400.0]) + 50 * rng.normal(size=3)
            w.add("MAG", t, 0, *np.round(field).astype(int), 0, 0, 0, 0, 0, 0, 1, t)
    path = tmp_path_factory.mktemp("df") / "00000001.BIN"
    w.write(path)
    return path, np.array(acc), len(sick)


def test_the_first_imu_is_read_with_its_flags(log):
    path, acc, n_sick = log
    rec = load_recording(path)
    assert rec.acc.shape[0] == len(acc) - n_sick
    assert rec.exclusions["DataFlash IMU rows with AH=0 (ArduPilot judged the accelerometer unhealthy)"] == n_sick
    assert rec.exclusions[SATURATED] == 10  # the IMU samples in (1.0 s, 1.1 s], where VIBE.Clip rose
    assert rec.rate_hz == pytest.approx(100, rel=1e-3) and rec.gyro_units == "rad/s" and rec.temp is not None
    poses = load(path)
    assert poses.n == 3
    assert np.allclose(poses.acc, [(0, 0, 9.80665), (9.80665, 0, 0), (0, 9.80665, 0)], atol=0.03)
    assert any("DataFlash IMU:0 read" in n and "IMU:1" in n for n in poses.meta["notes"])


def test_another_instance_by_topic_and_a_missing_one_refused(log):
    path, acc, _ = log
    other = load_recording(path, topic="IMU:1")
    assert other.acc.shape[0] == len(acc) and np.allclose(other.acc, acc + 0.1, atol=1e-5)
    with pytest.raises(InputError, match=r"no DataFlash IMU instance 2 \(logged: IMU:0 .*IMU:1"):
        load(path, topic="IMU:2")


def test_the_compass_is_read_in_milligauss(log):
    path, _, _ = log
    mag = read_mag(path)
    assert mag.units.units == "mgauss" and mag.n == -(-len(log[1]) // 10)
    assert np.median(mag.m[:, 2]) == pytest.approx(400, abs=15)
    assert mag.acc is not None and mag.acc.shape == mag.m.shape


def test_the_raw_acc_messages_are_read_by_topic_with_their_gyro(tmp_path):
    """ACC/GYR (the sensor's own samples, here at 400 Hz beside IMU at 50 Hz): --topic ACC reads them, stamped by
    SampleUS, the GYR samples interpolated onto their times; by default IMU is read and the note names ACC."""
    w = DataFlashWriter()
    rng = np.random.default_rng(2)
    t_sample = 2_000_000 + np.arange(2000) * 2_500  # 400 Hz, logged 300 µs after the sample
    acc = np.array([0.0, 0.0, 9.80665]) + rng.normal(0, 0.02, (2000, 3))
    rate = 0.01 * np.sin(np.arange(2000) / 50.0)
    for k, ts in enumerate(t_sample):
        w.add("ACC", ts + 300, 0, ts, *acc[k])
        w.add("GYR", ts + 300, 0, ts + 1_250, rate[k], 0.0, 0.0)  # the gyro sampled between two accelerometer samples
        if k % 8 == 0:
            w.add("IMU", ts, 0, rate[k], 0.0, 0.0, *acc[k], 0, 0, 40.0, 1, 1, 50, 50)
    path = tmp_path / "raw.bin"
    w.write(path)
    raw = load_recording(path, topic="ACC")
    assert raw.acc.shape[0] == 2000 and raw.rate_hz == pytest.approx(400, rel=1e-3)
    assert raw.t[0] == pytest.approx(2.0) and np.allclose(raw.acc, acc, atol=1e-5)
    mid = (rate[:-1] + rate[1:]) / 2  # the gyro at the accelerometer's time, halfway between two of its samples
    assert np.allclose(raw.gyro[1:, 0], mid, atol=2e-6)
    default = load_recording(path)
    assert default.acc.shape[0] == 250
    assert any("ACC:0 (400 Hz)" in n for n in default.meta["notes"])


def test_unhealthy_gyro_rows_keep_their_accelerometer_sample_and_every_flag_decision_has_an_override(tmp_path):
    """GH=0 rows (ArduPilot judged the gyro unhealthy) keep their accelerometer sample (AH=1 says it is sound) and their
    gyro sample is left out of the gyro's use: a failing gyro's 3 rad/s on those rows reaches neither the rests nor
    their gyro means.  AH=0 rows are left out whole; both are counted (a row both mark once, under AH);
    --keep-unhealthy keeps both and --keep-clipped keeps the samples VIBE's clip rise flags, each said in the read
    line."""
    from optcal.data.static import MOVING, detect_static

    w = DataFlashWriter()
    rng = np.random.default_rng(3)
    # rows 100-102 the gyro alone (a 4-period hole in its record, inside the first rest); 400, 401 both flags
    n, gyro_sick, acc_sick = 600, {100, 101, 102, 400, 401}, set(range(400, 405))
    acc_of = {}
    for j in range(n):
        t = 1_000_000 + j * 10_000
        gh, ah = int(j not in gyro_sick), int(j not in acc_sick)
        gyro = np.full(3, 3.0) if not gh else rng.normal(0, 0.002, 3)  # what a failing gyro may log
        acc_of[j] = np.array([0, 0, 9.80665]) + rng.normal(0, 0.02, 3)
        w.add("IMU", t, 0, *gyro, *acc_of[j], 0, 0, 35.0, gh, ah, 100, 100)
        if j % 10 == 0:
            w.add("VIBE", t, 0, 0.1, 0.1, 0.1, 0 if t < 3_000_000 else 1)
    path = tmp_path / "sick.bin"
    w.write(path)
    rec = load_recording(path)
    gyro_key = "DataFlash IMU rows with GH=0 (ArduPilot judged the gyro unhealthy)"
    acc_key = "DataFlash IMU rows with AH=0 (ArduPilot judged the accelerometer unhealthy)"
    assert rec.exclusions[acc_key] == 5 and rec.exclusions[gyro_key] == 3
    assert rec.acc.shape[0] == n - 5 and rec.exclusions[SATURATED] == 10  # the AH=0 rows alone are gone
    gyro_only = [int(np.flatnonzero(np.isclose(rec.t, 1.0 + 0.01 * j))[0]) for j in (100, 101, 102)]
    assert np.allclose(rec.acc[gyro_only], [acc_of[j] for j in (100, 101, 102)])  # their accelerometer samples
    assert rec.usable[gyro_only].all() and not rec.gyro_usable[gyro_only].any()
    assert rec.gyro_unhealthy is not None and int(rec.gyro_unhealthy.sum()) == 3
    # the log is still: no block moves (the failing gyro's 3 rad/s would move the blocks holding it), and the rest
    # around those rows is found as around any short hole, its gyro mean at the bias
    seg = detect_static(rec)
    assert MOVING not in seg.exclusions
    around = [iv for iv in seg.intervals if iv.start < gyro_only[0] and iv.stop > gyro_only[-1]]
    assert len(around) == 1 and float(np.max(np.abs(around[0].gyro_mean))) < 0.01
    assert any("IMU rows with GH=0" in note and "--keep-unhealthy" in note and "accelerometer sample is used" in note
               for note in rec.meta["notes"])
    kept = load_recording(path, keep_unhealthy=True, keep_clipped=True)
    assert kept.acc.shape[0] == n and acc_key not in kept.exclusions and gyro_key not in kept.exclusions
    assert kept.gyro_unhealthy is None and SATURATED not in kept.exclusions
    assert any("kept (--keep-unhealthy)" in note for note in kept.meta["notes"])
    assert any("kept (--keep-clipped" in note for note in kept.meta["notes"])


def test_apply_corrects_a_dataflash_log(log, tmp_path, capsys):
    """``optcal apply`` on a DataFlash log: its frame is built from the samples under their roles (``ax``), not the
    log's field names (``IMU.AccX``), which it once looked for and ended in a traceback."""
    import pandas as pd

    import optcal
    from optcal.families.simulate.poses import simulate_poses, uniform_directions
    from tests.helpers.cli_run import run

    path, acc, sick = log
    cal = optcal.calibrate(simulate_poses(optcal.lu2017_reference_model(), uniform_directions(30, 4), 0.001, rng=5))
    cal.save(tmp_path / "c.json")
    code, out, err = run(["apply", tmp_path / "c.json", path, "-o", tmp_path / "a.csv"], capsys)
    assert code == 0, err
    frame = pd.read_csv(tmp_path / "a.csv")
    assert len(frame) == len(acc) - sick  # the AH=0 rows were left out by the reader: said so, not "marked"
    counted = next(line for line in out.splitlines() if line.startswith("counted while reading"))
    assert f"AH=0 (ArduPilot judged the accelerometer unhealthy): {sick}" in counted and "not in the output" in counted
    marked = next(line for line in out.splitlines() if line.startswith("excluded (marked, not dropped)"))
    assert "AH=0" not in marked and frame["optcal_status"].tolist().count("excluded") == 10  # the clipped samples
    ok = (frame["optcal_status"] == "ok").to_numpy()
    expected = cal.correct(np.delete(acc, range(50, 50 + sick), axis=0) / 9.80665)  # m/s² in, g calibration and out
    assert np.allclose(frame[["ax_g", "ay_g", "az_g"]].to_numpy()[ok], expected[ok], atol=1e-6)  # the log stores float32
