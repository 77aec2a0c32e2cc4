"""A magnetometer's isolated spikes (a bus glitch, a torn register read, a motor's pulse): the fit had no outlier
handling, and AlexMinhao/MagnetometerCali's ``M1.csv`` had two one-row spikes of |m| ≈ 152 µT that set its rms (15.5 %
against 7 % without them).  Now a run of one to three rows that leaves both neighbours by more than a turning field
moves, with a second difference beyond the Bonferroni bound of its robust scale, is left out of every command's
samples, counted and said (:mod:`optcal.families.mag.spikes`); ``--keep-mag-spikes`` keeps them."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cli_run import run_args
from optcal.families.mag.samples import read_mag
from optcal.families.mag.spikes import SPIKE_ROWS, find_spikes

#: AK8963's 16-bit step, µT.
STEP_UT = 0.15
#: A hard iron, µT.
HARD_IRON = np.array([10.0, -5.0, 3.0])


def _turning_field(t: np.ndarray, rate: float = 0.7) -> np.ndarray:
    """A 45-µT field seen by a sensor turning at ``rate`` rad/s about a wandering axis, plus :data:`HARD_IRON`."""
    az, el = rate * t, 0.9 * np.sin(0.23 * t)
    return 45.0 * np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]) + HARD_IRON


def _quantised(m: np.ndarray, noise: float, seed: int) -> np.ndarray:
    return np.round((m + np.random.default_rng(seed).normal(0, noise, m.shape)) / STEP_UT) * STEP_UT


def _write(path, t: np.ndarray | None, m: np.ndarray) -> None:
    rows, header = (m, "mag_x_uT,mag_y_uT,mag_z_uT") if t is None else (np.column_stack([t, m]),
                                                                        "t,mag_x_uT,mag_y_uT,mag_z_uT")
    np.savetxt(path, rows, delimiter=",", header=header, comments="", fmt="%.6f")


#: Planted glitches: (first row, rows, the offset of each row from the field, µT).  A one-axis jump of 25 µT (half
#: the field; at 100 Hz a turn at 10 rad/s moves about 5 µT in two periods), M1's +150 µT on x and −150 µT on z, a
#: torn read of all axes, and runs of two rows (one value repeated, as a register stuck for a read) and of three
#: (values that differ).
SPIKES = ((300, 1, [[25.0, 0, 0]]), (900, 1, [[150.0, 0, 0]]), (1500, 1, [[0, 0, -150.0]]),
          (2100, 1, [[-30.0, 40.0, 20.0]]), (2700, 2, [[0, 60.0, 0], [0, 60.0, 0]]),
          (3300, 3, [[80.0, 0, 0], [70.0, 10.0, 0], [90.0, 0, -10.0]]))


@pytest.mark.parametrize("timed", [True, False])
def test_spikes_planted_in_a_turning_field_are_found_exactly(tmp_path, timed):
    t = np.arange(4000) / 100.0
    m = _quantised(_turning_field(t), 0.3, 1)
    planted = []
    for start, k, offsets in SPIKES:
        m[start:start + k] += offsets
        planted += range(start, start + k)
    if not timed:  # without a time column only departures beyond the field's diameter (about 100 µT here) count
        planted = [r for s, k, o in SPIKES for r in range(s, s + k) if min(np.linalg.norm(o, axis=1)) > 100]
    path = tmp_path / "spiky.csv"
    _write(path, t if timed else None, m)
    s = read_mag(path)
    assert s.exclusions.get(SPIKE_ROWS, 0) == len(planted)
    np.testing.assert_allclose(s.m, np.delete(m, planted, axis=0), atol=1e-9)
    line = next(x for x in s.notes if "spikes" in x)
    assert line.endswith("left out (--keep-mag-spikes keeps them)") and ("no time column" in line) != timed
    if timed:
        assert "4 single rows, 1 runs of 2 rows, 1 runs of 3 rows" in line
    kept = read_mag(path, keep_spikes=True)
    assert kept.n == 4000 and SPIKE_ROWS not in kept.exclusions and "kept (--keep-mag-spikes)" in kept.notes[-1]


def test_a_run_of_four_glitched_rows_is_not_sought():
    """Four rows are a disturbance's length, not a read fault's (:data:`MAX_SPIKE_ROWS`): left to the diagnosis."""
    t = np.arange(2000) / 100.0
    m = _quantised(_turning_field(t), 0.3, 2)
    m[1000:1004] += [0, 0, 150.0]
    assert find_spikes(m, t).n == 0


@pytest.mark.parametrize("rate_hz", [100.0, 25.0])
def test_a_hands_fastest_turn_is_no_spike(rate_hz):
    """10 rad/s, a wrist's flick, at the logger's rate: the field sweeps 0.1 rad (100 Hz) or 0.4 rad (25 Hz) a
    sample, its second difference far beyond the noise's, yet no sample leaves its neighbours by more than a turn."""
    t = np.arange(int(20 * rate_hz)) / rate_hz
    m = _quantised(_turning_field(t, rate=10.0), 0.3, 3)
    assert find_spikes(m, t).n == 0 and find_spikes(m).n == 0
    # the same turn broken by still stretches: the turns' second differences are then outliers of the log's scale
    turned = np.floor(t / 4) + np.maximum(t % 4 - 3, 0.0)  # seconds of turning: 1 s in every 4
    m = _quantised(_turning_field(turned, rate=10.0), 0.3, 4)
    assert find_spikes(m, t).n == 0 and find_spikes(m).n == 0


@pytest.mark.parametrize("noise_steps", [0.15, 0.3, 1.0, 3.0])
def test_a_still_magnetometers_quantised_noise_is_no_spike(noise_steps):
    t = np.arange(20000) / 100.0
    m = _quantised(np.tile([30.0, -12.0, 40.0], (t.size, 1)), noise_steps * STEP_UT, 5)
    assert find_spikes(m, t).n == 0 and find_spikes(m).n == 0


def test_spikes_planted_in_a_real_recording_are_found_and_every_command_has_the_flag(shared_data, tmp_path, capsys):
    """ckexplorer's handheld turns (an LSM303's gauss, no time column): three glitches beyond the field's diameter
    planted, found exactly, and the flag kept and refused as the other magnetometer flags."""
    src = shared_data / "ckexplorer-holds" / "acc_mag_log.csv"
    header = src.read_text().splitlines()[0]
    data = np.loadtxt(src, delimiter=",", skiprows=1)
    assert header == "ax,ay,az,mx,my,mz"
    rows = [2000, 5000, 9000]
    data[rows[0], 3] += 3.0
    data[rows[1], 5] -= 2.5
    data[rows[2], 3:6] += [1.5, -1.5, 1.5]
    path = tmp_path / "glitched.csv"
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.6g")
    s = read_mag(path)
    original = read_mag(src)
    assert s.exclusions[SPIKE_ROWS] == 3 and SPIKE_ROWS not in original.exclusions
    np.testing.assert_allclose(s.m, original.m[[i for i in range(original.n) if i not in rows]], rtol=1e-5)
    path = tmp_path / "glitched_part.csv"  # the commands on the first 6000 rows (2 spikes): seconds, not ten
    np.savetxt(path, data[:6000], delimiter=",", header=header, comments="", fmt="%.6g")
    cal = tmp_path / "cal.json"
    code, out, _ = run_args(capsys, "calibrate", path, "--sensor", "mag", "--mag-form", "offsets", "-o", cal)
    assert code == 0 and "excluded: 2 magnetometer samples that are spikes" in out
    kept = "2 magnetometer samples are spikes (2 single rows)"
    for argv in (("calibrate", path, "--sensor", "mag", "--mag-form", "offsets"), ("check", cal, path),
                 ("plan", "--sensor", "mag", "--next", path), ("diagnose", path, "--sensor", "mag"),
                 ("apply", cal, path, "-o", tmp_path / "out.csv")):
        code, out, err = run_args(capsys, *argv, "--keep-mag-spikes")
        assert code == 0 and kept in out and "kept (--keep-mag-spikes)" in out, (argv, err)
    code, _, err = run_args(capsys, "calibrate", path, "--keep-mag-spikes")
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: ") and "--keep-mag-spikes" in err
    assert err.strip().endswith("apply with --sensor mag")
