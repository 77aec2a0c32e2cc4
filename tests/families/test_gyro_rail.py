"""A gyro at its rail (saturation): detected, counted, and its moves kept out of the gyro's fit.

A ±250 °/s gyro turned briskly holds its full scale while the turn is faster: the move's integrated rotation is
short by the rate beyond the rail, whatever the calibration, and such moves bias the gyro fit.  The data layer
finds the rail (:mod:`optcal.data.rails`), counts its samples in the reading's exclusions, keeps them out of the
rests, and the moves holding them are left out of the gyro fit (:data:`optcal.families.gyro.moves.RAIL_MOVES`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import optcal
from helpers.cli_run import run_args
from optcal.data.options import Reading, read
from optcal.data.rails import GYRO_RAIL_MIN_RUN, gyro_bias_bound, gyro_rail
from optcal.data.recording import GYRO_SATURATED
from optcal.families.gyro.estimator import calibrate_imu_loaded
from optcal.families.gyro.moves import RAIL_MOVES, moves_from_segmentation
from optcal.families.simulate.gyro import reference_gyro, simulate_imu

#: An MPU-6050's gyro at its smallest range, °/s.
FULL_SCALE_DEG_S = 250.0


def test_moves_clipped_at_250_deg_s_are_left_out_and_the_fit_is_unbiased(tmp_path: Path) -> None:
    """23 brisk moves (peaks 130-340 °/s) read by a ±250 °/s gyro in °/s.

    Kept (``keep_gyro_rail``), the clipped moves pull T_g by 5.5 of its standard errors (T_zz); left out, every
    entry of T_g is within 3 of them, and the moves left out are the ones whose true rate passed the rail.
    """
    truth = reference_gyro(np.degrees(1.0), rng=7)  # raw °/s
    rec = simulate_imu(optcal.lu2017_reference_model(), truth, 24, rng=5, dwell_s=2.0, move_s=0.8,
                       acc_noise=0.002, gyro_noise=0.05)
    bounds = [(a1, b0) for (_, a1), (b0, _) in zip(rec.intervals[:-1], rec.intervals[1:])]
    clipped_moves = sum(bool(np.any(np.abs(rec.gyro[a:b]) > FULL_SCALE_DEG_S)) for a, b in bounds)
    assert 0 < clipped_moves < len(bounds) - 6  # some moves clipped, enough left to fit
    gyro = np.clip(rec.gyro, -FULL_SCALE_DEG_S, FULL_SCALE_DEG_S)
    path = tmp_path / "clipped.csv"
    np.savetxt(path, np.column_stack([rec.t, rec.acc, gyro]), delimiter=",", comments="",
               header="t,ax,ay,az,gx,gy,gz", fmt="%.10g")
    Q = rec.acc_model.T_canonical @ rec.acc_model.C  # body → the true accelerometer's canonical frame
    expected = Q @ truth.T

    def z_scores(reading: Reading) -> tuple[np.ndarray, dict[str, int]]:
        cal = calibrate_imu_loaded(reading, gyro_units="deg/s")
        se = np.sqrt(np.diag(cal.covariance))[:9]
        return np.abs((cal.gyro.T - expected).ravel()) / se, cal.exclusions

    kept = read(path, keep_gyro_rail=True)
    assert GYRO_SATURATED not in kept.decisions.exclusions
    assert any("the gyro is at its rail" in w and "kept" in w for w in kept.decisions.warnings)
    z_kept, excl_kept = z_scores(kept)
    assert RAIL_MOVES not in excl_kept
    assert z_kept.max() > 3.0  # biased: T_zz 5.5 standard errors off

    left_out = read(path)
    n_rail = int(np.count_nonzero(np.any(np.abs(gyro) == FULL_SCALE_DEG_S, axis=1)))
    assert left_out.decisions.exclusions[GYRO_SATURATED] == n_rail
    assert left_out.recording is not None and left_out.recording.gyro_rail is not None
    assert left_out.recording.gyro_rail.levels == (FULL_SCALE_DEG_S,)
    z, excl = z_scores(left_out)
    assert excl[RAIL_MOVES] == clipped_moves
    assert z.max() < 3.0


@pytest.mark.usefixtures("shared_data")
def test_a_rail_planted_in_the_xsens_log_is_reported_and_its_moves_left_out(tmp_path: Path, capsys) -> None:
    """The Xsens log's gyro (unsigned counts) clipped, as a converter clips, at a rail a bit below the peak of its
    move that stays longest beyond what a rest reads: ``calibrate --imu --json`` counts the clipped samples, leaves
    out and counts the moves holding them, and fits the others."""
    from helpers.common import SHARED
    from optcal.data import load_with_segmentation

    src = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
    clean = load_with_segmentation(str(src))
    rec = clean.segmentation.recording
    assert rec.gyro is not None and rec.gyro_rail is None  # the log itself has no rail
    n_moves = moves_from_segmentation(clean.segmentation).n_moves
    zero, limit, _ = gyro_bias_bound(rec.gyro_units, rec.gyro)
    centre = np.median(rec.gyro, axis=0)
    ivs = [(iv.start, iv.stop) for iv in clean.segmentation.intervals]
    moves = [(a, b) for (_, a), (b, _) in zip(ivs[:-1], ivs[1:])]
    # the longest run of a move's samples beyond the bound a rest reads (from the zero and the median) on one axis
    beyond = (np.abs(rec.gyro - zero) > limit) & (np.abs(rec.gyro - centre) > limit)
    best: tuple[int, int, int] = (0, 0, 0)
    for a, b in moves:
        for axis in range(3):
            edges = np.flatnonzero(np.diff(np.concatenate(([0], beyond[a:b, axis].view(np.int8), [0]))))
            for start, stop in zip(edges[::2], edges[1::2]):
                best = max(best, (int(stop - start), a + int(start), axis))
    run, first, axis = best
    assert run >= GYRO_RAIL_MIN_RUN  # the log has a move that fast (6 samples over 19661 counts from the zero)
    level = float(np.min(np.abs(rec.gyro[first: first + run, axis] - zero[axis])))  # a bit below that move's peak
    data = np.loadtxt(src, delimiter=",", skiprows=1)
    data[:, 4:7] = np.clip(data[:, 4:7], zero - level, zero + level)  # every axis, both directions: a converter's rail
    at_rail = np.any(np.abs(data[:, 4:7] - zero) == level, axis=1)
    moves_at_rail = sum(bool(at_rail[a:b].any()) for a, b in moves)
    assert moves_at_rail >= 1
    path = tmp_path / "xsens_rail.csv"
    np.savetxt(path, data, delimiter=",", fmt=["%.6f"] + ["%d"] * 6, comments="",
               header="t_s,acc_x_counts,acc_y_counts,acc_z_counts,gyro_x_counts,gyro_y_counts,gyro_z_counts")
    code, out, err = run_args(capsys, "calibrate", str(path), "--imu", "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["data"]["exclusions"][GYRO_SATURATED] == int(np.count_nonzero(at_rail))
    assert result["gyro_fit"]["exclusions"] == {RAIL_MOVES: moves_at_rail}
    assert result["gravity_prediction"]["n_moves"] == n_moves - moves_at_rail
    assert any("the gyro is at its rail" in w for w in result["data"]["decisions"]["warnings"])


@pytest.mark.usefixtures("shared_data")
def test_the_mpu6050_examples_gyro_at_its_int16_rail_is_counted_and_the_rests_kept() -> None:
    """The shared MPU-6050 example (int16 counts at the default ±250 °/s) reaches its gyro's full scale in brisk
    moves: those samples are counted, the moves holding them left out, and the accelerometer's poses are the ones
    read with ``--keep-gyro-rail`` (the rail samples lie in moves)."""
    from helpers.common import SHARED

    src = SHARED / "data" / "mpu6050-imucalibration" / "example_data_calibration.csv"
    reading, kept = read(src), read(src, keep_gyro_rail=True)
    assert reading.recording is not None and reading.recording.gyro is not None and reading.segmentation is not None
    gyro = reading.recording.gyro
    at_rail = np.any((gyro == -32768) | (gyro == 32767), axis=1)
    assert reading.decisions.exclusions[GYRO_SATURATED] == int(np.count_nonzero(at_rail)) > 0
    np.testing.assert_array_equal(reading.poses.acc, kept.poses.acc)
    ivs = [(iv.start, iv.stop) for iv in reading.segmentation.intervals]
    holding = sum(bool(at_rail[a:b].any()) for (_, a), (b, _) in zip(ivs[:-1], ivs[1:]))
    assert holding > 0
    assert moves_from_segmentation(reading.segmentation).exclusions[RAIL_MOVES] == holding
    assert kept.segmentation is not None and RAIL_MOVES not in moves_from_segmentation(kept.segmentation).exclusions


def test_a_still_stretch_with_the_gyro_at_its_rail_is_no_rest(tmp_path: Path) -> None:
    """A 10-s rest, a tilt, then 20 s of a spin about the vertical held at a ±2000 °/s gyro's rail (the accelerometer
    still at 1 g): with the gyro not taken as evidence of motion (``--no-gyro-gate``) the spin passed as a second pose;
    its rail now rejects it, and ``--keep-gyro-rail`` gives the two poses back."""
    from optcal.data.static import RAIL_STRETCHES

    rng = np.random.default_rng(1)
    g, rate_hz, rail = 9.81, 100.0, np.radians(2000.0)
    tilt = np.linspace(0.0, np.pi / 2, 200)  # z up -> x up, turning about y in 2 s
    acc = np.concatenate([np.tile([0.0, 0.0, g], (1000, 1)),
                          np.column_stack([g * np.sin(tilt), 0 * tilt, g * np.cos(tilt)]),
                          np.tile([g, 0.0, 0.0], (2000, 1))]) + 0.02 * rng.standard_normal((3200, 3))
    gyro = 0.005 * rng.standard_normal((3200, 3))
    gyro[1000:1200, 1] += (np.pi / 2) / 2.0
    gyro[1200:, 0] = rail  # spinning about x, the vertical: the gyro held at its full scale
    path = tmp_path / "spin_at_rail.csv"
    np.savetxt(path, np.column_stack([np.arange(3200) / rate_hz, acc, gyro]), delimiter=",", comments="",
               header="t,ax,ay,az,gx,gy,gz", fmt="%.6f")
    kept = read(path, use_gyro=False, gyro_units="rad/s", keep_gyro_rail=True)
    assert kept.poses.n == 2
    reading = read(path, use_gyro=False, gyro_units="rad/s")
    assert reading.decisions.exclusions[GYRO_SATURATED] == 2000
    assert reading.poses.n == 1 and reading.poses.exclusions[RAIL_STRETCHES] == 1
    np.testing.assert_allclose(reading.poses.acc[0], kept.poses.acc[0])  # the true rest is kept


@pytest.mark.parametrize("still", [False, True], ids=["rail in moves", "rail in a still stretch"])
def test_every_sample_is_counted_once_with_the_gyro_at_its_rail(tmp_path: Path, still: bool) -> None:
    """The samples at the gyro's rail are counted while reading (their cause); the segmentation's counts (moves,
    edges, stretches rejected) are of the other samples, so the samples excluded and those in poses sum to the
    rows (they were counted twice: in the reading's count and again as moving or as the rejected stretch's)."""
    from optcal.data.static import MOVING, RAIL_STRETCHES

    if still:  # a rest, a tilt, then a spin about the vertical held at a ±2000 °/s gyro's rail
        rng = np.random.default_rng(1)
        tilt = np.linspace(0.0, np.pi / 2, 200)
        acc = np.concatenate([np.tile([0.0, 0.0, 9.81], (1000, 1)),
                              np.column_stack([9.81 * np.sin(tilt), 0 * tilt, 9.81 * np.cos(tilt)]),
                              np.tile([9.81, 0.0, 0.0], (2000, 1))]) + 0.02 * rng.standard_normal((3200, 3))
        gyro = 0.005 * rng.standard_normal((3200, 3))
        gyro[1000:1200, 1] += (np.pi / 2) / 2.0
        gyro[1200:, 0] = np.radians(2000.0)
        t, units = np.arange(3200) / 100.0, "rad/s"
    else:  # brisk moves between rests read by a ±250 °/s gyro
        rec = simulate_imu(optcal.lu2017_reference_model(), reference_gyro(np.degrees(1.0), rng=7), 12, rng=5,
                           dwell_s=2.0, move_s=0.8, acc_noise=0.002, gyro_noise=0.05)
        t, acc, units = rec.t, rec.acc, "deg/s"
        gyro = np.clip(rec.gyro, -FULL_SCALE_DEG_S, FULL_SCALE_DEG_S)
    path = tmp_path / "rail.csv"
    np.savetxt(path, np.column_stack([t, acc, gyro]), delimiter=",", comments="", header="t,ax,ay,az,gx,gy,gz",
               fmt="%.8g")
    for keep in (True, False):
        reading = read(path, use_gyro=not still, gyro_units=units, keep_gyro_rail=keep)
        seg = reading.segmentation
        assert seg is not None
        samples = {k: v for k, v in seg.exclusions.items() if k.startswith("samples")}
        assert sum(samples.values()) + seg.n_used == len(t), samples
        assert (GYRO_SATURATED in samples) is not keep
    if still:  # the stretch is rejected (every sample of it at the rail: none left to count as the stretch's)
        assert seg.exclusions[RAIL_STRETCHES] == 1 and samples[GYRO_SATURATED] == 2000
    else:
        assert samples[MOVING] > 0  # the moves' other samples, still counted


def test_a_smooth_peak_of_a_fast_log_is_no_rail_and_a_clipped_one_is() -> None:
    """A 1 kHz log of a ±2000 °/s 16-bit gyro (a step of 1/16.4 °/s, noise a third of it): a 0.5-s turn peaking at
    300 °/s holds its top for 4 equal samples (a peak of curvature c stays within one step q for √(8q/c) samples,
    6.5 here), which the 3-sample rule took for a rail; the same turn clipped at 290 °/s holds it for 83."""
    rng = np.random.default_rng(3)
    q = 1.0 / 16.4
    gyro = 0.3 * q * rng.standard_normal((6000, 3))
    turn = np.sin(np.pi * np.arange(500) / 500)
    gyro[2000:2500, 2] += 300.0 * turn
    gyro[4000:4500, 0] -= 280.0 * turn
    smooth = np.round(gyro / q) * q
    assert np.count_nonzero(smooth[:, 2] == smooth[:, 2].max()) >= GYRO_RAIL_MIN_RUN  # what the run rule saw
    assert not gyro_rail(smooth, np.ones(6000, bool), "deg/s").samples.any()
    clipped = np.round(np.clip(gyro, -290.0, 290.0) / q) * q
    rail = gyro_rail(clipped, np.ones(6000, bool), "deg/s")
    assert np.array_equal(rail.samples, np.abs(clipped[:, 2]) == clipped[:, 2].max())
    assert rail.levels == (pytest.approx(290.0, abs=q),)


#: A 12-bit converter's codes (a logger keeping the top 12 bits of an int16, ``gx >> 4``).
CODES_12_BIT: tuple[float, float] = (-2048.0, 2047.0)


def test_a_stated_full_scale_finds_a_rail_near_the_zero_of_a_counts_gyro(tmp_path: Path) -> None:
    """A ±250 °/s gyro read in 12-bit counts (8.19 per °/s): its rail, ±2048 counts, lies within the 19661 counts
    (75 °/s of the finest 16-bit gyro) that bound a rail of a counts gyro of unknown scale, so it was not found;
    ``--gyro-range 250`` makes the bound 75/250 of the largest reading (614 counts) and finds exactly the clipped
    samples.  The control: the same stated range on the log's first rest alone (a still log) finds none."""
    truth = reference_gyro(np.degrees(1.0), rng=7)
    rec = simulate_imu(optcal.lu2017_reference_model(), truth, 24, rng=5, dwell_s=2.0, move_s=0.8,
                       acc_noise=0.002, gyro_noise=0.05)
    counts = np.clip(np.round(rec.gyro * (2048.0 / FULL_SCALE_DEG_S)), *CODES_12_BIT)
    n_rail = int(np.count_nonzero(np.any(np.isin(counts, CODES_12_BIT), axis=1)))
    assert n_rail > 0
    path = tmp_path / "counts12.csv"
    np.savetxt(path, np.column_stack([rec.t, rec.acc, counts]), delimiter=",", comments="",
               header="t,ax,ay,az,gx,gy,gz", fmt="%.10g")
    unstated = optcal.data.load_recording(path)
    assert unstated.gyro_rail is None and GYRO_SATURATED not in unstated.exclusions
    stated = optcal.data.load_recording(path, gyro_range_dps=FULL_SCALE_DEG_S)
    assert stated.gyro_rail is not None and int(np.count_nonzero(stated.gyro_rail.samples)) == n_rail
    assert stated.gyro_rail.levels == (2047.0, 2048.0)
    assert stated.exclusions[GYRO_SATURATED] == n_rail
    assert any("--gyro-range" in w and "the gyro is at its rail" in w for w in stated.decisions.warnings)
    a, b = rec.intervals[0]
    still = tmp_path / "still.csv"
    np.savetxt(still, np.column_stack([rec.t, rec.acc, counts])[a:b], delimiter=",", comments="",
               header="t,ax,ay,az,gx,gy,gz", fmt="%.10g")
    quiet = optcal.data.load_recording(still, gyro_range_dps=FULL_SCALE_DEG_S)
    assert quiet.gyro_rail is None and GYRO_SATURATED not in quiet.exclusions
    assert any("no gyro rail found" in w and "not used" in w for w in quiet.decisions.warnings)
