"""The data layer at scale (issue 11): the O(n) static detector against a straightforward reference,
large text files parsed once into a column-major block (the same poses as the small-file path), and
two refusals: a recording that never rests, and gyroscope columns mapped as the accelerometer with
fewer than nine poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from numpy.lib.stride_tricks import sliding_window_view

import optcal.data.text as text
from optcal.data import load, load_with_segmentation
from optcal.data.readers import read_source
from optcal.data.recording import recording_from_source
from optcal.data.static import MOVING, SWEEPING_STRETCHES, Segmentation, detect_static
from optcal.families.simulate.recording import synthesize_recording
from optcal.errors import InputError
from optcal.core.model import LumpedModel, lu2017_reference_model
from optcal.families.simulate.poses import tilted_sweeps, uniform_directions

from helpers.common import SHARED

DATA = SHARED / "data"


def need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


# ----------------------------------------------------------------------------- reference detector
def reference_window_std(x: np.ndarray, window: int) -> np.ndarray:
    """Population std over the centred window ``[i − h, i − h + window)`` clipped to the data, by brute force."""
    m, h = x.size, window // 2
    out = np.empty(m)
    if m >= window:
        out[h:h + m - window + 1] = sliding_window_view(x, window).std(axis=1)
    for i in [*range(min(h, m)), *range(max(h, h + m - window + 1), m)]:
        out[i] = x[max(0, i - h):min(m, i - h + window)].std()
    return out


def reference_drift(acc: np.ndarray, window: int) -> np.ndarray:
    """‖mean of the next h samples − mean of the previous h samples‖, h = window // 2, zero at the ends."""
    m, h = acc.shape[0], window // 2
    out = np.zeros(m)
    for i in range(h, m - h + 1):
        out[i] = np.linalg.norm(acc[i:i + h].mean(axis=0) - acc[i - h:i].mean(axis=0))
    return out


def reference_static_mask(seg: Segmentation) -> np.ndarray:
    """The static mask recomputed from the brute-force statistics and the segmentation's thresholds."""
    rec, thr, window = seg.recording, seg.thresholds, int(seg.trace["window_samples"])
    acc = rec.acc[rec.usable]
    norm = np.linalg.norm(acc - nominal_offset(seg), axis=1)
    axes = np.sqrt(sum(reference_window_std(acc[:, j], window) ** 2 for j in range(3)))
    mask = (reference_window_std(norm, window) <= thr["acc_norm_std"]) & (axes <= thr["acc_axes_std"])
    return mask & (reference_drift(acc, window) <= thr["acc_drift"])


def nominal_offset(seg: Segmentation) -> np.ndarray:
    from optcal.data.units import nominal_conversion

    rec = seg.recording
    return nominal_conversion(rec.units, rec.acc[rec.usable]).offset


def check_against_reference(seg: Segmentation, statistics_samples: int | None = None) -> None:
    """The detector's block statistics and poses against brute force.

    Every block's mean and variance (the rest model's evidence, :mod:`optcal.data.rest_model`) as numpy
    computes them sample by sample, to rounding, however large the data's offset; every pose the plain
    mean and standard deviation of its samples.
    """
    from optcal.data import rest_model as rm

    rec, block = seg.recording, int(seg.trace["window_samples"])
    acc = rec.acc[rec.usable]
    b = rm.make_blocks(rec.t[rec.usable], acc, None, block, np.zeros(0, dtype=np.int64), 0.0, 0.0)
    n = b.count if statistics_samples is None else min(b.count, max(1, statistics_samples // block))
    scale = float(np.max(np.abs(acc - np.median(acc, axis=0))))
    for k in range(n):
        x = acc[b.start[k]:b.stop[k]]
        np.testing.assert_allclose(b.mean[k], x.mean(axis=0), rtol=1e-12, atol=1e-12 * scale)
        np.testing.assert_allclose(b.var[k], x.var(axis=0, ddof=1), rtol=1e-7, atol=1e-12 * scale**2)
    for iv in seg.intervals:  # every pose is the plain mean of its samples, to 1e-12
        rows = rec.acc[iv.start:iv.stop][rec.usable[iv.start:iv.stop]]
        if rows.shape[0] == iv.n_samples:  # one stretch (joined stretches leave samples out between them)
            np.testing.assert_allclose(iv.mean, rows.mean(axis=0), rtol=1e-12, atol=0)
            np.testing.assert_allclose(iv.std, rows.std(axis=0, ddof=1), rtol=1e-9, atol=0)


def test_detector_matches_reference_on_a_synthetic_recording():
    syn = synthesize_recording(lu2017_reference_model(), tilted_sweeps(3), sigma=0.003, slow_creeps=2, rng=3)
    frame = syn.frame
    seg = detect_static(recording_from_source(source_of(frame)))
    assert len(seg.intervals) >= len(syn.dwells)
    check_against_reference(seg)


def test_detector_matches_reference_on_raw_counts_with_an_offset():
    model = LumpedModel.from_physical([16300, 16400, 16700], 0.01, -0.005, 0.008, [700, -360, -1800])
    syn = synthesize_recording(model, uniform_directions(15, rng=1), sigma=60.0, quantum=1.0, units="counts", rng=2)
    seg = detect_static(recording_from_source(source_of(syn.frame)))
    assert len(seg.intervals) == 15
    check_against_reference(seg)


@pytest.mark.parametrize("name", ["mikoff-mpu9150/imu0.log", "mpu6050-imucalibration/example_data_calibration.csv"])
def test_detector_matches_reference_on_real_recordings(name):
    loaded = load_with_segmentation(need(DATA / name), rate=100.0 if name.endswith(".log") else None)
    assert loaded.poses.n >= 10
    check_against_reference(loaded.segmentation)


def source_of(frame: pd.DataFrame):
    from optcal.data.readers import source_from_frame

    return source_from_frame(frame, "synthetic", "csv")


# ----------------------------------------------------------------------------- large files
def test_large_file_block_gives_the_poses_of_the_small_file_path(tmp_path, monkeypatch):
    """A file above the small-file size is parsed into one column-major block (pyarrow, or pandas for
    whitespace): the recording's accelerometer and gyro are views of it, and the poses are those of numpy's
    small-file path (comma-separated: bit for bit; whitespace via pandas: to 1e-12)."""
    model = LumpedModel.from_physical([16300, 16400, 16700], 0.01, -0.005, 0.008, [700, -360, -1800])
    syn = synthesize_recording(model, uniform_directions(12, rng=4), sigma=60.0, quantum=1.0, units="counts", rng=5,
                               temperature=(25.0, 0.001))
    comma = tmp_path / "rec.csv"
    syn.to_csv(str(comma), float_format="%.6f")
    blank = tmp_path / "rec.txt"
    syn.frame.to_csv(blank, sep=" ", index=False, float_format="%.6f")
    small = {p: load_with_segmentation(p) for p in (comma, blank)}
    monkeypatch.setattr(text, "SMALL_FILE_BYTES", 1024)  # every file is "large"
    monkeypatch.setattr(text, "ARROW_STREAM_BLOCK_BYTES", 64 * 1024)  # several streamed batches
    for path, exact in ((comma, True), (blank, False)):
        src = read_source(path)
        rec = recording_from_source(src)
        assert rec.acc.base is not None and np.shares_memory(rec.acc, src.column("ax"))  # a view, no copy
        large = load_with_segmentation(path)
        a, b = small[path].poses, large.poses
        assert a.n == b.n == 12
        if exact:
            assert np.array_equal(a.acc, b.acc) and np.array_equal(a.sigma, b.sigma)
        else:
            np.testing.assert_allclose(b.acc, a.acc, rtol=1e-12)
        assert a.exclusions == b.exclusions


def test_large_file_with_text_cells_falls_back_to_pandas_and_counts_them(tmp_path, monkeypatch):
    rows = ["t,ax,ay,az"] + [f"{k / 100:.2f},0.001,0.002,1.0" for k in range(3000)]
    rows[1500] = "14.99,oops,0.002,1.0"
    path = tmp_path / "cells.csv"
    path.write_text("\n".join(rows) + "\n")
    monkeypatch.setattr(text, "SMALL_FILE_BYTES", 1024)
    parsed = text.parse_numbers(path, text.sniff_layout(path))
    assert parsed.engine == "pandas" and parsed.non_numeric == {1: (1, 1500, "oops")}
    assert np.isnan(parsed.columns[1][1499]) and parsed.columns[0].size == 3000


def test_column_block_grows_past_its_estimate():
    block = text.ColumnBlock(2, 3)
    for k in range(4):
        block.append([np.full(2, k, float), np.full(2, -k, float)])
    a, b = block.columns()
    assert np.array_equal(a, [0, 0, 1, 1, 2, 2, 3, 3]) and np.array_equal(b, -a) and a.flags.c_contiguous


# ----------------------------------------------------------------------------- a recording that never rests
def slow_sphere(gyro: bool) -> pd.DataFrame:
    """A slow full-sphere rotation with noise: 20 directions passed through without stopping."""
    model = LumpedModel.from_physical([1.0, 1.0, 1.0], 0.0, 0.0, 0.0, [0.0, 0.0, 0.0])
    syn = synthesize_recording(model, uniform_directions(20, rng=3), dwell_s=0.0, transition_s=(8.0, 15.0),
                               sigma=0.004, gyro=gyro, yaw_rate_dps=0.0, rng=4)
    return syn.frame


def true_turn_deg(frame: pd.DataFrame, iv) -> float:
    """The path the simulated sensor turns through over a pose, from its gyro columns (°/s; their noise adds ≈ 0.2°)."""
    rates = np.radians(frame[["gx", "gy", "gz"]].to_numpy()[iv.start:iv.stop])
    return float(np.degrees(np.sum(np.linalg.norm(rates, axis=1)) * np.median(np.diff(frame["t"]))))


@pytest.mark.parametrize("gyro", [False, True], ids=["no gyro", "float gyro"])
def test_never_resting_sphere_gives_too_few_rests_to_calibrate_and_each_is_a_near_stop(gyro):
    """A slow full-sphere rotation that eases in and out of 20 directions without stopping.  The rest model
    takes a moment where the sensor turns through less than a pose tolerates for a rest (measured: 4 poses
    without the gyro, 12 with it, at the turning points); each such pose is a mean on the sphere within its
    own noise, and without the gyro they are too few to calibrate from, so the recording is refused."""
    frame = slow_sphere(gyro)
    seg = detect_static(recording_from_source(source_of(frame)))
    assert sum(v for k, v in seg.exclusions.items() if k.startswith("samples")) + seg.n_used == len(frame)
    for iv in seg.intervals:
        assert abs(np.linalg.norm(iv.mean) - 1.0) < 3 * iv.sigma + 1e-4
    if gyro:  # by the true rates, each pose is a moment of the sphere's slowest turning: no faster than a MEMS
        # gyro's bias may move (1 °/s, which the gyro cannot tell from a turn), through at most a pose's tolerance more
        truth = slow_sphere(True)
        for iv in seg.intervals:
            assert true_turn_deg(truth, iv) <= 1.0 * (iv.t_end - iv.t_start) + 0.81 + 0.2
    else:
        assert len(seg.intervals) < 9


def test_the_same_sphere_with_rests_gives_its_poses():
    """20 rests of 4 s between slow turns: each rest is one pose; what else is taken is a near-stop of a turn,
    within its own noise of the sphere (measured: 2 such, with 5 times a rest's noise of the mean)."""
    model = LumpedModel.from_physical([1.0, 1.0, 1.0], 0.0, 0.0, 0.0, [0.0, 0.0, 0.0])
    syn = synthesize_recording(model, uniform_directions(20, rng=3), dwell_s=4.0, transition_s=(8.0, 15.0),
                               sigma=0.004, gyro=False, yaw_rate_dps=0.0, rng=4)
    seg = detect_static(recording_from_source(source_of(syn.frame)))
    inside = [[iv for iv in seg.intervals if iv.start < b and iv.stop > a] for a, b in syn.dwells]
    assert all(len(found) == 1 for found in inside) and SWEEPING_STRETCHES not in seg.exclusions
    assert seg.exclusions[MOVING] > 0 and len(seg.intervals) <= 20 + 3
    for iv in seg.intervals:
        assert abs(np.linalg.norm(iv.mean) - 1.0) < 3 * iv.sigma + 1e-4


@pytest.mark.parametrize("folder", ["set-2/full-sphere", "set-1/tilt-sphere", "set-2/roll-and-tilt-at-45-90"])
def test_sunsided_motion_without_its_gyro_gives_no_pose(folder, request):
    """The motion logs with their gyro columns left unused (they gave 15, 9 and 3 poses before)."""
    if folder != "set-1/tilt-sphere":  # a known gap of the rest model: strict, so that a fix is noticed
        request.applymarker(pytest.mark.xfail(strict=True, reason=(
            "without a gyro, a hand's slow turn that the accelerometer barely sees passes the creep tests for "
            "0.5-1 s: measured 1 pose (full-sphere) and 4 (roll-and-tilt)")))
    path = need(DATA / "sunsided-mpu6050" / folder / "mpu6050.csv")
    with pytest.raises(InputError, match="never rests"):
        load(path, columns="gx=none,gy=none,gz=none")


def test_sunsided_rest_without_its_gyro_is_still_one_pose():
    path = need(DATA / "sunsided-mpu6050" / "set-2" / "unmoved-with-x-pointing-forward" / "mpu6050.csv")
    assert load(path, columns="gx=none,gy=none,gz=none").n == 1


# ----------------------------------------------------------------------------- gyro columns as the accelerometer
def imu_counts(n_poses: int) -> pd.DataFrame:
    """An unsigned 16-bit IMU in counts: the accelerometer at 4096 counts/g, the gyro at mid-scale with
    its bias and 25 counts of noise (the Xsens MTi's gyro at rest: 27 counts)."""
    model = LumpedModel.from_physical([4096.0, 4096.0, 4096.0], 0.0, 0.0, 0.0, [32768.0, 32768.0, 32768.0])
    syn = synthesize_recording(model, uniform_directions(n_poses, rng=7), sigma=8.0, quantum=1.0, units="counts",
                               gyro=False, rng=8)
    frame = syn.frame.rename(columns={"ax": "acc_x", "ay": "acc_y", "az": "acc_z"})
    rng = np.random.default_rng(9)
    for axis, bias in zip("xyz", (310.0, -240.0, 180.0)):
        frame[f"gyro_{axis}"] = np.round(32768.0 + bias + 25.0 * rng.standard_normal(len(frame)))
    return frame


@pytest.mark.parametrize("n_poses", [1, 3, 6])
def test_gyro_columns_as_accelerometer_refused_with_few_poses(n_poses, tmp_path):
    path = tmp_path / "imu.csv"
    imu_counts(n_poses).to_csv(path, index=False)
    assert load(path).n == n_poses  # the accelerometer's own columns
    with pytest.raises(InputError, match=r"noisier than 0.05 g per sample.*gyroscope columns\? map the "
                                         r"accelerometer's with --columns"):
        load(path, columns="ax=gyro_x,ay=gyro_y,az=gyro_z")


def test_xsens_gyro_as_accelerometer_refused_with_six_poses(tmp_path):
    """imu_tk's Xsens log cut after its sixth pose, its gyro columns mapped as the accelerometer."""
    frame = pd.read_csv(need(DATA / "imutk-xsens" / "xsens_imutk.csv"), nrows=11_360)
    path = tmp_path / "xsens6.csv"
    frame.to_csv(path, index=False)
    assert load(path).n == 6
    with pytest.raises(InputError, match=r"noisier than 0.05 g per sample.*gyroscope columns\? map the "
                                         r"accelerometer's with --columns"):
        load(path, columns="ax=gyro_x_counts,ay=gyro_y_counts,az=gyro_z_counts")
