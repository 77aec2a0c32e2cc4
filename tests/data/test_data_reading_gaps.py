"""Two reading gaps of the data layer: a slow turn that keeps |a| taken for a rest when there is no gyro,
and gyroscope columns mapped as the accelerometer whose noise is far below their offset."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from optcal.data import load, load_with_segmentation
from optcal.data.readers import source_from_frame
from optcal.data.recording import recording_from_source
from optcal.data.static import SWEEPING, SWEEPING_STRETCHES, detect_static
from optcal.families.simulate.recording import synthesize_recording
from optcal.errors import InputError
from optcal.core.model import lu2017_reference_model
from optcal.families.simulate.poses import uniform_directions

from helpers.common import SHARED

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"


def plant_slow_turn(x: np.ndarray, t: np.ndarray, zero: np.ndarray, rate_dps: float, tilt_deg: float) -> np.ndarray:
    """``x`` (n, 3) turned about an axis ``tilt_deg`` from its mean direction at ``rate_dps`` (Rodrigues):
    |x − zero| is kept, the axes move slowly, as in a pan by hand about an axis near the vertical."""
    v = x - zero
    m = v.mean(axis=0) / np.linalg.norm(v.mean(axis=0))
    p = np.cross(m, [1.0, 0.0, 0.0] if abs(m[0]) < 0.9 else [0.0, 1.0, 0.0])
    p /= np.linalg.norm(p)
    u = np.cos(np.radians(tilt_deg)) * m + np.sin(np.radians(tilt_deg)) * p
    phi = np.radians(rate_dps) * (t - t[0])[:, None]
    turned = v * np.cos(phi) + np.cross(u, v) * np.sin(phi) + np.outer(v @ u, u) * (1.0 - np.cos(phi))
    return turned + zero


def segment_frame(frame: pd.DataFrame):
    return detect_static(recording_from_source(source_from_frame(frame, "planted", "csv")))


def test_slow_turn_keeping_the_norm_is_not_a_pose_without_gyro():
    """Twelve 10 s dwells, one of them turned at 1 °/s about an axis 10° from gravity: within one window the
    axes move by less than the noise (the moving std and the half-window drift pass), across the dwell the
    means sweep 0.03 g, three times the gate: that dwell is rejected and counted, the eleven others kept."""
    syn = synthesize_recording(lu2017_reference_model(), uniform_directions(12, rng=5), dwell_s=10.0, sigma=0.002,
                               gyro=False, rng=6)
    frame = syn.frame
    clean = segment_frame(frame)
    assert len(clean.intervals) == 12 and not clean.exclusions.get(SWEEPING_STRETCHES)
    a, b = syn.dwells[5]
    acc = frame[["ax", "ay", "az"]].to_numpy(dtype=float, copy=True)
    acc[a:b] = plant_slow_turn(acc[a:b], frame["t"].to_numpy()[a:b], np.zeros(3), rate_dps=1.0, tilt_deg=10.0)
    planted = frame.copy()
    planted[["ax", "ay", "az"]] = acc
    seg = segment_frame(planted)
    assert len(seg.intervals) == 11
    assert all(iv.stop <= a or iv.start >= b for iv in seg.intervals)
    assert seg.exclusions[SWEEPING_STRETCHES] == 1 and seg.exclusions[SWEEPING] > 0.8 * (b - a)
    # the rejected stretch is in the trace with its reason, and the segmentation figure marks it
    t = frame["t"].to_numpy()
    (t0, t1, reason), = [r for r in seg.trace["rejected"] if r[2] == SWEEPING_STRETCHES]
    assert t[a] <= t0 < t1 <= t[b - 1] and t1 - t0 > 0.8 * (t[b - 1] - t[a])
    from optcal.report.segmentation_figure import segmentation_figure

    labels = segmentation_figure(seg).axes[0].get_legend_handles_labels()[1]
    assert "rejected: mean creeps" in labels and "static interval" in labels
    # the norm did not change: |a| alone cannot see it
    assert np.allclose(np.linalg.norm(acc[a:b], axis=1), np.linalg.norm(frame[["ax", "ay", "az"]].to_numpy()[a:b], axis=1))


def test_slow_turn_planted_in_a_real_recording_without_gyro():
    """IMU-TK's Xsens log without its gyro.  One rest turned at 0.3 °/s about an axis 10° from its gravity
    direction (|a| kept) is no longer a pose (its batch means trend); the others are found as before."""
    if not XSENS.exists():
        pytest.skip(f"{XSENS} is not present")
    frame = pd.read_csv(XSENS).drop(columns=["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"])
    before = segment_frame(frame)
    # 38 rests; without the gyro one 0.5 s stretch of a move's slow end (18 mg per-sample noise) passes as well
    assert len(before.intervals) in (38, 39)
    longest = max(before.intervals[1:], key=lambda iv: iv.n_samples)
    a, b = longest.start, longest.stop
    cols = ["acc_x_counts", "acc_y_counts", "acc_z_counts"]
    acc = frame[cols].to_numpy(dtype=float, copy=True)
    acc[a:b] = plant_slow_turn(acc[a:b], frame["t_s"].to_numpy()[a:b], np.full(3, 32768.0), rate_dps=0.3, tilt_deg=10.0)
    planted = frame.copy()
    planted[cols] = acc
    after = segment_frame(planted)
    assert len(after.intervals) == len(before.intervals) - 1 and after.exclusions[SWEEPING_STRETCHES] == 1
    assert all(iv.stop <= a or iv.start >= b for iv in after.intervals)
    kept = [iv for iv in before.intervals if iv.start != a]
    assert [(iv.start, iv.stop) for iv in after.intervals] == [(iv.start, iv.stop) for iv in kept]


def gyro_as_accelerometer(frame: pd.DataFrame, path, **options):
    frame.to_csv(path, index=False)
    return load(path, **options)


def test_gyro_with_an_offset_far_above_its_noise_mapped_as_accelerometer_is_refused(tmp_path):
    """A gyro whose bias (≈ 50 °/s) is 300× its noise reads the same offset in all six orientations: below
    the noise-to-offset rule's 5 %, and too few poses for the sphere rule, so it was read as six poses of an
    accelerometer; the pose means' spread (0.04 % of |a|, an accelerometer turned between poses moves them
    by a good part of 1 g) refuses it.  The accelerometer's own columns of the same file still load."""
    syn = synthesize_recording(lu2017_reference_model(), uniform_directions(6, rng=1), sigma=0.002,
                               gyro_bias_dps=(40.0, -25.0, 15.0), gyro_sigma_dps=0.1, rng=2)
    path = tmp_path / "imu.csv"
    with pytest.raises(InputError, match="one constant offset, as a gyroscope at rest reads in every orientation"):
        gyro_as_accelerometer(syn.frame, path, columns="ax=gx,ay=gy,az=gz", units="counts")
    assert load(path).n == 6


def test_gyro_with_an_offset_planted_on_a_real_recording_is_refused(tmp_path):
    """The first quarter of the Xsens log (7 rests) with its gyro counts mapped as the accelerometer and
    shifted from the unsigned mid-scale to a signed converter's offset of 5000 counts: the noise is 0.3 % of
    that offset (the 5 % rule passes it), the 7 means stay within 30 counts of each other: refused."""
    if not XSENS.exists():
        pytest.skip(f"{XSENS} is not present")
    frame = pd.read_csv(XSENS)
    frame = frame.iloc[: len(frame) // 4].copy()
    gyro = ["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]
    frame[gyro] = frame[gyro] - 32768 + 5000
    path = tmp_path / "xsens_quarter.csv"
    mapped = "ax=gyro_x_counts,ay=gyro_y_counts,az=gyro_z_counts,gx=none,gy=none,gz=none"
    with pytest.raises(InputError, match="pose means do not look like an accelerometer's: they stay within"):
        gyro_as_accelerometer(frame, path, columns=mapped)
    assert load_with_segmentation(path).poses.n == 7  # the accelerometer's columns: its rests


def _one_orientation_log(path, header: str) -> None:
    """Two rests of one orientation (a bump between them) of an accelerometer whose z offset is 0.22 g: |a| = 0.78 g."""
    rng = np.random.default_rng(3)
    n = 3000
    a = np.tile([0.1, 0.06, 0.78], (2 * n + 200, 1)) + rng.normal(0.0, 0.004, (2 * n + 200, 3))
    a[n:n + 200] += 0.3 * np.sin(np.linspace(0.0, 4 * np.pi, 200))[:, None]  # handled for 2 s, then
    a[n + 200:, 0] += 0.005  # set down 0.4° from where it was: two rests of (nearly) one orientation
    t = np.arange(len(a)) / 100.0
    np.savetxt(path, np.column_stack([t, a]), delimiter=",", header=header, comments="", fmt="%.6f")


def test_one_orientation_far_from_1_g_is_read_when_its_unit_is_stated(tmp_path, capsys):
    """One orientation cannot tell an accelerometer's 0.22 g offset from a wrong unit or a gyroscope's constant
    reading: with the unit decided from the magnitudes the refusal says so and names ``--units``; with the unit
    stated (the flag, or the unit word in the header) the columns are an accelerometer's and the log is read."""
    plain = tmp_path / "still.csv"
    _one_orientation_log(plain, "t,ax,ay,az")
    with pytest.raises(InputError, match=r"offset of 0\.21 g and a wrong unit look the same: --units g"):
        load(plain)
    assert load(plain, units="g").n == 2
    worded = tmp_path / "still_g.csv"
    _one_orientation_log(worded, "t,ax_g,ay_g,az_g")
    assert load(worded).n == 2
