"""Allan deviation and noise parameters (Yin 2014, section 2.2) against simulated truth."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from optcal.cli.main import main
from optcal.errors import InputError
from optcal.core.model import STANDARD_GRAVITY
from optcal.families.noise.allan import (
    FLICKER_FACTOR,
    MIN_CLUSTERS,
    allan_deviation,
    analyse_static_log,
    fit_noise_parameters,
    octave_taus,
    plot_allan,
    si_per_unit,
    simulate_noise,
)

RATE = 100.0
#: Truth of the long log (g units): N in g·√s, B in g, K in g/√s.
N_TRUE, B_TRUE, K_TRUE = 200e-6, 100e-6, 10e-6


@pytest.fixture(scope="module")
def long_log() -> np.ndarray:
    """12 h at 100 Hz (4.32 million samples), three axes with the same truth."""
    rng = np.random.default_rng(20140701)
    n = int(12 * 3600 * RATE)
    return np.column_stack([simulate_noise(n, RATE, N_TRUE, B_TRUE, K_TRUE, rng) for _ in range(3)])


@pytest.fixture(scope="module")
def long_analysis(long_log: np.ndarray):
    return analyse_static_log(long_log, RATE, "g")


def test_twelve_hour_log_recovers_the_three_noise_parameters(long_analysis) -> None:
    # acceptance of issue 5: VRW and BI within 10 %, RRW within 25 % (12 h, 100 Hz)
    for axis, p in long_analysis.parameters.items():
        assert p.velocity_random_walk == pytest.approx(N_TRUE, rel=0.10), axis
        assert not p.bias_instability_bound
        assert p.bias_instability == pytest.approx(B_TRUE, rel=0.10), axis
        assert p.rate_random_walk is not None
        assert p.rate_random_walk == pytest.approx(K_TRUE, rel=0.25), axis


def test_paper_minimum_reading_overstates_bias_instability_where_terms_overlap(long_analysis) -> None:
    # σ_min/0.664 includes the white and random-walk contributions at the minimum; the fit removes them
    for p in long_analysis.parameters.values():
        assert p.min_reading > 1.1 * B_TRUE
        assert abs(p.bias_instability / B_TRUE - 1) < abs(p.min_reading / B_TRUE - 1)


def test_taus_are_octaves_leaving_nine_clusters(long_analysis, long_log: np.ndarray) -> None:
    curve = long_analysis.curves["x"]
    m = np.rint(curve.taus * RATE)
    assert np.all(m == 2.0 ** np.arange(m.size))
    assert long_log.shape[0] // m[-1] >= MIN_CLUSTERS
    assert long_log.shape[0] // (2 * m[-1]) < MIN_CLUSTERS


def test_confidence_intervals_cover_the_white_noise_truth() -> None:
    # white noise of per-sample σ: σ(τ) = σ/√m exactly; the 68 % intervals must cover it about 68 % of the time
    rng = np.random.default_rng(7)
    sigma = 0.01
    hits, total = 0, 0
    for _ in range(20):
        curve = allan_deviation(rng.standard_normal(50_000) * sigma, RATE)
        truth = sigma / np.sqrt(np.rint(curve.taus * RATE))
        hits += int(np.sum((curve.ci_low <= truth) & (truth <= curve.ci_high)))
        total += truth.size
        assert np.all(curve.ci_low < curve.adev) and np.all(curve.adev < curve.ci_high)
        assert np.all(curve.alpha[:8] == 0)  # identified as white frequency noise
    assert 0.55 < hits / total < 0.82


def test_generator_levels_match_the_allan_relations() -> None:
    rng = np.random.default_rng(11)
    n = int(3 * 3600 * RATE)
    flicker = allan_deviation(simulate_noise(n, RATE, 1e-9, bias_instability=1.0, rng=rng), RATE)
    mid = (flicker.taus > 1) & (flicker.taus < 300)
    assert np.median(flicker.adev[mid]) == pytest.approx(FLICKER_FACTOR, rel=0.05)  # σ = 0.664 B
    walk = allan_deviation(simulate_noise(n, RATE, 1e-9, rate_random_walk=1.0, rng=rng), RATE)
    big = walk.taus > 10
    assert np.median(walk.adev[big] / np.sqrt(walk.taus[big] / 3)) == pytest.approx(1.0, rel=0.15)  # K √(τ/3)


def test_white_noise_only_reports_absent_terms_without_nan() -> None:
    rng = np.random.default_rng(3)
    y = rng.standard_normal(int(600 * RATE)) * 0.004  # N = 0.004/√100 = 4e-4 g√s
    p = fit_noise_parameters(allan_deviation(y, RATE))
    assert p.velocity_random_walk == pytest.approx(4e-4, rel=0.02)
    assert p.rate_random_walk is None and p.ci["rate_random_walk"] is None
    assert p.bias_instability_bound and p.bias_instability == pytest.approx(p.min_reading)
    assert any("upper bound" in n for n in p.notes)
    assert all(math.isfinite(v) for v in (p.velocity_random_walk, p.bias_instability, p.correlation_time_s))


def test_units_convert_to_si_whatever_the_input_units() -> None:
    rng = np.random.default_rng(5)
    g_log = np.column_stack([simulate_noise(60_000, RATE, 3e-4, 5e-5, 0.0, rng) for _ in range(3)])
    in_g = analyse_static_log(g_log, RATE, "g").summary()
    in_ms2 = analyse_static_log(g_log * STANDARD_GRAVITY, RATE, "m/s^2").summary()
    in_counts = analyse_static_log(g_log * 16384.0, RATE, "counts", counts_per_g=16384.0).summary()
    for axis in "xyz":
        for other in (in_ms2, in_counts):
            assert other[axis]["velocity_random_walk"] == pytest.approx(in_g[axis]["velocity_random_walk"], rel=1e-9)
            assert other[axis]["bias_instability"] == pytest.approx(in_g[axis]["bias_instability"], rel=1e-9)
        assert in_g[axis]["velocity_random_walk"] == pytest.approx(3e-4 * STANDARD_GRAVITY, rel=0.05)
    assert si_per_unit("m/s^2") == 1.0 and si_per_unit("g") == STANDARD_GRAVITY
    assert in_g["units"]["velocity_random_walk"] == "m/s/√s"
    json.dumps(in_g, allow_nan=False)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: octave_taus(800, RATE), "needs at least 9 clusters"),
        (lambda: octave_taus(10_000, RATE, max_tau_s=20.0), "τ = 20 s needs at least 9 clusters"),
        (lambda: allan_deviation(np.r_[np.zeros(5000), np.nan], RATE), "NaN"),
        (lambda: allan_deviation(np.ones(5000), RATE), "constant"),
        (lambda: si_per_unit("counts"), "counts-per-g"),
        (lambda: analyse_static_log(np.zeros((5000, 2)), RATE, "g"), "three columns"),
    ],
)
def test_bad_input_is_refused_with_a_reason(call, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call()


def _write_log(path, data: np.ndarray, rate: float = RATE) -> None:
    lines = [f"Fs,{rate:g}", "ax,ay,az"] + [f"{x:.7f},{y:.7f},{z:.7f}" for x, y, z in data]
    path.write_text("\n".join(lines) + "\n")


def test_cli_prints_one_json_object_in_si_units(tmp_path, capsys) -> None:
    rng = np.random.default_rng(9)
    data = np.column_stack([simulate_noise(30_000, RATE, 3e-4, 5e-5, 0.0, rng) for _ in range(3)]) + [0, 0, 1]
    f = tmp_path / "static.csv"
    _write_log(f, data)
    png = tmp_path / "allan.png"
    assert main(["allan", str(f), "--units", "g", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"units", "x", "y", "z"}
    for axis in "xyz":
        a = out[axis]
        assert set(a) >= {"velocity_random_walk", "bias_instability", "rate_random_walk", "ci"}
        assert a["velocity_random_walk"] == pytest.approx(3e-4 * STANDARD_GRAVITY, rel=0.05)
        assert isinstance(a["bias_instability"], float)
    assert png.stat().st_size > 10_000


def test_cli_short_log_and_missing_scale_exit_2(tmp_path, capsys) -> None:
    f = tmp_path / "short.csv"
    _write_log(f, np.random.default_rng(1).standard_normal((500, 3)) * 0.01 + [0, 0, 1])
    assert main(["allan", str(f), "--units", "g"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "9 clusters" in err and "longer" in err
    counts = tmp_path / "counts.csv"
    _write_log(counts, np.round(np.random.default_rng(2).standard_normal((2000, 3)) * 60 + [0, 0, 16384]))
    assert main(["allan", str(counts), "--units", "counts"]) == 2
    assert "--counts-per-g" in capsys.readouterr().err


def test_real_mpu6050_static_log(shared_data, tmp_path) -> None:
    from optcal.cli.cmd_allan import static_log

    path = shared_data / "mpu6050-imucalibration" / "example_data_tinit_calc.csv"
    samples, rate, units, _, excluded = static_log(str(path), None, None, None, None)
    assert units == "counts" and rate == pytest.approx(100.0) and not excluded
    analysis = analyse_static_log(samples, rate, units, counts_per_g=16384.0)
    si = analysis.si_parameters()
    for p in si.values():
        # MPU-6050 datasheet: 400 µg/√Hz; a 449 s log cannot resolve the flat region
        vrw_ug = p.velocity_random_walk / STANDARD_GRAVITY * 1e6
        assert 150 < vrw_ug < 800
        assert p.bias_instability_bound and p.rate_random_walk is None
    plot_allan(analysis, tmp_path / "real.png")


def test_cli_refuses_a_log_with_a_gap(tmp_path, capsys) -> None:
    rng = np.random.default_rng(12)
    t = np.arange(3000) / RATE
    t[1500:] += 5.0  # five seconds missing
    data = rng.standard_normal((3000, 3)) * 0.003 + [0, 0, 1]
    f = tmp_path / "gap.csv"
    f.write_text("t_s,ax,ay,az\n" + "\n".join(f"{ti:.3f},{x:.6f},{y:.6f},{z:.6f}" for ti, (x, y, z) in zip(t, data)) + "\n")
    assert main(["allan", str(f), "--units", "g"]) == 2
    assert "gap of 5.01 s" in capsys.readouterr().err
