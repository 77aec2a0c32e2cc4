"""Formulations as objects (optcal.problems): each calibration problem taken out and solved by several solvers,
to the optimum the estimator reaches; and the solver study's performance profiles on a small library."""

from __future__ import annotations

import numpy as np
import pytest

import optcal
from optcal.applications.papers.solver_profiles import (
    Instance,
    format_profile,
    profile,
    real_instances,
    run,
    solve_instance,
    synthetic_instances,
)
from optcal.data.units import GyroUnitsDecision
from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro
from optcal.families.gyro.moves import moves_from_arrays
from optcal.families.simulate.gyro import reference_gyro, simulate_imu
from optcal.families.simulate.poses import simulate_poses, uniform_directions
from optcal.problems import convex_fit, exact_ml, gyroscope, norm_residual_ml, pose_refinement, theta_of
from optcal.problems.accel import exact_theta
from optcal.solvers.registry import probe_nlp_solver


@pytest.fixture(scope="module")
def poses() -> optcal.PoseTable:
    return simulate_poses(optcal.lu2017_reference_model(), uniform_directions(40, np.random.default_rng(2)), 0.004,
                          rng=np.random.default_rng(3))


def test_norm_residual_ml_formulation_is_what_the_estimator_solves(poses) -> None:
    problem = norm_residual_ml(poses)
    text = problem.describe()
    assert "Lu 2017, eq. 13-14" in text and "T_xx'" in text and "cost scaled" in text
    nlp = problem.nlp()
    assert set(nlp) == {"x", "p", "f"} and nlp["x"].numel() == 9
    fit = optcal.calibrate(poses, reweight=0)  # one pass: the formulation's weights
    se = np.sqrt(np.diag(fit.covariance))
    for solver in ("ipopt", "sqpmethod", "fatrop"):
        if not probe_nlp_solver(solver).available:
            continue
        solution = problem.solve(solver)
        assert solution.success and solution.solver == solver
        assert np.max(np.abs(theta_of(poses, solution.x) - fit.params) / se) < 1e-3


def test_constrained_formulation_has_its_constraint(poses) -> None:
    problem = norm_residual_ml(poses, fix={"S_x": 1.21}, bounds={"o_z": (0.0, 0.2)})
    assert problem.has_constraints and "S_x" in problem.constraints[0]
    assert "o_z' in [" in problem.describe()
    solution = problem.solve("ipopt")
    from optcal.core.constraints import parameter_value

    assert parameter_value(theta_of(poses, solution.x), "S_x") == pytest.approx(1.21, rel=1e-8)


def test_convex_formulation_by_two_conic_solvers(poses) -> None:
    problem = convex_fit(poses)
    a = problem.solve("CLARABEL")
    b = problem.solve("SCS")
    assert a.success and b.success and a.values["eta"] is not None and b.values["eta"] is not None
    assert np.max(np.abs(a.values["eta"] - b.values["eta"])) < 1e-6


def test_exact_formulation_is_eq_8(poses) -> None:
    start = optcal.calibrate(poses).params
    problem = exact_ml(poses, start)
    assert problem.has_constraints and problem.nlp()["x"].numel() == 9 + 3 * poses.n
    solution = problem.solve()
    assert solution.success
    exact = optcal.calibrate(poses, method="exact")
    se = np.sqrt(np.diag(exact.covariance))
    assert np.max(np.abs(exact_theta(poses, solution.x) - exact.params) / se) < 1e-3


def test_gyroscope_formulation_reaches_the_estimators_answer() -> None:
    rec = simulate_imu(optcal.lu2017_reference_model(), reference_gyro(1.0, rng=1), 12, rng=12, dwell_s=1.0, move_s=1.0,
                       gyro_noise=0.002)
    moves = moves_from_arrays(rec.t, rec.acc, rec.gyro, rec.intervals)
    acc = optcal.calibrate(optcal.PoseTable(acc=moves.acc_means))
    units = GyroUnitsDecision("rad/s", "test")
    problem = gyroscope(moves, acc, units)
    cal = calibrate_gyro(moves, acc, units, GyroSettings())
    for solver in ("ipopt", "sqpmethod"):
        solution = problem.solve(solver)
        assert solution.success, solution
        np.testing.assert_allclose(np.eye(3) + solution.x.reshape(3, 3),
                                   np.eye(3) + (cal.gyro.T / units.rad_per_unit - np.eye(3)), atol=1e-5)


def test_pose_refinement_formulation_keeps_unit_directions() -> None:
    from optcal.applications.plan.information import Criterion, Prior

    vectors = Prior.nominal("g").information_vectors
    start = uniform_directions(12, np.random.default_rng(4))
    problem = pose_refinement(vectors, start, Criterion.D)
    assert problem.has_constraints and "‖d_k‖² = 1" in problem.describe()
    solution = problem.solve()
    d = solution.x.reshape(-1, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)


def test_performance_profile_of_a_small_library() -> None:
    """Seconds: six synthetic instances, two solvers; ρ is a share that rises to the success rate."""
    instances = synthetic_instances(quick=True)[:6]
    results = [solve_instance(inst, ["ipopt", "sqpmethod"], 1) for inst in instances]
    prof = profile(results, ["ipopt", "sqpmethod"], "time_s")
    for s in ("ipopt", "sqpmethod"):
        rho = np.asarray(prof["rho"][s])
        assert np.all(np.diff(rho) >= 0) and 0 <= rho[0] and rho[-1] <= 1
        success = np.mean([r["solvers"][s]["success"] for r in results])
        assert rho[-1] <= success + 1e-12
    assert max(prof["rho"][s][0] for s in ("ipopt", "sqpmethod")) > 0  # someone is the fastest somewhere
    for r in results:
        best = [v for v in r["solvers"].values() if v["gap"] == 0.0]
        assert best, r


def test_quick_study_library_has_twenty_instances_and_five_real(shared_data) -> None:
    synthetic = synthetic_instances(quick=True)
    real, skipped = real_instances(shared_data)
    assert len(synthetic) + len(real) >= 20 and len(real) >= 5, skipped
    assert {i.factor for i in synthetic} >= {"size", "noise", "distortion", "coverage", "outliers"}


def test_run_reports_the_profile_object(shared_data, tmp_path) -> None:
    """The quick study's JSON object on a library cut to two real recordings (the full library is the CLI's)."""
    import optcal.applications.papers.solver_profiles as sp

    small = tmp_path / "data"
    (small / "imutk-xsens").mkdir(parents=True)
    (small / "imutk-xsens" / "xsens_imutk.csv").symlink_to(shared_data / "imutk-xsens" / "xsens_imutk.csv")
    original = sp.synthetic_instances
    try:
        sp.synthetic_instances = lambda quick, seed=0: original(quick, seed)[:3]  # type: ignore[assignment]
        res = run(quick=True, solvers=["ipopt", "sqpmethod"], data_dir=small)
    finally:
        sp.synthetic_instances = original  # type: ignore[assignment]
    assert res["solvers"] == ["ipopt", "sqpmethod"] and res["n_instances"] == 4 and res["n_real_instances"] == 1
    assert len(res["real_skipped"]) == len(sp.REAL_RECORDINGS) - 1
    assert set(res["time"]) == {"tau", "rho", "solvers"} and len(res["time"]["tau"]) == len(res["time"]["rho"]["ipopt"])
    assert res["conic"]["max_abs_difference_normalised"]["SCS"] < 1e-6
    assert "instances" in format_profile(res)
    assert isinstance(Instance("x", "synthetic", "base", instances_poses()).poses, optcal.PoseTable)


def instances_poses() -> optcal.PoseTable:
    return simulate_poses(optcal.lu2017_reference_model(), uniform_directions(12, 1), 0.001, rng=1)
