"""The ML problem forms (SX and vectorised), scipy's least_squares, the gd core, the solver study CLI.

Speed is measured in ``benchmarks/`` (never in a test); here every solver path must reach the
same optimum, and the study command must produce its JSON.
"""

import json

import numpy as np
import pytest

from optcal import calibrate
from optcal.cli.main import main
from optcal.errors import InputError
from optcal.families.accel.base import Normaliser
from optcal.families.accel.gradient_descent import GradientDescent, cost_and_gradient, descend
from optcal.families.accel.mle import MaximumLikelihood, MLProblem, NormResidualCost, VectorisedMLProblem
from optcal.families.accel.scipy_ls import ScipyLeastSquares, solve_least_squares
from optcal.core.norm_residual import norm_residual_jacobian, normal_gain
from optcal.core.model import unpack_theta
from optcal.families.simulate.poses import simulate_poses, tilted_sweeps, uniform_directions

from helpers.common import SHARED, rngs


def normalised_problem(model, n, sigma, seed, outliers=0):
    rd, rn = rngs(seed)
    poses = simulate_poses(model, uniform_directions(n, rd), sigma, rng=rn)
    acc = poses.acc.copy()
    acc[:outliers] += 0.3  # corrupt poses
    norm = Normaliser.of(acc)
    u = norm.forward(acc)
    theta0 = norm.theta_to_normalised(model.theta) + 1e-3
    w = np.random.default_rng(seed).uniform(0.5, 1.5, n)
    return u, w / w.mean(), theta0


def test_cost_derivatives_match_finite_differences_and_reference(lu_model):
    u, w, theta = normalised_problem(lu_model, 50, 0.01, 1)
    cost = NormResidualCost(u, w)
    T, o = unpack_theta(theta)
    np.testing.assert_allclose(cost.residuals(theta), np.linalg.norm((u - o) @ T.T, axis=1) - 1, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(cost.jacobian(theta).T, norm_residual_jacobian(T, o, u), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(cost.normal_gain(theta), normal_gain(T, o, u), rtol=1e-12)
    f, g = cost.gradient(theta)
    h = 1e-6
    numeric = [(cost.value(theta + h * e) - cost.value(theta - h * e)) / (2 * h) for e in np.eye(9)]
    np.testing.assert_allclose(g, numeric, rtol=1e-6, atol=1e-9)
    J = norm_residual_jacobian(T, o, u)
    np.testing.assert_allclose(cost.gauss_newton_hessian(theta), 2 * J.T @ (J * w[:, None]), rtol=1e-12)


@pytest.mark.parametrize("loss", ["squared", "huber", "cauchy"])
def test_vectorised_problem_matches_sx_problem(lu_model, loss):
    """The numpy-callback NLP and the SX NLP have the same optimum, robust losses and bounds included."""
    u, w, theta0 = normalised_problem(lu_model, 150, 0.005, 2, outliers=8)
    delta = 1.345 * 0.005
    sx = MLProblem(len(u), loss)
    vec = VectorisedMLProblem(loss)
    a, stats_a = sx.solve(theta0, u, w, delta)
    b, stats_b = vec.solve(theta0, u, w, delta)
    assert stats_a["success"] and stats_b["success"]
    # both stop on the same scaled-gradient tolerance; 5e-7 is < 1e-3 standard errors here
    # (σ/√n ≈ 4e-4), the outliers making the Gauss–Newton Hessian of the vectorised form inexact
    np.testing.assert_allclose(a, b, atol=5e-7)
    lbx = np.full(9, -np.inf)
    lbx[6] = a[6] + 0.01  # an active bound on o_x
    a, _ = sx.solve(theta0, u, w, delta, lbx=lbx)
    b, _ = vec.solve(theta0, u, w, delta, lbx=lbx)
    assert b[6] >= lbx[6] - 1e-7  # IPOPT relaxes bounds by 1e-8 relative
    np.testing.assert_allclose(a, b, atol=2e-6)  # interior point at an active bound: < 0.005 standard errors


def test_problem_choice_and_cache():
    assert isinstance(MLProblem.get(MLProblem.SX_LIMIT), MLProblem)
    assert MLProblem.get(MLProblem.SX_LIMIT) is MLProblem.get(MLProblem.SX_LIMIT)  # built once
    big = MLProblem.get(MLProblem.SX_LIMIT + 1)
    assert isinstance(big, VectorisedMLProblem)  # nothing per n to build: made per solve, not cached


def test_large_n_path_recovers_truth_and_matches_scipy(lu_model):
    rd, rn = rngs(5)
    d = uniform_directions(3000, rd)
    exact = calibrate(simulate_poses(lu_model, d, 0.0), method="mle")
    assert np.max(np.abs(exact.params - lu_model.theta)) < 1e-9
    poses = simulate_poses(lu_model, d, 0.005, rng=rn)
    ml = calibrate(poses, method="mle")
    assert "numpy callbacks" in ml.solver.message and ml.solver.success
    lm = ScipyLeastSquares("lm").fit(poses)
    se = np.sqrt(np.diag(ml.covariance))
    assert np.all(np.abs(ml.params - lm.params) < 1e-4 * se)


def test_reweighting_stops_when_weights_settle(lu_model):
    rd, rn = rngs(6)
    known = simulate_poses(lu_model, uniform_directions(100, rd), 0.005, rng=rn)
    res = MaximumLikelihood(reweight=5).fit(known)
    assert 2 <= res.extra["passes"] < 6  # the start's weights are re-propagated once or twice, not 5 times
    unknown = known.__class__(acc=known.acc)  # no sigma: weights are all 1, nothing to re-propagate
    assert MaximumLikelihood(reweight=5).fit(unknown).extra["passes"] == 1


def test_descend_is_the_gd_iteration_and_stops_at_the_target(lu_model):
    u, w, theta0 = normalised_problem(lu_model, 60, 0.005, 7)
    T, o = unpack_theta(theta0)
    x0 = np.concatenate([T.ravel(), o])
    mu = GradientDescent.auto_step(x0, u, w)
    x, f, it, status = descend(x0, u, w, mu, 0.0, 3)
    expected = x0.copy()
    for _ in range(3):
        expected = expected - mu * cost_and_gradient(expected, u, w)[1]  # Lu 2017, eq. 17
    np.testing.assert_allclose(x, expected, rtol=1e-14)
    assert (it, status) == (3, "max_iter reached")
    f0 = cost_and_gradient(x0, u, w)[0]
    target = 0.5 * (f0 + f)
    _, f_t, it_t, status_t = descend(x0, u, w, mu, 0.0, 1000, target)
    assert status_t == "converged" and f_t <= target and it_t <= 3


@pytest.mark.parametrize("method", ["lm", "trf"])
def test_scipy_least_squares_reaches_the_ml_optimum(lu_model, method):
    u, w, theta0 = normalised_problem(lu_model, 120, 0.005, 8)
    x_ml, _ = MLProblem.get(len(u)).solve(theta0, u, w)
    x_ls, res = solve_least_squares(theta0, u, w, method)
    cost = NormResidualCost(u, w)
    assert res.success
    assert cost.value(x_ls) <= cost.value(x_ml) * (1 + 1e-12)
    np.testing.assert_allclose(x_ls, x_ml, atol=1e-8)
    poses = simulate_poses(lu_model, tilted_sweeps(20), 0.005, rng=np.random.default_rng(9))
    np.testing.assert_allclose(ScipyLeastSquares(method).fit(poses).params, calibrate(poses, method="mle").params, atol=1e-8)
    with pytest.raises(InputError, match="unknown least_squares method"):
        ScipyLeastSquares("dogbox")


def test_reproduce_solvers_quick_json(capsys):
    """The study command prints one JSON object with the figures of the issue, no NaN."""
    code = main(["reproduce", "solvers", "--json", "--quick", "--runs", "2", "--profile-solvers", "ipopt,sqpmethod"])
    assert code in (0, None)
    out = capsys.readouterr().out
    res = json.loads(out)  # exactly one JSON object on stdout
    assert set(res["efficiency"]) == {"svd", "convex-clarabel", "mle", "exact", "scipy-lm"}
    assert all(v is None or v > 0 for v in res["efficiency"].values())
    assert res["speedup"]["mle_vs_gd"] > 0 and res["speedup"]["mle_vs_scipy"] > 0
    assert res["throughput_fits_per_s"] > 0
    assert res["large"]["n_poses"] == 100_000 and res["large"]["mle_s"] > 0
    assert res["speedup_large"]["n_poses"] == 100_000 and res["speedup_large"]["mle_vs_scipy"] > 0
    assert "NaN" not in out
    table1 = res["details"]["experiments"]["table1"]["methods"]
    assert set(table1) == {"svd", "convex-clarabel", "convex-scs", "mle", "exact", "gd", "scipy-lm", "scipy-trf"}
    profile = res["performance_profile"]  # issue 29: the quick mode's library, 20 instances or more, 5 real or more
    assert profile["solvers"] == ["ipopt", "sqpmethod"]
    assert profile["n_instances"] >= 20
    if (SHARED / "data").is_dir():
        assert profile["n_real_instances"] >= 5
    for metric in ("time", "iterations"):
        curves = profile[metric]
        assert len(curves["tau"]) == len(curves["rho"]["ipopt"]) and curves["tau"][0] == 1.0
        assert all(0.0 <= v <= 1.0 for v in curves["rho"]["ipopt"])
    assert profile["success_rate"]["ipopt"] > 0.5


def test_reproduce_solvers_refuses_a_solver_that_does_not_run(capsys):
    code = main(["reproduce", "solvers", "--quick", "--profile-solvers", "ipopt,nope"])
    err = capsys.readouterr().err
    assert code == 2 and "unknown NLP solver 'nope'" in err and err.count("\n") == 1


def test_reproduce_solvers_bad_runs(capsys):
    code = main(["reproduce", "solvers", "--runs", "0"])
    assert code == 2
    assert "--runs" in capsys.readouterr().err
