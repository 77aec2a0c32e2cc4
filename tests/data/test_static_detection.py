"""Static detection on synthetic raw recordings with known truth."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from optcal.data import StaticSettings, load
from optcal.data.readers import source_from_frame
from optcal.data.recording import recording_from_source
from optcal.data.static import (
    MOVING,
    SHORT,
    SHORT_STRETCHES,
    TRIMMED,
    detect_static,
)
from optcal.families.simulate.recording import synthesize_recording
from optcal.core.model import LumpedModel, lu2017_reference_model
from optcal.families.simulate.poses import tilted_sweeps, uniform_directions

SIGMA = 0.002  # g per sample, MPU-6050-like


def detect(frame: pd.DataFrame, settings: StaticSettings | None = None, **kw):
    rec = recording_from_source(source_from_frame(frame, "synthetic", "csv"), **kw)
    return detect_static(rec, settings)


def dwell_labels(syn) -> np.ndarray:
    lab = np.full(syn.n_samples, -1)
    for i, (a, b) in enumerate(syn.dwells):
        lab[a:b] = i
    return lab


def slow_mask(syn) -> np.ndarray:
    m = np.zeros(syn.n_samples, dtype=bool)
    for a, b in syn.slow:
        m[a:b] = True
    return m


@pytest.fixture(scope="module")
def with_slow_rotations():
    return synthesize_recording(lu2017_reference_model(), uniform_directions(30, rng=1), sigma=SIGMA,
                                slow_creeps=3, slow_turns=3, slow_rate_dps=1.0, rng=2, temperature=(25.0, 0.01))


def test_intervals_match_the_true_dwells_one_to_one(with_slow_rotations):
    syn = with_slow_rotations
    seg = detect(syn.frame)
    lab = dwell_labels(syn)
    assert len(seg.intervals) == len(syn.dwells)
    found = []
    for iv in seg.intervals:
        inside = lab[iv.start:iv.stop]
        main = np.bincount(inside[inside >= 0]).argmax()
        assert np.mean(inside == main) >= 0.95, "an interval straddles two poses or a rotation"
        a, b = syn.dwells[main]
        assert iv.n_samples >= 0.7 * (b - a), "most of the dwell is used"
        found.append(main)
    assert sorted(found) == list(range(len(syn.dwells)))


def test_poses_and_noise_recovered(with_slow_rotations):
    syn = with_slow_rotations
    seg = detect(syn.frame)
    poses = seg.pose_table()
    assert poses.source == "raw recording"
    truth = syn.true_pose_means()
    lab = dwell_labels(syn)
    order = [np.bincount(lab[iv.start:iv.stop][lab[iv.start:iv.stop] >= 0]).argmax() for iv in seg.intervals]
    err = (poses.acc - truth[order]) / poses.sigma[:, None]
    # pose means within the noise of the mean (a few edge samples may lean into a rotation)
    assert np.sqrt(np.mean(err**2)) < 1.5
    # white noise: σ_k ≈ σ/√n_k (batch means never below the white value, scatter ±15 %),
    # and the per-axis spread equals the simulated noise
    ratio = poses.sigma / (SIGMA / np.sqrt(poses.n_samples))
    assert np.all((ratio > 0.9) & (ratio < 1.45)) and 0.95 < np.median(ratio) < 1.2
    assert np.allclose([iv.std for iv in seg.intervals], SIGMA, rtol=0.2)
    # temperature: mean over each interval
    temp = syn.frame["temp"].to_numpy()
    assert np.allclose(poses.temp, [temp[iv.start:iv.stop].mean() for iv in seg.intervals])
    assert np.all(np.diff(poses.t) > 0) and list(poses.rows) == list(range(1, poses.n + 1))


def test_slow_rotation_is_never_a_static_pose_with_gyro(with_slow_rotations):
    syn = with_slow_rotations
    slow = slow_mask(syn)
    seg = detect(syn.frame)
    window = seg.trace["window_samples"]
    for iv in seg.intervals:
        assert slow[iv.start:iv.stop].sum() <= window // 10


def test_without_gyro_a_turn_about_the_vertical_is_missed(with_slow_rotations):
    """The accelerometer cannot see a turn about gravity: that is what the gyro gate is for."""
    syn = with_slow_rotations
    slow = slow_mask(syn)
    seg = detect(syn.frame.drop(columns=["gx", "gy", "gz"]))
    worst = max(slow[iv.start:iv.stop].sum() for iv in seg.intervals)
    assert worst > 0.5 * syn.slow[:, 1].__sub__(syn.slow[:, 0]).min()


@pytest.mark.parametrize("rate_dps", [1.0, 2.0, 5.0])
def test_slow_creeps_rejected_at_several_rates(rate_dps):
    syn = synthesize_recording(lu2017_reference_model(), uniform_directions(12, rng=3), sigma=SIGMA,
                               slow_creeps=4, slow_rate_dps=rate_dps, rng=4)
    seg = detect(syn.frame)
    slow = slow_mask(syn)
    for iv in seg.intervals:
        assert slow[iv.start:iv.stop].mean() < 0.1


def test_every_sample_is_accounted_for(with_slow_rotations):
    syn = with_slow_rotations
    seg = detect(syn.frame, StaticSettings(trim_s=0.2, min_dwell_s=0.5))
    sample_counts = sum(v for k, v in seg.exclusions.items() if k.startswith("samples") or "samples" in k.split(" (")[0])
    assert seg.n_used + sample_counts == syn.n_samples
    assert seg.exclusions[TRIMMED] == len(seg.intervals) * 2 * 20
    assert seg.exclusions[MOVING] > 0


def test_short_dwells_are_dropped_and_counted():
    syn = synthesize_recording(lu2017_reference_model(), uniform_directions(10, rng=5), sigma=SIGMA,
                               dwell_s=(1.2, 6.0), rng=6)
    seg = detect(syn.frame, StaticSettings(min_dwell_s=2.0))
    lengths = (syn.dwells[:, 1] - syn.dwells[:, 0]) / syn.rate_hz
    # a dwell of L s leaves about L − window of window centres
    assert len(seg.intervals) == np.sum(lengths - 1.0 >= 2.0 + 0.05) or len(seg.intervals) == np.sum(lengths - 1.0 >= 2.0 - 0.05)
    assert seg.exclusions.get(SHORT_STRETCHES, 0) == len(syn.dwells) - len(seg.intervals)
    assert seg.exclusions.get(SHORT, 0) > 0
    assert all(iv.duration_s >= 2.0 - 0.011 for iv in seg.intervals)


def test_the_noise_is_measured_not_assumed():
    """The same recording at 1× and 10× the noise: the same 12 rests, each test at its distribution's quantile
    (the same critical values), the rests' measured noise 10 times larger."""
    found, noise, limits = [], [], []
    for sigma in (SIGMA, 10 * SIGMA):
        syn = synthesize_recording(lu2017_reference_model(), uniform_directions(12, rng=7), sigma=sigma, rng=8)
        seg = detect(syn.frame)
        found.append(len(seg.intervals))
        noise.append(seg.noise_floor["rest_noise_median"])
        limits.append(seg.thresholds)
    assert found == [12, 12]
    assert noise[1] / noise[0] == pytest.approx(10, rel=0.1)
    assert limits[0] == limits[1]


def test_multipliers_scale_the_critical_values():
    syn = synthesize_recording(lu2017_reference_model(), uniform_directions(12, rng=7), sigma=SIGMA, rng=8)
    base = detect(syn.frame).thresholds
    loose = detect(syn.frame, StaticSettings(threshold=2.0, drift_threshold=3.0)).thresholds
    assert loose["step"] == pytest.approx(2 * base["step"]) and loose["trend"] == pytest.approx(3 * base["trend"])


def test_time_gap_splits_an_interval():
    syn = synthesize_recording(lu2017_reference_model(), uniform_directions(10, rng=9), sigma=SIGMA, dwell_s=8.0, rng=10)
    frame = syn.frame.copy()
    a, b = syn.dwells[3]
    mid = (a + b) // 2
    frame.loc[mid:, "t"] += 2.0  # the logger stopped for 2 s in the middle of dwell 3
    seg = detect(frame)
    assert len(seg.intervals) == 11


def test_noise_free_recording_has_exact_poses():
    model = lu2017_reference_model()
    d = tilted_sweeps(4)
    syn = synthesize_recording(model, d, sigma=0.0, gyro_sigma_dps=0.0, rng=1)
    seg = detect(syn.frame)
    assert len(seg.intervals) == len(d)
    assert np.allclose(seg.pose_table().acc, model.measure(d), atol=1e-12)


def _z_scores(model, sigma, quantum, units, seed, tmp_path=None):
    from optcal.families.accel.calibration import calibrate

    syn = synthesize_recording(model, uniform_directions(40, rng=100 + seed), sigma=sigma, quantum=quantum,
                               units=units, dwell_s=(3.0, 8.0), rng=200 + seed, slow_creeps=2, slow_turns=2)
    if tmp_path is not None:  # the whole way from a CSV file
        syn.frame.to_csv(tmp_path / "raw.csv", index=False, float_format="%.9g")
        poses = load(tmp_path / "raw.csv")
    else:
        poses = detect(syn.frame).pose_table()
    assert poses.source == "raw recording" and poses.units == units
    assert poses.n == len(syn.dwells)
    result = calibrate(poses)
    se = np.array([result.stderr[k] for k in result.param_names[:9]])
    return (result.params[:9] - model.theta) / se


def test_raw_recordings_calibrate_within_three_standard_errors(tmp_path):
    """Known truth end to end (raw recording in g, with slow rotations → static detection → mle).

    Monte Carlo over 6 recordings: the 54 z-scores (estimate − truth)/SE are standard normal,
    so all lie within 3 SE but for at most one (P(|z| > 3) = 0.27 %), and their rms is ≈ 1.
    """
    model = LumpedModel.from_physical([1.01, 0.99, 1.02], np.deg2rad(0.5), np.deg2rad(-0.3), np.deg2rad(0.4),
                                      [0.04, -0.02, -0.11])
    z = np.concatenate([_z_scores(model, 0.004, None, "g", seed, tmp_path if seed == 0 else None) for seed in range(6)])
    assert np.sum(np.abs(z) > 3) <= 1, z
    assert 0.7 < np.sqrt(np.mean(z**2)) < 1.4


def test_raw_recording_in_counts_calibrates_within_three_standard_errors(tmp_path):
    """Known truth end to end in raw counts (MPU-6050-like): parameters within 3 SE."""
    model = LumpedModel.from_physical([16300, 16450, 16700], np.deg2rad(0.5), np.deg2rad(-0.3), np.deg2rad(0.4),
                                      [700.0, -360.0, -1800.0])
    z = _z_scores(model, 60.0, 1.0, "counts", 1, tmp_path)
    assert np.all(np.abs(z) < 3), z


def test_sigma_of_mean_sees_correlated_noise():
    """AR(1) noise (ρ = 0.95): the mean scatters √((1+ρ)/(1−ρ)) ≈ 6× more than σ/√n."""
    from optcal.data.static_poses import sigma_of_mean

    rng = np.random.default_rng(3)
    rho, n, reps = 0.95, 2000, 200
    e = rng.standard_normal((reps, n, 3))
    x = np.empty_like(e)
    x[:, 0] = e[:, 0] / np.sqrt(1 - rho**2)
    for i in range(1, n):
        x[:, i] = rho * x[:, i - 1] + e[:, i]
    true_sd = x.mean(axis=1).std()
    est = np.array([sigma_of_mean(x[r], 10) for r in range(reps)])
    white = np.array([sigma_of_mean(x[r], 0) for r in range(reps)])
    assert np.median(white) < 0.25 * true_sd
    assert 0.8 < np.median(est) / true_sd < 1.2
