"""A still log's moves against its Allan deviation (``optcal allan``): a turn between rests and samples not at rest
that move σ(τ) beyond its uncertainty are refused with the --window that analyses the still part and the flag
that keeps them; a start-up transient is cut and counted; a stretch the rest model flags that is the noise's own is
kept; a still log's gyro unit from its noise density.  Generated logs: a 5-minute still IMU at 100 Hz (MPU-6050
noise: 2 mg, 0.05 °/s per sample), gravity along z."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from optcal.cli.main import main
from optcal.families.noise.disturbance import PLACEBOS, RELEVANT_SHARE, patched

RATE = 100.0


def still_log(path: Path, kind: str, gyro_deg: bool = True, seed: int = 1) -> Path:
    """A still log with ``kind``: "still", "turn" (90° about y at 150 s, kept), "turnback" (90° and back over 2 s),
    "transient" (the first 0.3 s ringing at 0.2 g, as a sensor's first samples after power-up)."""
    rng = np.random.default_rng(seed)
    n = int(300 * RATE)
    t = np.arange(n) / RATE
    ang = np.zeros(n)
    w = np.zeros(n)
    if kind in ("turn", "turnback"):
        i0 = int(150 * RATE)
        if kind == "turn":
            ang[i0:i0 + 200] = np.linspace(0, np.pi / 2, 200)
            ang[i0 + 200:] = np.pi / 2
        else:
            ang[i0:i0 + 200] = np.pi / 2 * np.sin(np.linspace(0, np.pi, 200))
        w = np.gradient(ang) * RATE
    acc = np.column_stack([np.sin(ang), np.zeros(n), np.cos(ang)]) + rng.normal(0, 0.002, (n, 3)) + [0.01, -0.02, 0.015]
    if kind == "transient":
        acc[:30] += 0.2 * rng.normal(size=(30, 3))
    gyro = np.column_stack([np.zeros(n), w, np.zeros(n)]) + rng.normal(0, np.radians(0.05), (n, 3)) + 0.005
    if gyro_deg:
        gyro = np.degrees(gyro)
    p = path / f"{kind}_{'deg' if gyro_deg else 'rad'}.csv"
    np.savetxt(p, np.column_stack([t, acc, gyro]), delimiter=",", header="t,ax,ay,az,gx,gy,gz", comments="", fmt="%.7f")
    return p


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("moves")
    return {k: still_log(d, k) for k in ("still", "turn", "turnback", "transient")}


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["allan", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_a_turn_between_two_rests_is_refused_naming_the_window_and_the_flag(logs, capsys) -> None:
    code, _, err = run(capsys, str(logs["turn"]), "--units", "g")
    assert code == 2
    assert "more than one orientation" in err and "--window 0:149.99" in err and "--keep-moves" in err
    assert len(err.strip().splitlines()[-1]) > 0 and "Traceback" not in err
    code, out, _ = run(capsys, str(logs["turn"]), "--units", "g", "--keep-moves")
    assert code == 0 and "kept with --keep-moves" in out


def test_a_turn_and_back_inside_one_rest_is_refused_and_its_still_part_read(logs, capsys) -> None:
    code, _, err = run(capsys, str(logs["turnback"]), "--units", "g")
    assert code == 2 and "the log moves" in err and "--window 0:149.99" in err
    code, out, _ = run(capsys, str(logs["turnback"]), "--units", "g", "--window", "0:149.99")
    assert code == 0 and "not at rest" not in out


def test_a_still_log_says_nothing_and_a_start_up_transient_is_cut_and_counted(logs, capsys) -> None:
    code, out, _ = run(capsys, str(logs["still"]), "--units", "g", "--json")
    assert code == 0
    assert "disturbances" not in json.loads(out)["log"]
    code, out, _ = run(capsys, str(logs["transient"]), "--units", "g", "--json")
    assert code == 0
    result = json.loads(out)
    cut = [v for k, v in result["log"]["exclusions"].items() if "start-up transient" in k]
    assert cut and 30 <= cut[0] <= 100  # the ringing samples and the rest model's block around them
    assert result["n_samples"] == int(300 * RATE) - cut[0] if "n_samples" in result else True


def test_samples_flagged_that_are_the_noises_own_are_kept_by_the_placebo_null() -> None:
    """Patching samples at rest (a rest model's false alarm, no disturbance) moves σ(τ) at long τ beyond the share
    of its interval by itself; the placebo null (19 draws: a one-sided 5 % level) keeps it in about 19 of 20 logs,
    while a step of 20 noise σ over 1 s is refused in every one."""
    from optcal.families.noise.allan import allan_deviation
    from optcal.families.noise.disturbance import disturbance_change

    beyond_share = refused = 0
    for seed in range(10):
        x = np.random.default_rng(seed).normal(0, 1.0, 6000)
        flagged = np.ones(6000, dtype=bool)
        flagged[3000:3100] = False
        quiet = disturbance_change(x[:, None], flagged, RATE, [allan_deviation(x, RATE)])
        beyond_share += quiet.ratio > RELEVANT_SHARE
        refused += quiet.relevant
        bumped = x.copy()
        bumped[3000:3100] += 20.0
        loud = disturbance_change(bumped[:, None], flagged, RATE, [allan_deviation(bumped, RATE)])
        assert loud.relevant and loud.placebo_ratios.size == PLACEBOS and loud.ratio > loud.placebo_ratios.max()
    assert refused <= 2  # binomial(10, 0.05): 3 or more has probability 1.2 %
    assert beyond_share >= 1  # the share alone would have refused noise (measured: 1 of these 10)


def test_patched_replaces_only_the_stretches_with_rest_at_the_local_level() -> None:
    x = np.arange(100, dtype=float) * 0.0 + 5.0
    x[40:50] = 50.0
    at_rest = np.ones(100, dtype=bool)
    at_rest[40:50] = False
    c = patched(x, at_rest, RATE)
    assert np.allclose(c[40:50], 5.0) and np.array_equal(c[:40], x[:40]) and np.array_equal(c[50:], x[50:])


@pytest.mark.parametrize(("deg", "unit"), [(True, "deg/s"), (False, "rad/s")])
def test_a_still_logs_gyro_unit_from_its_noise_density(tmp_path, capsys, deg: bool, unit: str) -> None:
    """An MPU-6050's 0.05 °/s per sample at 100 Hz is 0.005 °/s/√Hz: read as °/s when written in °/s, as rad/s
    when written in rad/s (the moves' peak-rate rule read both as rad/s: a still log has no moves)."""
    p = still_log(tmp_path, "still", gyro_deg=deg)
    code, out, _ = run(capsys, str(p), "--units", "g", "--sensor", "gyro", "--json")
    assert code == 0
    result = json.loads(out)
    assert result["log"]["units_reason"].startswith(f"{unit} from the still log's noise density")
    # the noise density in SI is the same whichever unit the file is written in: 0.05 °/s / √100 Hz
    assert result["kalibr"]["gyroscope_noise_density"] == pytest.approx(np.radians(0.05) / np.sqrt(RATE), rel=0.1)


def test_the_patched_curve_from_the_phases_running_sum_equals_its_full_recomputation() -> None:
    """disturbance_change sums again only the second differences a patch reaches; its change equals the Allan
    deviation of the patched series computed in full (``patched`` then ``overlapping_adev``), stretches at the start,
    inside and at the end."""
    from optcal.families.noise.allan import allan_deviation, overlapping_adev, phase_from_rate
    from optcal.families.noise.disturbance import disturbance_change

    x = np.random.default_rng(3).normal(0, 1.0, 6000)
    x[3000:3100] += 3.0
    at_rest = np.ones(6000, dtype=bool)
    at_rest[3000:3100] = at_rest[10:40] = at_rest[5950:] = False
    curve = allan_deviation(x, RATE)
    found = disturbance_change(x[:, None], at_rest, RATE, [curve])
    full, _ = overlapping_adev(phase_from_rate(patched(x, at_rest, RATE), RATE), RATE,
                               np.rint(curve.taus * RATE).astype(int))
    k = int(np.flatnonzero(curve.taus == found.tau)[0])
    assert found.change == pytest.approx(abs(full[k] - curve.adev[k]), rel=1e-9, abs=1e-12)
    assert found.ratio == pytest.approx(np.max(np.abs(full - curve.adev) / ((curve.ci_high - curve.ci_low) / 2)),
                                        rel=1e-9)


@pytest.mark.parametrize("piece", [7, 1000, None])
def test_the_phases_running_sum_at_a_few_points_equals_the_whole_column_sums_to_the_bit(monkeypatch, piece) -> None:
    """phase_prefix_at sums the log piece by piece, each sum carried into the next piece: the same numbers, to the
    bit, as the phase and its running sum over the whole column, at points inside, on and beside piece boundaries."""
    import optcal.families.noise.disturbance as disturbance
    from optcal.families.noise.allan import phase_from_rate

    if piece is not None:
        monkeypatch.setattr(disturbance, "PREFIX_PIECE", piece)
    rng = np.random.default_rng(4)
    x = rng.normal(0.0, 2e-3, 5001) + 1.0
    whole = np.concatenate([[0.0], np.cumsum(phase_from_rate(x, RATE))])
    points = np.unique(np.concatenate([[0, 1, 2, 999, 1000, 1001, 1002, 5000, 5001, 5002],
                                       rng.integers(0, x.size + 2, 300)]))
    assert np.array_equal(disturbance.phase_prefix_at(x, RATE, points), whole[points])
    # the carries worked out ahead (none, some, all of them): the pieces without points skipped, the same bits; a few
    # points far apart, so that most pieces are skipped
    sparse = np.array([0, 3, 1001, 4998, 5002])
    pieces = -(-x.size // disturbance.PREFIX_PIECE)
    for ahead in sorted({0, 1, pieces // 2, pieces}):
        carries = disturbance.PhaseCarries(x, RATE)
        assert carries.advance(ahead) == (ahead == pieces) == carries.done
        for at in (points, sparse):
            assert np.array_equal(disturbance.phase_prefix_at(x, RATE, at, carries), whole[at])
    # carries of another array (a cut of the log, a copy of it elsewhere in memory) are not taken for its own
    assert carries.of(x, RATE) and not carries.of(x[1:], RATE) and not carries.of(x.copy(), RATE)
    assert not carries.of(x, 2 * RATE)


def test_a_still_log_with_unusable_rows_is_analysed_and_they_are_counted(tmp_path, capsys) -> None:
    """A logger's unfilled buffer (all-zero rows, as sunsided's set-1 MPU-6050 log ends) is excluded while reading; the
    rest model's trace then has a value per usable row, and the start-up cut read it indexed by the usable rows a second
    time: an IndexError traceback (exit 1) on every such log.  Now analysed, the zero rows and the cut transient counted."""
    src = np.loadtxt(still_log(tmp_path, "transient"), delimiter=",", skiprows=1)
    t = np.arange(src.shape[0] + 300) / RATE
    rows = np.column_stack([t, np.vstack([src[:, 1:], np.zeros((300, 6))])])
    p = tmp_path / "zero_tail.csv"
    np.savetxt(p, rows, delimiter=",", header="t,ax,ay,az,gx,gy,gz", comments="", fmt="%.7f")
    code, out, err = run(capsys, str(p), "--units", "g", "--json")
    assert code == 0, err
    exclusions = json.loads(out)["log"]["exclusions"]
    assert [v for k, v in exclusions.items() if "all-zero rows" in k] == [300]
    cut = [v for k, v in exclusions.items() if "start-up transient" in k]
    assert cut and 30 <= cut[0] <= 100


def test_the_running_sums_carried_ahead_give_the_disturbance_checks_own_lines(logs, monkeypatch) -> None:
    """``carry_ahead`` works out the disturbance check's running sums while the stillness check runs (here one that
    never ends, so every sum is worked out); given them, the check's lines (the ratio to its last printed digit, the
    placebos drawn) are the ones it finds alone; a log cut by ``trim_unsettled`` does not take them.  Pieces of 1000
    samples, so that the 5-minute log has 30 and most are skipped."""
    from concurrent.futures import Future

    import optcal.families.noise.disturbance as disturbance

    from optcal.cli.cmd_allan import carry_ahead, check_disturbances, read_still_log
    from optcal.families.noise.analysis import analyse_static_log

    monkeypatch.setattr(disturbance, "PREFIX_PIECE", 1000)
    for kind, cut in (("turnback", False), ("transient", True)):
        log = read_still_log(str(logs[kind]), sensor="both", units="g")
        analyses = {"acc": analyse_static_log(log.samples, log.rate_hz, log.units, None, None)}
        pending: Future[None] = Future()
        segmentation, log.still = log.segmentation, pending
        carries = carry_ahead(log, analyses)
        log.still = None
        assert not pending.done() and [c.done for c in carries["acc"]] == [True] * 3
        assert bool(log.trim_unsettled()) == cut
        alone = check_disturbances(log, analyses, "log", True)
        assert check_disturbances(log, analyses, "log", True, carries) == alone and bool(alone) != cut
        assert all(c.of(log.samples[:, j], log.rate_hz) != cut for j, c in enumerate(carries["acc"]))
        assert segmentation is log.segmentation
