"""The rest model (issue 26) on the recordings the old detector refused, and every refusal overridable.

The shared files (../shared/data, skipped without it): ckexplorer's holds-only log (160 holds of 100 samples,
no motion samples, no time), divemove's low-pass filtered tag (netCDF-4).  The rest model's own statistics
(:mod:`optcal.data.rest_model`) against their distributions on white noise.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from optcal.data import load, load_with_segmentation
from optcal.data import rest_model as rm
from optcal.data.quantiles import column_medians, quantiles
from optcal.data.readers import source_from_frame
from optcal.data.recording import recording_from_source
from optcal.data.static import FEW_STRETCHES, SHORT_STRETCHES, StaticSettings, detect_static
from optcal.errors import InputError

from helpers.common import SHARED

CKEXPLORER = SHARED / "data" / "ckexplorer-holds" / "acc_log.csv"
DIVEMOVE = SHARED / "data" / "divemove-tag" / "magnt_accel_calib.nc"


def need(path):
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


# ----------------------------------------------------------------------------- the statistics
def test_fast_order_statistics_equal_numpys() -> None:
    """The per-stretch medians and quantiles (data.quantiles: one partition each) give numpy's values exactly, and
    the batches of each range are numpy's groupings (array_split's, or evenly spread), so the detector's verdicts
    do not depend on which is used."""
    rng = np.random.default_rng(3)
    for k in range(1, 41):
        x = rng.normal(size=(k, 3)) * rng.uniform(0.1, 10.0, 3)
        assert np.array_equal(column_medians(x), np.median(x, axis=0))
        for q in (0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0):
            assert quantiles(x[:, 0], [q])[0] == np.quantile(x[:, 0], q)
        if k >= rm.TREND_BATCHES:
            one = rm.Ranges.of([0], [k])
            split = [len(g) for g in np.array_split(np.arange(k), rm.TREND_BATCHES)]
            assert list(rm.batch_ranges(one, rm.TREND_BATCHES, larger_first=True)[0].length) == split
            even = (np.arange(rm.TREND_BATCHES) * k) // rm.TREND_BATCHES
            assert list(rm.batch_ranges(one, rm.TREND_BATCHES)[0].start) == list(even)
    assert rm.step_limit_one(1e-3, 40.0) == float(rm.step_limit(1e-3, np.array([40.0]))[0])


def test_step_statistic_has_its_stated_false_alarm_on_white_noise() -> None:
    """Consecutive blocks of one white-noise rest: the step statistic exceeds its 1e-3 critical value about
    once in a thousand pairs (κ² measured on the same pairs, as the detector does)."""
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400_000, 3)) * [1.0, 2.0, 0.5]
    b = rm.make_blocks(np.arange(x.shape[0]) / 100.0, x, None, 25, np.zeros(0, dtype=np.int64), 0.0, 0.0)
    ratios = rm.pair_ratios(b.mean, b.var, b.n)
    dof = b.n[1:] + b.n[:-1] - 2.0
    kappa2 = rm.noise_colour(ratios, float(np.median(dof)), 0.5)
    np.testing.assert_allclose(kappa2, 1.0, atol=0.1)
    rate = float(np.mean(rm.step_statistic(ratios, kappa2) > rm.step_limit(1e-3, dof)))
    assert 0.2e-3 < rate < 3e-3


def test_noise_colour_of_filtered_noise_is_measured() -> None:
    """Noise averaged over 10 samples (a moving-average filter): the block means scatter 10 times more than
    the within-block spread says, and κ² says so."""
    rng = np.random.default_rng(1)
    white = rng.normal(size=(200_010, 3))
    x = np.cumsum(white, axis=0)
    x = (x[10:] - x[:-10]) / 10.0
    b = rm.make_blocks(np.arange(x.shape[0]) / 100.0, x, None, 100, np.zeros(0, dtype=np.int64), 0.0, 0.0)
    kappa2 = rm.noise_colour(rm.pair_ratios(b.mean, b.var, b.n), 198.0, 0.5)
    assert np.all((kappa2 > 6.0) & (kappa2 < 14.0))


def test_trend_statistic_is_student_t_on_a_rest_and_sees_a_creep() -> None:
    rng = np.random.default_rng(2)
    t = np.arange(64) * 0.25
    flat = [rm.trend_statistic(t, rng.normal(size=(64, 3)))[0] for _ in range(2000)]
    # the largest |t| of three axes with 6 dof beyond the Bonferroni quantile about once in a thousand
    assert np.mean(np.array(flat) > rm.trend_limit(1e-3, 6)) < 5e-3
    creep = rng.normal(size=(64, 3)) + np.outer(t, [0.5, 0.0, 0.0])
    tstat, dof, change, spread = rm.trend_statistic(t, creep)
    assert tstat > rm.trend_limit(1e-3, dof) and change == pytest.approx(0.5 * (t[-1] - t[0]), rel=0.1)


def test_half_sample_mode_finds_the_bias_among_turning_rates() -> None:
    rng = np.random.default_rng(3)
    at_rest = 0.02 + 0.001 * rng.normal(size=600)
    turning = rng.uniform(-2.0, 2.0, size=400)
    assert rm.half_sample_mode(np.concatenate([at_rest, turning])) == pytest.approx(0.02, abs=0.002)
    assert stats.median_abs_deviation(at_rest) < 0.002


# ----------------------------------------------------------------------------- the recordings refused before
@pytest.mark.parametrize("rate", [100.0, 50.0])
def test_holds_only_log_gives_its_holds(rate: float) -> None:
    """160 holds of 100 samples, back to back: each jump between holds is a step; 150-160 poses, each
    inside one hold, whatever the rate given (the rest model has no rate-dependent constant but the dwell)."""
    loaded = load_with_segmentation(need(CKEXPLORER), rate=rate)
    ivs = loaded.segmentation.intervals
    assert 150 <= len(ivs) <= 160
    assert all(iv.start // 100 == (iv.stop - 1) // 100 for iv in ivs)


def test_low_pass_filtered_tag_calibrates_to_its_noise() -> None:
    """divemove's tag, stored low-pass filtered, opened as it is: about ten poses of its 14-50 s rests (a long
    stretch measures the noise of its own mean from its batch means), and the calibration's rms |a|-1 at most
    0.3 mg (the moves' settling oscillations are not poses)."""
    from optcal.families.accel.calibration import calibrate

    loaded = load_with_segmentation(need(DIVEMOVE))
    poses, ivs = loaded.poses, loaded.segmentation.intervals
    assert 9 <= poses.n <= 14
    assert calibrate(poses).rms_norm_residual_g <= 0.3e-3
    # a rest the step test cut in two (a knock, the filter's smoothing) is one pose: no two consecutive poses'
    # means lie within the model's "same pose" distance, 3 per-sample σ (the pieces split before lay 0.8-1.9 σ apart)
    apart = [np.linalg.norm(q.mean - p.mean) / min(np.linalg.norm(p.std), np.linalg.norm(q.std))
             for p, q in zip(ivs[:-1], ivs[1:])]
    assert min(apart) > rm.SAME_POSE_SAMPLE_SIGMAS, np.round(apart, 2)


def test_a_long_rest_measures_its_own_noise_of_the_mean() -> None:
    """A 1 Hz low-pass filtered float rest at 200 Hz: its samples are correlated over about 0.2 s (the
    integrated autocorrelation time), so 20 s hold about a hundred independent samples.  The pairs of 0.25 s
    blocks overstate the colour (a block is smoother than the noise between blocks: κ² of thousands); the
    stretch's batch means measure it within their chi-square scatter."""
    from scipy import signal

    from optcal.data.rest_tests import RestModel

    rng = np.random.default_rng(7)
    n, rate = 4000, 200.0
    sos = signal.butter(4, 1.0, fs=rate, output="sos")
    noise = signal.sosfiltfilt(sos, rng.normal(size=(n + 2000, 6)), axis=0)[1000:-1000]
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * noise[:, :3] / noise[:, :3].std()
    gyro = np.radians(0.05) * noise[:, 3:] / noise[:, 3:].std()
    frame = pd.DataFrame({"t": np.arange(n) / rate, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
                          "gx": gyro[:, 0], "gy": gyro[:, 1], "gz": gyro[:, 2]})
    rec = recording_from_source(source_from_frame(frame, "filtered", "csv"))
    s = StaticSettings()
    model = RestModel(rec, s, rec.t, rec.acc, rec.gyro, 50, np.zeros(0, dtype=np.int64), rate)
    k = model.b.count
    x = noise[:, 2] - noise[:, 2].mean()
    acf = np.correlate(x, x, "full")[n - 1:] / (x @ x)
    tau = 1.0 + 2.0 * acf[1:200].sum()  # the integrated autocorrelation time, samples
    truth = n / tau
    assert float(np.median(model.kappa2)) > 10 * tau  # what the block pairs say: far too few samples
    verdict = model.judge([(0, n, 0, k)])
    for measured in (verdict.independent[0], verdict.independent_gyro[0]):
        assert truth / 4 < measured < truth * 4
    assert len(detect_static(rec).intervals) >= 1


def test_a_short_stretch_with_correlated_gyro_noise_is_refused_naming_the_flag() -> None:
    """Two rests of 2.5 s whose gyro sways with a 0.5 s correlation (a hand's slow sway through a pause):
    fewer than four independent gyro samples each, so no rest; the refusal names --min-independent, which
    lets them through with a warning, as --no-gyro-gate does."""
    from scipy import signal

    rng = np.random.default_rng(3)
    rate, dwell = 100.0, 250
    sos = signal.butter(2, 0.3, fs=rate, output="sos")
    pieces, rates = [], []
    for d in ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]):
        pieces.append(np.array(d) + 1e-3 * rng.normal(size=(dwell, 3)))
        sway = signal.sosfiltfilt(sos, rng.normal(size=(dwell + 600, 3)), axis=0)[300:-300]
        rates.append(np.radians(0.02) * sway / sway.std())
        pieces.append(np.linspace(d, [0.0, 1.0, 0.0], 60) + 1e-3 * rng.normal(size=(60, 3)))
        rates.append(np.full((60, 3), np.radians(90.0)))
    acc, gyro = np.vstack(pieces), np.vstack(rates) + np.radians(0.01) * rng.normal(size=(2 * (dwell + 60), 3))
    frame = pd.DataFrame({"t": np.arange(acc.shape[0]) / rate, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
                          "gx": gyro[:, 0], "gy": gyro[:, 1], "gz": gyro[:, 2]})
    rec = recording_from_source(source_from_frame(frame, "sway", "csv"))
    seg = detect_static(rec)
    assert seg.n_used == 0 and seg.evidence[FEW_STRETCHES] >= 2
    with pytest.raises(InputError, match=r"fewer independent samples .*--min-independent N"):
        seg.pose_table()
    loose = detect_static(rec, StaticSettings(min_independent=1.0))
    assert len(loose.intervals) == 2
    assert any("--min-independent 1" in w for w in loose.override_warnings())
    assert len(detect_static(rec, StaticSettings(use_gyro=False)).intervals) == 2


# ----------------------------------------------------------------------------- every refusal can be overridden
def test_too_short_for_the_dwell_is_refused_naming_the_flag_and_passes_with_it() -> None:
    frame = pd.read_csv(need(CKEXPLORER))
    with pytest.raises(InputError, match=r"shorter than the minimum dwell 2 s \(--min-dwell S") as caught:
        load(CKEXPLORER, rate=100.0, min_dwell_s=2.0)
    assert "never rests by the model" in str(caught.value)
    seg = detect_static(recording_from_source(source_from_frame(frame, "holds", "csv"), rate=100.0),
                        StaticSettings(min_dwell_s=2.0))
    assert seg.exclusions[SHORT_STRETCHES] >= 150
    assert load(CKEXPLORER, rate=100.0, min_dwell_s=0.5).n >= 150


def test_each_multiplier_loosens_its_test() -> None:
    """A 10 s rest creeping at 2 mg/s (a slow turn) is no pose; --drift-threshold 100 accepts it and a
    warning says what it assumes; --static-threshold and --gyro-threshold scale their critical values."""
    rng = np.random.default_rng(5)
    n = 3000
    t = np.arange(n) / 100.0
    acc = np.tile([0.0, 0.0, 1.0], (n, 1)) + 0.001 * rng.normal(size=(n, 3))
    acc[1000:2000, 0] += 0.002 * (t[1000:2000] - t[1000])  # creeps by 20 mg over its 10 s (20 σ)
    acc[:1000] = [0.3, 0.0, 0.954] + 0.001 * rng.normal(size=(1000, 3))  # two other rests, other orientations
    acc[2000:] = [0.0, 0.3, 0.954] + 0.001 * rng.normal(size=(1000, 3))
    frame = pd.DataFrame({"t": t, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]})
    rec = recording_from_source(source_from_frame(frame, "creep", "csv"))
    strict = detect_static(rec)
    assert not any(iv.start >= 1000 and iv.stop <= 2000 for iv in strict.intervals)
    loose = detect_static(rec, StaticSettings(drift_threshold=100.0))
    assert any(iv.start >= 1000 and iv.stop <= 2000 for iv in loose.intervals)
    assert any("--drift-threshold 100" in w for w in loose.override_warnings())
    base = strict.thresholds
    wide = detect_static(rec, StaticSettings(threshold=3.0)).thresholds
    assert wide["step"] == pytest.approx(3.0 * base["step"])


# ----------------------------------------------------------------------------- one rest cut in two
XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
XSENS_GYRO = ["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]
XSENS_ACC = ["acc_x_counts", "acc_y_counts", "acc_z_counts"]
XSENS_ZERO = np.full(3, 32768.0)  # the counts' mid-scale (IMU-TK's log is offset binary)


def _tilted(v: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """``v`` (n, 3) turned by ``angle_rad`` (n,) about an axis at right angles to its mean direction (Rodrigues)."""
    m = v.mean(axis=0) / np.linalg.norm(v.mean(axis=0))
    u = np.cross(m, [1.0, 0.0, 0.0] if abs(m[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    c, s = np.cos(angle_rad)[:, None], np.sin(angle_rad)[:, None]
    return v * c + np.cross(u, v) * s + np.outer(v @ u, u) * (1.0 - c)


def _xsens_with(change) -> tuple[object, object, int, int]:
    """IMU-TK's Xsens log without its gyro, segmented before and after ``change(acc, t, a, b)`` rewrites the middle
    of its longest rest ``[a, b)``."""
    frame = pd.read_csv(need(XSENS)).drop(columns=XSENS_GYRO)
    before = detect_static(recording_from_source(source_from_frame(frame, "xsens", "csv")))
    longest = max(before.intervals, key=lambda iv: iv.n_samples)
    a, b = longest.start, longest.stop
    acc = frame[XSENS_ACC].to_numpy(dtype=float, copy=True)
    change(acc, frame["t_s"].to_numpy(), a, b)
    planted = frame.copy()
    planted[XSENS_ACC] = acc
    after = detect_static(recording_from_source(source_from_frame(planted, "xsens", "csv")))
    return before, after, a, b


def _poses_over(seg, a: int, b: int) -> list:
    return [iv for iv in seg.intervals if iv.start < b and iv.stop > a]


def test_a_knock_in_a_rest_without_gyro_leaves_one_pose() -> None:
    """A knock in the middle of the Xsens log's longest rest (a decaying 8 Hz ring of 40 per-sample σ for 1.5 s, longer
    than the dwell prior joins): the step test cuts the rest, and without a gyro the accelerometer's block means,
    which never leave the pose's wobble tolerance, join the two pieces into one pose, whose mean is the rest's."""
    sigma = {}

    def knock(acc, t, a, b):
        mid = (a + b) // 2
        ring = (t[mid:] - t[mid] < 1.5).sum()
        tau = t[mid:mid + ring] - t[mid]
        sigma["per_sample"] = float(np.linalg.norm(acc[a:mid].std(axis=0)))
        acc[mid:mid + ring] += np.outer(40.0 * sigma["per_sample"] * np.exp(-tau / 0.4) * np.sin(2 * np.pi * 8.0 * tau),
                                        [0.6, 0.0, 0.8])

    before, after, a, b = _xsens_with(knock)
    assert len(_poses_over(before, a, b)) == 1
    over = _poses_over(after, a, b)
    assert len(over) == 1, [(iv.start, iv.stop) for iv in over]
    assert len(after.intervals) == len(before.intervals)
    original = _poses_over(before, a, b)[0]
    assert over[0].n_samples >= 0.8 * original.n_samples  # all of the rest but the knock
    assert np.linalg.norm(over[0].mean - original.mean) < sigma["per_sample"]


def test_a_pose_left_and_regained_without_gyro_stays_two_poses() -> None:
    """The same rest tilted away by 20° and back over 2 s in its middle (a move, not a rest): the two pieces
    have the same mean, but the block means between them leave the pose, so they are two poses."""

    def excursion(acc, t, a, b):
        mid = (a + b) // 2
        n = (t[mid:] - t[mid] < 2.0).sum()
        angle = np.radians(20.0) * np.sin(np.pi * (t[mid:mid + n] - t[mid]) / 2.0)
        acc[mid:mid + n] = _tilted(acc[mid:mid + n] - XSENS_ZERO, angle) + XSENS_ZERO

    before, after, a, b = _xsens_with(excursion)
    assert len(_poses_over(before, a, b)) == 1
    over = _poses_over(after, a, b)
    assert len(over) == 2
    assert len(after.intervals) == len(before.intervals) + 1


@pytest.mark.parametrize("use_gyro", [True, False])
def test_the_stretches_judged_together_are_judged_as_one_by_one(monkeypatch, use_gyro) -> None:
    """The Xsens log's still stretches judged at once give, stretch by stretch, what each judged alone gives (no
    statistic of one stretch reaches into its neighbour's blocks)."""
    from optcal.data.rest_tests import RestModel

    calls = []
    judge = RestModel.judge

    def recording(self, pieces):
        calls.append((self, list(pieces)))
        return judge(self, pieces)

    monkeypatch.setattr(RestModel, "judge", recording)
    frame = pd.read_csv(need(XSENS))
    detect_static(recording_from_source(source_from_frame(frame, "xsens", "csv")), StaticSettings(use_gyro=use_gyro))
    (model, pieces), = calls
    assert len(pieces) > 30
    together = judge(model, pieces)
    for i, piece in enumerate(pieces):
        alone = judge(model, [piece])
        for field in ("per_sample", "independent", "independent_gyro"):
            assert getattr(alone, field)[0] == pytest.approx(getattr(together, field)[i], rel=1e-9)
        assert alone.creeps[0] == together.creeps[i] and alone.turns[0] == together.turns[i]
    assert np.isfinite(together.independent_gyro).all() == use_gyro  # the gyro counted only where it is evidence


def test_rounding_floor_only_where_the_signal_is_quieter_than_the_quantum() -> None:
    """A block mean keeps the rounding's q²/12 only where the signal's own noise is below half a quantum
    (undithered); a noisier signal's rounding averages down like white noise."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(20_000, 3)) * [3.0, 0.2, 0.45]
    b = rm.make_blocks(np.arange(x.shape[0]) / 100.0, np.round(x), None, 25, np.zeros(0, dtype=np.int64), 1.0, 0.0)
    floor = rm.rounding_floor(b.var, 1.0)
    assert floor[0] == 0.0 and floor[1] == pytest.approx(1.0 / 12.0) and floor[2] == pytest.approx(1.0 / 12.0)
    assert not rm.rounding_floor(b.var, 0.0).any()


def test_a_recording_filtered_below_its_quantum_keeps_its_rests() -> None:
    """IMU-TK's Xsens log through a 1 Hz 4th-order Butterworth and rounded back to counts, as a logger that
    filters before it stores: the filtered noise is below one count, so block means step by a fraction of a count
    as the slow signal crosses a rounding edge, which no white-noise model of the rounding allows (0 poses before
    the rounding floor).  Most of its 38 rests are found and calibrate as the raw log does."""
    from scipy import signal

    from optcal.families.accel.calibration import calibrate

    frame = pd.read_csv(need(XSENS))
    b, a = signal.butter(4, 1.0 / 50.0)  # 1 Hz at 100 Hz
    for column in XSENS_ACC + XSENS_GYRO:
        x = frame[column].to_numpy(dtype=float)
        frame[column] = np.round(signal.lfilter(b, a, x - x[0]) + x[0])
    seg = detect_static(recording_from_source(source_from_frame(frame, "xsens", "csv")))
    assert 30 <= len(seg.intervals) <= 38
    assert calibrate(seg.pose_table()).rms_norm_residual_g <= 0.15e-3


def test_bias_track_follows_a_drift_and_not_a_turn() -> None:
    """The bias track follows a linear drift within the fastest a MEMS bias moves, and passes over spans
    dominated by a turn (a jump of 0.2 rad/s in the local mode, which the drift limit does not allow)."""
    t = np.arange(0.0, 600.0, 0.25)
    drift = np.radians(2.0) * t / 600.0  # 2 °/s over ten minutes
    rates = np.column_stack([drift, -0.5 * drift, np.zeros_like(t)]) + np.random.default_rng(1).normal(0, 1e-4, (t.size, 3))
    limit = rm.MAX_BIAS_DRIFT_RAD_S2
    track = rm.bias_track(t, rates, t, limit)
    assert np.abs(track[:, 0] - drift).max() < np.radians(0.1)
    turning = rates.copy()
    turning[(t > 280) & (t < 330), 2] += 0.2  # 50 s turning at 11 °/s, the densest rates of its spans
    track = rm.bias_track(t, turning, t, limit)
    assert np.abs(track[:, 2]).max() < 0.1 * 0.2  # the turn stays a turn against it
    # a gyro in counts (no rate known for its drift): one bias for the session
    assert np.ptp(rm.bias_track(t, rates, t, None), axis=0).max() == 0.0


def test_a_gyro_whose_bias_drifts_two_degrees_per_second_keeps_the_rests() -> None:
    """IMU-TK's Xsens log with its gyro in rad/s (imu_tk's own scale and bias) and a bias drifting by 2.4 °/s over
    the session (a warming MEMS gyro, within 1 °/s per minute): the rests are found against the bias where they
    are (0 poses against one bias for the session, which a drift beyond 1 °/s leaves behind)."""
    frame = pd.read_csv(need(XSENS))
    scale = np.array([0.000209295, 0.000209899, 0.000209483])  # IMUTK_REFERENCE.md: rad/s per count
    zero = np.array([32777.1, 32459.8, 32511.8])
    t = frame["t_s"].to_numpy()
    gyro = (frame[XSENS_GYRO].to_numpy(dtype=float) - zero) * scale
    gyro += np.radians(2.0) * ((t - t[0]) / (t[-1] - t[0]))[:, None] * np.array([1.0, -0.6, 0.3])
    drifting = pd.DataFrame({"t": t, **{f"a{a}_counts": frame[c] for a, c in zip("xyz", XSENS_ACC)},
                             **{f"g{a}_rad_s": gyro[:, j] for j, a in enumerate("xyz")}})
    seg = detect_static(recording_from_source(source_from_frame(drifting, "xsens", "csv")))
    assert len(seg.intervals) >= 36


@pytest.mark.parametrize("end", ["last", "first"])
def test_a_touch_next_to_a_move_is_left_out_of_the_pose(end: str) -> None:
    """A hand's touch planted in a real rest of the Xsens log, next to its move: a twitch (a 0.2 s ring of 30
    per-sample σ) and then the sensor held tilted by 1.5 mg (one per-sample σ) for the last (or, settling, the first) 1.2 s of an
    8-s rest.  The tilt is within the samples' spread, so the piece joins the pose; it would move the pose's mean by
    several of its standard errors, and is left out and counted (--keep-touches keeps it)."""
    from optcal.data.static import TOUCH, TOUCH_STRETCHES

    frame = pd.read_csv(need(XSENS))
    rec = recording_from_source(source_from_frame(frame, "xsens", "csv"))
    before = detect_static(rec)
    # a rest of 8-12 s in the middle of the session, with a move on either side
    rest = [iv for iv in before.intervals[1:-1] if 8.0 <= iv.duration_s <= 12.0][0]
    a, b = rest.start, rest.stop
    t = frame["t_s"].to_numpy()
    acc = frame[XSENS_ACC].to_numpy(dtype=float, copy=True)
    per_sample = float(np.linalg.norm(acc[a:b].std(axis=0)))
    held = int(round(1.2 / np.median(np.diff(t))))
    ring = int(round(0.2 / np.median(np.diff(t))))
    piece = slice(b - held, b) if end == "last" else slice(a, a + held)
    twitch = slice(b - held - ring, b - held) if end == "last" else slice(a + held, a + held + ring)
    tau = np.arange(ring) * float(np.median(np.diff(t)))
    acc[twitch] += np.outer(30.0 * per_sample * np.exp(-tau / 0.05) * np.sin(2 * np.pi * 12.0 * tau), [0.6, 0.0, 0.8])
    acc[piece] = _tilted(acc[piece] - XSENS_ZERO, np.full(held, 1.5e-3)) + XSENS_ZERO  # 1.5 mrad: 1.5 mg
    planted = frame.copy()
    planted[XSENS_ACC] = acc
    rec2 = recording_from_source(source_from_frame(planted, "xsens", "csv"))
    after = detect_static(rec2)
    kept = detect_static(rec2, StaticSettings(keep_touches=True))

    assert len(after.intervals) == len(before.intervals)
    over = _poses_over(after, a, b)
    assert len(over) == 1
    pose = over[0]
    assert pose.stop <= piece.start + ring if end == "last" else pose.start >= piece.stop - ring
    assert after.exclusions[TOUCH_STRETCHES] >= 1 and after.exclusions[TOUCH] >= 0.8 * held
    shift_left_out = float(np.linalg.norm(pose.mean - rest.mean))
    with_touch = _poses_over(kept, a, b)
    assert len(with_touch) == 1 and TOUCH not in kept.exclusions
    shift_kept = float(np.linalg.norm(with_touch[0].mean - rest.mean))
    # joined, the touch moves the pose's mean by more than twice its standard error; left out, by less
    assert shift_kept > 2.0 * rest.sigma > shift_left_out, (shift_kept, rest.sigma, shift_left_out)


@pytest.mark.parametrize("name", ["threshold", "gyro_threshold", "drift_threshold"])
def test_a_huge_multiplier_accepts_without_overflow(name: str) -> None:
    """A multiplier of 1e308 makes every limit infinite (every stretch passes its test): no numpy overflow warning."""
    import warnings

    frame = pd.read_csv(need(XSENS))
    rec = recording_from_source(source_from_frame(frame, "xsens", "csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        seg = detect_static(rec, StaticSettings(**{name: 1e308}))
    assert len(seg.intervals) >= 1
