"""Sun & Cao 2011: turntable simulator, alignment filter, ten-position scheme, reproduction.

Reference data: Sun, Cao 2011, Systems Engineering and Electronics 33(10), eq. 14 and
Tables 2-4 (set values 0.978e-3 m/s² and 2.909e-5 rad; the paper's single-run estimates).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from optcal.applications.papers.sun2011.alignment import FilterTuning, align, discretise, error_dynamics
from optcal.cli.main import main
from optcal.errors import InputError
from optcal.core.identifiability import analyse_design
from optcal.core.model import LumpedModel
from optcal.core.rotations import turntable_attitude
from optcal.applications.papers.sun2011.reproduce import _BUDGET_OFF, PAPER_TABLE2, PAPER_TABLE3, run
from optcal.applications.papers.sun2011.tenposition import (
    coupling_bias,
    decoupled_estimate,
    error_rates,
    joint_estimate,
    least_squares,
    misalignment_design,
    path_coefficients,
    path_estimates,
    run_scheme,
    step1_closed_form,
    step2_closed_form,
    step3_closed_form,
    step4_closed_form,
)
from optcal.applications.papers.sun2011.turntable import (
    PARAM_NAMES,
    AccelerometerErrors,
    SimulationSettings,
    TurntableRun,
    ten_position_scheme,
)

G = 9.78


def random_parameters(rng: np.random.Generator) -> np.ndarray:
    p = rng.normal(0.0, 1e-3, 9)
    p[3:] /= G
    return p


@pytest.fixture(scope="module")
def mc() -> tuple[TurntableRun, FilterTuning, object]:
    """One vectorised Monte Carlo of the scheme (200 runs, well under a second)."""
    s = SimulationSettings()
    tuning = FilterTuning.paper(s.gravity)
    session = TurntableRun.start(s, 200, seed=11)
    return session, tuning, run_scheme(session, tuning)


# ------------------------------------------------------------------ conventions, eq. 1-3, 14


@pytest.mark.parametrize("beta_deg", [-45.0, 20.0, 45.0, 60.0])
def test_turntable_attitude_reproduces_eq14(beta_deg: float) -> None:
    b = np.deg2rad(beta_deg)
    s, c = np.sin(b), np.cos(b)
    t1 = np.array([[s, 0, c], [c, 0, -s], [0, 1, 0]])
    t2 = np.array([[-s, 0, c], [-c, 0, -s], [0, -1, 0]])
    np.testing.assert_allclose(turntable_attitude(np.pi / 2, np.pi / 2, b), t1, atol=1e-15)
    np.testing.assert_allclose(turntable_attitude(-np.pi / 2, np.pi / 2, b), t2, atol=1e-15)


def test_set_values_are_those_of_tables_2_and_3() -> None:
    v = SimulationSettings().set_errors().values
    np.testing.assert_allclose(v[:3], 0.978e-3, rtol=1e-4)  # Table 2, set value
    np.testing.assert_allclose(v[3:], 2.909e-5, rtol=2e-4)  # Table 3, set value


def test_error_model_is_eq3_with_tau_ij_axis_i_about_axis_j() -> None:
    rng = np.random.default_rng(0)
    p = random_parameters(rng)
    e = AccelerometerErrors(p)
    b, t = p[:3], dict(zip(PARAM_NAMES[3:], p[3:]))
    C = turntable_attitude(*rng.uniform(-np.pi, np.pi, 3))
    f = G * C[2]  # eq. 1: f^b = g [C31, C32, C33]
    expected = [
        b[0] + G * C[2, 1] * t["tau_xz"] - G * C[2, 2] * t["tau_xy"],
        b[1] - G * C[2, 0] * t["tau_yz"] + G * C[2, 2] * t["tau_yx"],
        b[2] + G * C[2, 0] * t["tau_zy"] - G * C[2, 1] * t["tau_zx"],
    ]
    np.testing.assert_allclose(e.error(f), expected, rtol=1e-12)


def test_bad_inputs_raise_input_error() -> None:
    with pytest.raises(InputError, match="9 values"):
        AccelerometerErrors(np.zeros(6))
    with pytest.raises(InputError, match="time step"):
        SimulationSettings(dt_s=120.0)
    with pytest.raises(InputError, match="at least one"):
        TurntableRun.start(SimulationSettings(), 0)
    session = TurntableRun.start(SimulationSettings(), 2)
    with pytest.raises(InputError, match="β2 = −β1"):
        run_scheme(session, FilterTuning.paper(G), step3_beta=(np.deg2rad(30), np.deg2rad(50)))


# ------------------------------------------------------------------ closed forms and least squares


def ideal_misalignments(p: np.ndarray, common: np.ndarray, positions) -> np.ndarray:
    """φ̂ = common + eq. 7 offsets, (n, 2)."""
    return np.array([common + misalignment_design(q.attitude, G) @ p for q in positions])


def test_closed_forms_with_compensation_recover_every_parameter() -> None:
    rng = np.random.default_rng(1)
    p, common = random_parameters(rng), rng.normal(0, 1e-3, 2)
    positions = ten_position_scheme()
    est = np.zeros(9)
    forms = {
        1: lambda phi: step1_closed_form(phi, G),
        2: step2_closed_form,
        3: lambda phi: step3_closed_form(phi, np.pi / 4, G),
        4: lambda phi: step4_closed_form(phi, np.pi / 4),
    }
    for step in (1, 2, 3, 4):
        phi = ideal_misalignments(p - est, common, [q for q in positions if q.step == step])
        for name, value in forms[step](phi).items():
            est[PARAM_NAMES.index(name)] = value
    np.testing.assert_allclose(est, p, rtol=1e-9, atol=1e-15)


def test_step1_needs_the_corrected_eq29_for_the_y_axis() -> None:
    """The printed last two lines of eq. 29 return g·τ_yx for b_y and b_y/g for τ_yx."""
    rng = np.random.default_rng(2)
    p = random_parameters(rng)
    phi = ideal_misalignments(p, np.zeros(2), ten_position_scheme()[:4])
    e = phi[:, 0]
    printed_b_y = G / 4 * (e[0] - e[1] + e[2] - e[3])
    printed_tau_yx = 0.25 * (e[0] - e[1] - e[2] + e[3])
    assert printed_b_y == pytest.approx(G * p[PARAM_NAMES.index("tau_yx")], rel=1e-9)
    assert printed_tau_yx == pytest.approx(p[1] / G, rel=1e-9)
    ours = step1_closed_form(phi, G)
    assert ours["b_y"] == pytest.approx(p[1], rel=1e-9)


def test_least_squares_over_all_positions_is_full_rank_and_exact() -> None:
    rng = np.random.default_rng(3)
    p, common = random_parameters(rng), rng.normal(0, 1e-3, 2)
    positions = ten_position_scheme()
    sol = least_squares([q.attitude for q in positions], ideal_misalignments(p, common, positions)[None], G)
    assert sol.rank == 11
    np.testing.assert_allclose(sol.params[0], p, rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(sol.common[0], common, rtol=1e-8)


# ------------------------------------------------------------------ path analysis, eq. 18-26


def test_only_paths_with_beta1_plus_beta2_zero_decouple() -> None:
    for b1, b2 in ((30, -30), (45, -45), (60, -60)):
        K = path_coefficients(np.deg2rad(b1), np.deg2rad(b2), G)
        assert abs(K[0, 1]) < 1e-12 and abs(K[1, 0]) < 1e-12
    b1, b2 = np.deg2rad(30), np.deg2rad(50)
    bz_bias, _ = coupling_bias(b1, b2, 1.0, 1.0, G)
    assert bz_bias == pytest.approx(G * (np.sin(b2) + np.sin(b1)) / (np.sin(b2) - np.sin(b1)))


def test_decoupled_readout_is_exact_on_symmetric_paths_and_biased_otherwise() -> None:
    bz, tzx = 1e-3, 3e-5
    for b1, b2 in ((45, -45), (30, 50), (20, 60)):
        K = path_coefficients(np.deg2rad(b1), np.deg2rad(b2), G)
        dphi = K @ np.array([bz, tzx])
        dec = decoupled_estimate(np.deg2rad(b1), np.deg2rad(b2), dphi, G)
        bias = coupling_bias(np.deg2rad(b1), np.deg2rad(b2), bz, tzx, G)
        np.testing.assert_allclose(dec, [bz + bias[0], tzx + bias[1]], rtol=1e-10)
        np.testing.assert_allclose(joint_estimate(np.deg2rad(b1), np.deg2rad(b2), dphi, G), [bz, tzx], rtol=1e-10)


def test_error_rates_of_eq26_are_equal_at_45_degrees() -> None:
    rb, rt = error_rates(np.deg2rad([30.0, 45.0, 60.0]), 1e-5)
    assert rb[1] == pytest.approx(rt[1])
    assert rb[0] > rt[0] and rb[2] < rt[2]  # b_z better at large β, τ_zx at small β (Table 4)


# ------------------------------------------------------------------ alignment filter


def test_discretisation_matches_the_matrix_exponential() -> None:
    import scipy.linalg

    F = error_dynamics(np.eye(3), np.deg2rad(45.78), G)
    Phi, Qd = discretise(F, np.diag(FilterTuning.paper(G).q_sd ** 2), 1.0)
    np.testing.assert_allclose(Phi, scipy.linalg.expm(F), rtol=1e-9, atol=1e-14)
    assert np.all(np.linalg.eigvalsh(Qd) > -1e-30)


@pytest.mark.parametrize("dt", [1.0, 0.1])
def test_filter_converges_to_the_limit_accuracy_of_eq7(dt: float) -> None:
    """Noise-free: the response of φ̂ to an accelerometer error is V̄/g (eq. 7)."""
    tuning = FilterTuning.paper(G)
    n = int(round(60 / dt))
    phi0 = np.deg2rad([[0.1, 0.1, 0.5]])
    lat = np.deg2rad(45.78)

    def final(df: list[float]) -> np.ndarray:
        r = align(np.eye(3), np.eye(3)[None], phi0, np.tile(df, (1, n, 1)), np.zeros((1, n, 3)), lat, G, dt, tuning)
        return (r.final_misalignment - r.truth[:, -1, 2:5])[0]

    base = final([0.0, 0.0, 0.0])
    east = final([1e-3, 0.0, 0.0]) - base
    north = final([0.0, 1e-3, 0.0]) - base
    assert east[1] == pytest.approx(-1e-3 / G, rel=2e-3)  # Δφ_n = −V̄_e/g
    assert north[0] == pytest.approx(1e-3 / G, rel=2e-3)  # Δφ_e = V̄_n/g


def test_perfect_turntable_gives_nominal_attitude_and_the_coarse_misalignment() -> None:
    s = replace(SimulationSettings(), **_BUDGET_OFF)
    session = TurntableRun.start(s, 3, seed=0)
    for q in ten_position_scheme():
        d = session.position(q)
        np.testing.assert_allclose(d.C_true, np.broadcast_to(d.C_nominal, d.C_true.shape), atol=1e-15)
        np.testing.assert_allclose(d.phi0, np.broadcast_to(np.deg2rad([0.1, 0.1, 0.5]), (3, 3)), rtol=1e-4)


def test_turntable_errors_are_arcseconds() -> None:
    session = TurntableRun.start(SimulationSettings(), 200, seed=5)
    d = session.position(ten_position_scheme()[2])  # pitch π: the tilted middle axis acts twice
    extra = np.linalg.norm(d.phi0 - np.deg2rad([0.1, 0.1, 0.5]), axis=1) * 206264.8
    assert 1.0 < np.median(extra) < 8.0


# ------------------------------------------------------------------ Monte Carlo


def test_monte_carlo_biases_are_unbiased_within_three_standard_errors(mc) -> None:
    session, tuning, scheme = mc
    det = run_scheme(TurntableRun.start(replace(session.settings, **_BUDGET_OFF), 1), tuning).estimates[0]
    truth = session.errors.values
    for name in ("b_x", "b_y", "b_z", "tau_xy", "tau_yx"):
        k = PARAM_NAMES.index(name)
        x = scheme.estimates[:, k]
        se = x.std(ddof=1) / np.sqrt(x.size)
        assert abs(x.mean() - truth[k]) <= 3 * se + abs(det[k] - truth[k]), name


def test_paper_single_run_errors_lie_within_three_monte_carlo_spreads(mc) -> None:
    _, _, scheme = mc
    for name, paper in {**PAPER_TABLE2, **PAPER_TABLE3}.items():
        x = scheme.estimate(name)
        assert abs(paper - x.mean()) < 3 * x.std(ddof=1), name


def test_table4_paths_that_break_orthogonality_are_clearly_worse(mc) -> None:
    session, tuning, scheme = mc
    set_bz = session.errors.values[PARAM_NAMES.index("b_z")]

    def bz_error(b1: float, b2: float) -> float:
        pe = path_estimates(session, tuning, scheme, np.deg2rad(b1), np.deg2rad(b2))
        return float(np.sqrt(np.mean((pe.decoupled[:, 0] - set_bz) ** 2)))

    ref = bz_error(45, -45)
    assert bz_error(30, 50) > 3 * ref
    assert bz_error(20, 60) > 2 * ref


def test_static_ml_design_of_the_ten_positions_is_rank_five() -> None:
    s = SimulationSettings()
    e = s.set_errors()
    model = LumpedModel(C=np.eye(3) + e.misalignment_matrix(), o=e.bias / s.gravity)
    directions = np.array([q.attitude[2] for q in ten_position_scheme()])  # f^b/g = third row of C_b^n
    assert np.unique(np.round(directions, 9), axis=0).shape[0] == 5
    assert analyse_design(model, directions).rank == 5


# ------------------------------------------------------------------ reproduction and CLI


def test_run_quick_is_json_safe_with_the_documented_fields() -> None:
    res = run(runs=10, seed=3, quick=True)
    text = json.dumps(res, allow_nan=False)
    assert json.loads(text)["runs"] == 10
    for table, names in (("table2", ("b_x", "b_y", "b_z")), ("table3", ("tau_xy", "tau_yx", "tau_xz", "tau_zx", "tau_yz", "tau_zy"))):
        for n in names:
            assert set(res[table][n]) == {"set", "estimate", "spread"}
    assert [(t["beta1_deg"], t["beta2_deg"]) for t in res["table4"]] == [(30, 50), (20, 60), (30, -30), (45, -45), (60, -60)]
    for t in res["table4"]:
        assert {"b_z", "tau_zx"} <= set(t) and set(t["b_z"]) == {"set", "estimate", "spread"}
    assert res["static_ml"]["fisher_rank"] == 5 and res["static_ml"]["runs_tried"] == 3
    assert res["least_squares"]["rank"] == 11
    assert isinstance(res["runtime_s"], float)


def test_cli_json_prints_one_object(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["reproduce", "sun2011", "--json", "--runs", "4", "--seed", "1"])
    out = capsys.readouterr().out
    assert code in (0, None)
    res = json.loads(out)
    assert res["runs"] == 4 and "static_ml" in res


def test_cli_text_reads_like_the_tables(capsys: pytest.CaptureFixture[str]) -> None:
    main(["reproduce", "sun2011", "--runs", "4"])
    out = capsys.readouterr().out
    for heading in ("Table 2", "Table 3", "Table 4", "Conclusion", "set", "estimate", "spread"):
        assert heading in out


def test_cli_rejects_zero_runs(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["reproduce", "sun2011", "--runs", "0"])
    assert code == 2
    assert "--runs" in capsys.readouterr().err


def test_cli_failed_acceptance_exits_1_with_one_line(capsys: pytest.CaptureFixture[str], monkeypatch) -> None:
    from optcal.applications.papers.sun2011 import reproduce as sun2011

    real_run = sun2011.run

    def run_with_a_failed_check(**kwargs):
        res = real_run(**kwargs)
        res["acceptance"][0]["met"] = False  # as if the b_x, b_y check had failed on these numbers
        return res

    monkeypatch.setattr(sun2011, "run", run_with_a_failed_check)
    code = main(["reproduce", "sun2011", "--runs", "4", "--seed", "1"])
    out, err = capsys.readouterr()
    assert code == 1
    last = err.splitlines()[-1]  # after any solver warnings of the Monte Carlo fits
    assert last.startswith("acceptance failed: b_x, b_y within 10% of the set value") and err.count("acceptance failed") == 1
    assert "--method convex" not in err
    assert "  [FAILED] b_x, b_y within 10%" in out and "[ok] paths (30°, 50°)" in out
    assert "{" not in out and "(30, 50) yes" in out
