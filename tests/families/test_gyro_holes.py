"""Holes inside the moves of a gyro calibration (issue 26, item 6): bridged over the true time step when short.

A repeated timestamp (the data layer keeps the first sample) or a lost sample inside a move used to drop the whole
move; a recording with one in every move gave no move at all.  Now a short hole is integrated from the usable
sample before it to the one after it, and only a hole whose trapezoid error bound exceeds the move's angle random
walk drops the move, counted by reason.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import optcal
from helpers.cli_run import run_args
from optcal.core.poses import PoseTable
from optcal.data.units import GyroUnitsDecision
from optcal.errors import InputError
from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro, calibrate_imu_loaded
from optcal.families.gyro.moves import HOLE_MOVES, MoveSet, hole_bound, moves_from_arrays
from optcal.families.simulate.gyro import ImuRecording, reference_gyro, simulate_imu

RAD_S = GyroUnitsDecision("rad/s", "test")


@pytest.fixture(scope="module")
def recording() -> ImuRecording:
    """36 poses, 35 moves of 1.5 s at 100 Hz, noisy accelerometer and gyro."""
    return simulate_imu(optcal.lu2017_reference_model(), reference_gyro(1.0, rng=7), 36, rng=5, dwell_s=2.0,
                        move_s=1.5, acc_noise=0.002, gyro_noise=0.005)


def middle_samples(rec: ImuRecording) -> list[int]:
    """One sample in the middle of each move (its fastest turn)."""
    return [(a1 + b0) // 2 for (_, a1), (b0, _) in zip(rec.intervals[:-1], rec.intervals[1:])]


def repeated_stamps(rec: ImuRecording) -> tuple[np.ndarray, np.ndarray]:
    """The times with the stamp of a middle sample repeated on the next one, which the data layer excludes."""
    t = rec.t.copy()
    usable = np.ones(t.size, bool)
    for k in middle_samples(rec):
        t[k + 1] = t[k]
        usable[k + 1] = False
    return t, usable


def fit(rec: ImuRecording, moves: MoveSet):
    acc = optcal.calibrate(PoseTable(acc=moves.acc_means, sigma=moves.acc_sigma))
    return calibrate_gyro(moves, acc, RAD_S, GyroSettings())


def rate_error(cal, rec: ImuRecording) -> float:
    """Rms error of the corrected noise-free rate relative to the rms true rate, over the moving samples."""
    Q = rec.acc_model.T_canonical @ rec.acc_model.C
    mov = rec.moving
    est = cal.gyro.correct(rec.gyro_clean[mov])
    return float(np.sqrt(np.mean(np.sum((est - rec.omega[mov] @ Q.T) ** 2, axis=1))
                         / np.mean(np.sum(rec.omega[mov] ** 2, axis=1))))


def test_one_repeated_stamp_per_move_keeps_every_move(recording: ImuRecording) -> None:
    """35 moves with a repeated stamp each: all 35 bridged, the gyro as good as without the holes (0.26 % of the rate)."""
    clean = fit(recording, moves_from_arrays(recording.t, recording.acc, recording.gyro, recording.intervals))
    t, usable = repeated_stamps(recording)
    moves = moves_from_arrays(t, recording.acc, recording.gyro, recording.intervals, usable)
    assert moves.n_moves == 35 and moves.exclusions == {}
    assert moves.bridged_holes == 35 and moves.bridged_samples == 35
    holed = fit(recording, moves)
    assert rate_error(clean, recording) < 0.004 and rate_error(holed, recording) < 0.004
    se = np.sqrt(np.diag(clean.covariance))[:9]
    assert np.all(np.abs(holed.params[:9] - clean.params[:9]) < se)  # the holes move T_g by less than its standard error
    assert any("35 hole(s) inside the moves bridged" in note for note in holed.notes)


def test_repeated_stamps_through_the_command_line(recording: ImuRecording, tmp_path: Path, capsys) -> None:
    """The same recording as a file: the data layer excludes the 35 repeated stamps, --imu calibrates over 35 moves."""
    t, _ = repeated_stamps(recording)
    path = tmp_path / "repeated.csv"
    np.savetxt(path, np.column_stack([t, recording.acc, recording.gyro]), delimiter=",", comments="",
               header="t,ax,ay,az,gx,gy,gz", fmt="%.10g")
    code, out, err = run_args(capsys, "calibrate", str(path), "--imu")
    assert code == 0, err
    assert "samples with a repeated timestamp (the first one kept): 35" in out
    assert "moves              = 35" in out and "35 hole(s) inside the moves bridged" in out


def test_long_hole_drops_its_move_and_says_why(recording: ImuRecording) -> None:
    """A quarter of a second lost in the middle of one turn: that move is dropped and counted, the others kept."""
    usable = np.ones(recording.t.size, bool)
    k = middle_samples(recording)[3]
    usable[k - 12: k + 13] = False
    moves = moves_from_arrays(recording.t, recording.acc, recording.gyro, recording.intervals, usable)
    assert moves.n_moves == 34 and moves.exclusions == {HOLE_MOVES: 1}
    assert 3 not in moves.move_from


def test_too_few_moves_names_the_reason(recording: ImuRecording) -> None:
    usable = np.ones(recording.t.size, bool)
    for k in middle_samples(recording)[:31]:
        usable[k - 12: k + 13] = False
    with pytest.raises(InputError, match=r"only 4 usable move\(s\).*a hole \(lost or unusable samples\).*: 31"):
        moves_from_arrays(recording.t, recording.acc, recording.gyro, recording.intervals, usable)


def test_hole_bound_covers_the_trapezoid_error() -> None:
    """A smooth rate with holes of 1 to 5 lost samples: the bound is at least the trapezoid's error over the hole."""
    t = np.arange(400) * 0.01
    omega = np.column_stack([np.sin(2 * np.pi * 1.3 * t), 0.5 * np.cos(2 * np.pi * 0.7 * t), 0.2 * t**2])
    turned = np.column_stack([-np.cos(2 * np.pi * 1.3 * t) / (2 * np.pi * 1.3),
                              0.5 * np.sin(2 * np.pi * 0.7 * t) / (2 * np.pi * 0.7), 0.2 * t**3 / 3])
    for lost in range(1, 6):
        for start in range(50, 300, 17):
            idx = np.concatenate([np.arange(start + 1), np.arange(start + 1 + lost, 400)])
            a, b = start, start + 1 + lost
            error = np.linalg.norm((turned[b] - turned[a]) - 0.5 * (omega[a] + omega[b]) * (t[b] - t[a]))
            assert error <= hole_bound(t, omega, idx, start, 0.01) * (1 + 1e-9)


class Planted:
    """A real recording and a copy with a hole in the middle of every move, written as ``t,ax,ay,az,gx,gy,gz``.

    ``repeat``: the stamp of the middle sample given to the next one (the data layer drops that sample: a hole of
    one period); ``duplicate``: the middle row written twice (the copy dropped, no time lost).  ``intervals`` are
    the clean recording's static intervals in the copy's rows, so that both are compared over the same moves
    whatever the static detection makes of the copy.
    """

    def __init__(self, path: Path, out: Path, mode: str, **options: object) -> None:
        from optcal.data import load_with_segmentation

        self.clean = load_with_segmentation(str(path), **options)
        rec = self.clean.segmentation.recording
        ivs = np.array([(iv.start, iv.stop) for iv in self.clean.segmentation.intervals])
        middle = (ivs[:-1, 1] + ivs[1:, 0]) // 2
        rows = np.column_stack([rec.t, rec.acc, rec.gyro])
        if mode == "repeat":
            rows[middle + 1, 0] = rows[middle, 0]
            self.intervals = ivs
        else:
            rows = np.insert(rows, middle + 1, rows[middle], axis=0)
            self.intervals = ivs + np.searchsorted(middle, ivs, side="left")  # rows inserted before each bound
        np.savetxt(out, rows, delimiter=",", header="t,ax,ay,az,gx,gy,gz", comments="", fmt="%.10g")
        self.planted = load_with_segmentation(str(out))
        self.n_moves = len(ivs) - 1

    def moves(self, loaded, intervals) -> MoveSet:
        rec = loaded.segmentation.recording
        return moves_from_arrays(rec.t, rec.acc, rec.gyro, [tuple(iv) for iv in intervals], rec.usable)

    def fits(self, units: str):
        """The gyro calibrated over the same moves, without and with the holes (one accelerometer calibration)."""
        clean_ivs = [(iv.start, iv.stop) for iv in self.clean.segmentation.intervals]
        clean, holed = self.moves(self.clean, clean_ivs), self.moves(self.planted, self.intervals)
        acc = optcal.calibrate(PoseTable(acc=clean.acc_means, sigma=clean.acc_sigma))
        decision = GyroUnitsDecision(units, "test")
        return clean, holed, calibrate_gyro(clean, acc, decision), calibrate_gyro(holed, acc, decision)


@pytest.mark.parametrize("mode", ["repeat", "duplicate"])
def test_xsens_with_a_hole_in_every_move_still_calibrates(shared_data: Path, tmp_path: Path, mode: str) -> None:
    """imu_tk's Xsens log with one repeated stamp (or duplicated row) in each of its moves: every move kept, the
    gravity prediction and T_g as without them."""
    planted = Planted(shared_data / "imutk-xsens" / "xsens_imutk.csv", tmp_path / "xsens.csv", mode)
    rec = planted.planted.segmentation.recording
    assert sum(rec.exclusions.values()) == planted.n_moves  # the data layer dropped one sample per move
    whole = calibrate_imu_loaded(planted.planted)  # as the command line reads it
    assert whole.exclusions == {} and whole.angles_after_deg.size == len(planted.planted.segmentation.intervals) - 1
    clean_moves, holed_moves, clean, holed = planted.fits("counts")
    assert holed_moves.n_moves == clean_moves.n_moves == planted.n_moves
    assert holed_moves.bridged_holes == (planted.n_moves if mode == "repeat" else 0)
    assert abs(holed.rms_angle_after_deg - clean.rms_angle_after_deg) < 0.01
    # T_g as without them to 0.5 % of its scale (a dropped sample shifts the later blocks' edges by one
    # sample, and with them where a rest ends: the small cross-axis terms move by 1e-8 of a 2e-4 scale)
    assert np.allclose(holed.gyro.T, clean.gyro.T, rtol=0, atol=5e-3 * np.abs(clean.gyro.T).max())


def test_mikoff_with_a_repeated_stamp_in_every_move_still_calibrates(shared_data: Path, tmp_path: Path) -> None:
    """mikoff's MPU-9150 imu0, time written out at 100 Hz, one repeated stamp per move: at most one move in ten is
    dropped (a hole where the hand's turn bends sharply), counted by reason, and T_g is that of the clean log."""
    planted = Planted(shared_data / "mikoff-mpu9150" / "imu0.log", tmp_path / "imu0.csv", "repeat", rate=100)
    whole = calibrate_imu_loaded(planted.planted)
    kept = whole.angles_after_deg.size
    assert set(whole.exclusions) <= {HOLE_MOVES} and sum(whole.exclusions.values()) <= 0.1 * kept
    clean_moves, holed_moves, clean, holed = planted.fits("rad/s")
    assert holed_moves.n_moves >= 0.9 * planted.n_moves and planted.n_moves >= 20
    assert holed_moves.n_moves + sum(holed_moves.exclusions.values()) == planted.n_moves
    assert abs(holed.rms_angle_after_deg - clean.rms_angle_after_deg) < 0.1 * clean.rms_angle_after_deg
    assert np.allclose(holed.gyro.T, clean.gyro.T, atol=5e-3)
