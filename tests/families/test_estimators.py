"""Estimators: noise-free recovery, noisy Monte Carlo, cross-method agreement, degenerate designs."""

import numpy as np
import pytest

from optcal import calibrate
from optcal.errors import FitError, IdentifiabilityError, InputError
from optcal.families.accel.ellipsoid import ConvexEllipsoidFit
from optcal.families.accel.gradient_descent import GradientDescent, cost_and_gradient
from optcal.families.accel.mle import MaximumLikelihood
from optcal.core.model import LumpedModel
from optcal.core.poses import PoseTable
from optcal.families.simulate.poses import cap_directions, lu2017_sweeps, simulate_poses, tilted_sweeps, uniform_directions

from helpers.common import rngs

METHODS = ["svd", "convex", "mle", "exact", "gd"]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("units_scale", [1.0, 9.80665, 4096.0])
def test_noise_free_recovery(lu_model, method, units_scale):
    """Every method recovers A and o to 1e-8 from exact data (gd to its tolerance), in any units."""
    model = LumpedModel(lu_model.C * units_scale, lu_model.o * units_scale + (32768 if units_scale > 100 else 0))
    poses = simulate_poses(model, tilted_sweeps(20), 0.0, units="counts" if units_scale > 100 else "g")
    res = calibrate(poses, method=method)
    A_rel = np.max(np.abs(res.A - model.A)) / np.max(np.abs(model.A))
    o_rel = np.max(np.abs(res.o - model.o)) / units_scale
    assert A_rel < 1e-8, (method, A_rel)
    assert o_rel < 1e-8, (method, o_rel)
    assert res.rms_norm_residual_g < 1e-8
    assert res.solver.success


def test_gd_from_perturbed_start_reaches_tolerance(lu_model):
    poses = simulate_poses(lu_model, tilted_sweeps(20), 0.0)
    start = calibrate(poses, method="svd")  # exact on noise-free data: gd would have nothing to do
    unperturbed = GradientDescent(init=start, tol=1e-12).fit(poses)
    start.o = start.o + 0.01  # a start away from the optimum
    res = GradientDescent(init=start, tol=1e-12).fit(poses)
    assert res.solver.success and res.extra["init"] == "svd"
    assert np.max(np.abs(res.A - lu_model.A)) < 1e-8 and np.max(np.abs(res.o - lu_model.o)) < 1e-8
    assert res.solver.iterations > 10 * max(unperturbed.solver.iterations, 1)  # it did start 10 mg away


def test_gradient_matches_finite_differences():
    rng = np.random.default_rng(4)
    u = rng.standard_normal((30, 3))
    w = rng.uniform(0.5, 2, 30)
    x = np.concatenate([(np.eye(3) + 0.1 * rng.standard_normal((3, 3))).ravel(), 0.1 * rng.standard_normal(3)])
    _, g = cost_and_gradient(x, u, w)
    h = 1e-6
    num = [(cost_and_gradient(x + h * e, u, w)[0] - cost_and_gradient(x - h * e, u, w)[0]) / (2 * h) for e in np.eye(12)]
    np.testing.assert_allclose(g, num, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("method", ["mle", "exact"])
def test_noisy_monte_carlo_unbiased_and_stderr_calibrated(lu_model, method):
    """Mean within 3 standard errors of the truth; reported stderr within 20% of the MC spread."""
    runs = 150 if method == "mle" else 80
    d = tilted_sweeps(40)
    sigma = 0.005
    est, se = [], []
    for k in range(runs):
        poses = simulate_poses(lu_model, d, sigma, rng=np.random.default_rng([k, 7]))
        r = calibrate(poses, method=method)
        est.append(r.params)
        se.append(np.sqrt(np.diag(r.covariance)))
    est, se = np.array(est), np.array(se)
    truth = lu_model.theta
    spread = est.std(axis=0, ddof=1)
    z = (est.mean(axis=0) - truth) / (spread / np.sqrt(runs))
    assert np.all(np.abs(z) < 3.5), z  # 9 parameters: 3.5 keeps the family-wise false alarm rate low
    ratio = se.mean(axis=0) / spread
    # the MC spread itself has relative error 1/sqrt(2 runs) (~6-8%): 20% + that
    assert np.all(np.abs(ratio - 1) < 0.20 + 2 / np.sqrt(2 * runs)), ratio


def test_cross_method_agreement(lu_model):
    """On the same noisy data, mle, exact and gd agree far inside the statistical error."""
    poses = simulate_poses(lu_model, tilted_sweeps(40), 0.005, rng=np.random.default_rng(11))
    mle = calibrate(poses, method="mle")
    gd = calibrate(poses, method="gd")
    exact = calibrate(poses, method="exact")
    svd = calibrate(poses, method="svd")
    se = np.sqrt(np.diag(mle.covariance))
    # same cost up to the weights (gd keeps the propagated weights of its start, mle re-propagates
    # them at its estimate): the optima agree to a small fraction of a standard error
    assert np.all(np.abs(gd.params - mle.params) < 1e-2 * se)
    assert np.all(np.abs(exact.params - mle.params) < 0.5 * se)  # different cost, close optimum
    assert np.all(np.abs(svd.params - mle.params) < 2 * se)
    assert abs(gd.chisqr - mle.chisqr) / mle.chisqr < 1e-4


def test_convex_returns_ellipsoid_where_svd_returns_hyperboloid(lu_model):
    # poses on a 20° cap of the sphere with 10 mg noise: the SVD fit is a hyperboloid (seed found by search)
    rd, rn = np.random.default_rng([1, 1]), np.random.default_rng([1, 2])
    poses = simulate_poses(lu_model, cap_directions(30, 20, rd), 0.01, rng=rn)
    with pytest.raises(FitError, match="hyperboloid"):
        calibrate(poses, method="svd", allow_degenerate=True)
    res = calibrate(poses, method="convex", allow_degenerate=True)
    assert np.all(np.linalg.eigvalsh(res.A) > 0)
    assert res.solver.status == "optimal"
    # and the ML refinement can start from it
    ml = calibrate(poses, method="mle", allow_degenerate=True)
    assert np.all(np.linalg.eigvalsh(ml.A) > 0)


def test_convex_with_scs(lu_model):
    poses = simulate_poses(lu_model, tilted_sweeps(20), 0.002, rng=np.random.default_rng(5))
    a = ConvexEllipsoidFit(solver="SCS").fit(poses)
    b = ConvexEllipsoidFit(solver="CLARABEL").fit(poses)
    assert a.solver.name == "SCS"
    np.testing.assert_allclose(a.A, b.A, atol=1e-6)


def test_convex_kkt_optimality_without_polish(lu_model):
    """Clarabel's answer satisfies the optimality conditions of the equality-constrained problem."""
    poses = simulate_poses(lu_model, tilted_sweeps(20), 0.002, rng=np.random.default_rng(6))
    polished = ConvexEllipsoidFit(polish=True).fit(poses)
    raw = ConvexEllipsoidFit(polish=False).fit(poses)
    np.testing.assert_allclose(raw.A, polished.A, rtol=1e-5, atol=1e-6)


def test_literal_lu_schedule_is_refused_and_named(lu_model):
    poses = simulate_poses(lu_model, lu2017_sweeps(30), 0.001, rng=np.random.default_rng(1))
    with pytest.raises(IdentifiabilityError, match="A_xy"):
        calibrate(poses, method="mle")
    res = calibrate(poses, method="mle", allow_degenerate=True)
    # with noise the missing direction is numerically present: full rank, but weakly determined (and said so)
    ident = res.identifiability
    word = "WEAKLY DETERMINED POSE SET" if ident.rank == ident.n_params else "DEGENERATE POSE SET"
    assert any(n.startswith(word) for n in res.notes), res.notes
    if ident.rank == ident.n_params:
        assert "does not determine" not in " ".join(res.notes) and "weakly determined (standard error" in " ".join(res.notes)


def test_mle_weights_per_pose_noise(lu_model):
    """Per-pose sigma enters as weights: a very noisy pose barely moves the answer."""
    d = tilted_sweeps(20)
    rd, rn = rngs(3)
    poses = simulate_poses(lu_model, d, 0.001, rng=rn)
    sig = np.full(poses.n, 0.001)
    sig[5] = 1.0
    acc = poses.acc.copy()
    acc[5] += 0.3  # corrupt, but declared very noisy
    weighted = calibrate(poses.with_acc(acc).__class__(acc=acc, sigma=sig), method="mle")
    clean = calibrate(poses, method="mle")
    assert np.max(np.abs(weighted.A - clean.A)) < 5e-3


def test_mle_huber_downweights_corrupt_poses(lu_model):
    d = uniform_directions(80, np.random.default_rng([2, 1]))
    poses = simulate_poses(lu_model, d, 0.001, rng=np.random.default_rng([2, 2]))
    acc = poses.acc.copy()
    bad = [3, 17, 40, 66]
    acc[bad] = lu_model.o + (acc[bad] - lu_model.o) * np.array([[1.05], [0.94], [1.06], [0.95]])  # ±5 % norm errors
    corrupt = PoseTable(acc=acc)
    plain = calibrate(corrupt, method="mle")
    robust = MaximumLikelihood(loss="cauchy").fit(corrupt)
    assert set(robust.extra["downweighted_rows"]) >= set(bad)
    err_plain = np.max(np.abs(plain.A - lu_model.A))
    err_robust = np.max(np.abs(robust.A - lu_model.A))
    assert err_robust < err_plain / 3


def test_mle_bounds_respected(lu_model):
    poses = simulate_poses(lu_model, tilted_sweeps(20), 0.01, rng=np.random.default_rng(8))
    free = calibrate(poses, method="mle")
    bound = MaximumLikelihood(bounds={"o_x": (0.0, free.o[0] - 0.02)}).fit(poses)
    assert bound.o[0] <= free.o[0] - 0.02 + 1e-7
    with pytest.raises(InputError, match="unknown parameter"):
        MaximumLikelihood(bounds={"bogus": (0, 1)}).fit(poses)
    ranged = MaximumLikelihood(scale_range=(0.5, 2.0)).fit(poses)
    np.testing.assert_allclose(ranged.params, free.params, atol=1e-6)  # inactive bounds change nothing


def test_mle_reuses_problem(lu_model):
    from optcal.families.accel.mle import ML_PROBLEMS
    from optcal.solvers.registry import SolverChoice

    poses = simulate_poses(lu_model, tilted_sweeps(20), 0.01, rng=np.random.default_rng(9))
    calibrate(poses, method="mle")
    problem = ML_PROBLEMS.get(poses.n, "squared", SolverChoice(), ())
    n_before = len(ML_PROBLEMS)
    for k in range(3):
        calibrate(simulate_poses(lu_model, tilted_sweeps(20), 0.01, rng=np.random.default_rng(k)), method="mle")
    assert len(ML_PROBLEMS) == n_before and ML_PROBLEMS.get(poses.n, "squared", SolverChoice(), ()) is problem


@pytest.mark.parametrize(
    "acc, message",
    [
        (np.full((12, 3), 1.0), "distinct poses"),
        (np.column_stack([np.cos(np.linspace(0, 6, 12)), np.sin(np.linspace(0, 6, 12)), np.zeros(12)]), "one plane"),
        (np.eye(3)[[0, 1, 2, 0, 1, 2, 0, 1]], "only 8 poses"),
    ],
)
def test_bad_pose_sets(acc, message):
    with pytest.raises(InputError, match=message):
        calibrate(PoseTable(acc=acc), method="mle")


def test_nan_pose_rejected(lu_model):
    poses = simulate_poses(lu_model, tilted_sweeps(10), 0.0)
    acc = poses.acc.copy()
    acc[2, 1] = np.nan
    with pytest.raises(InputError, match="NaN or infinite"):
        calibrate(PoseTable(acc=acc), method="svd")


def test_unknown_method():
    with pytest.raises(InputError, match="unknown method"):
        calibrate(PoseTable(acc=np.eye(3)), method="magic")


def test_nine_poses_convex_does_not_crash(lu_model):
    """Fewer than 10 poses: the convex fit pads its triangular factor (regression)."""
    poses = simulate_poses(lu_model, uniform_directions(9, np.random.default_rng([4, 1])), 0.0)
    res = ConvexEllipsoidFit(allow_degenerate=True).fit(poses)
    np.testing.assert_allclose(res.A, lu_model.A, atol=1e-8)


def test_counts_covariance_is_well_scaled(lu_model):
    """Standard errors of o in counts are of the size of the noise, not ~1e-15 (regression)."""
    model = LumpedModel(lu_model.C * 16384, lu_model.o * 16384 + 500)
    poses = simulate_poses(model, tilted_sweeps(20), 16.0, rng=np.random.default_rng(3), units="counts")
    res = calibrate(poses, method="mle")
    se = res.stderr
    assert 1.0 < se["o_x"] < 20.0, se


def test_collapsed_ml_fit_is_a_fit_error_with_the_right_advice():
    """On a 30° cap the norm-residual cost can fall into a degenerate minimum (T singular): the plain maximum
    likelihood (``keep_physical=False``) reports it as a collapsed fit, not as "not an ellipsoid, use convex"; by
    default the refinement is kept only inside the physical set, so the convex start is handed back, said so."""
    from optcal.core.model import lu2017_reference_model

    model = lu2017_reference_model()
    poses = simulate_poses(model, cap_directions(120, 30.0, np.random.default_rng(31)), 0.02,
                           rng=np.random.default_rng(131))
    with pytest.raises(FitError, match=r"collapsed to a singular T.*scale_range=\(low, high\)"):
        calibrate(poses, method="mle", allow_degenerate=True, keep_physical=False)
    kept = calibrate(poses, method="mle", allow_degenerate=True)
    assert "physical_set" in kept.extra and any("MAXIMUM LIKELIHOOD NOT KEPT" in n for n in kept.notes)
    bounded = calibrate(poses, method="mle", allow_degenerate=True, scale_range=(0.7, 1.4))
    assert np.all(np.abs(np.diag(bounded.T)) > 0.5)


def test_exact_problem_hessian_matches_automatic_differentiation():
    """The per-pose assembly of the eq. 8 Lagrangian Hessian equals CasADi's own (upper triangle)."""
    import casadi as ca

    from optcal.families.accel.exact import ExactProblem
    from optcal.core.norm_residual import casadi_lower_triangular as lower_triangular

    n = 7
    x, p = ca.SX.sym("x", 9 + 3 * n), ca.SX.sym("p", 4 * n)
    lam_f, lam_g = ca.SX.sym("lf"), ca.SX.sym("lg", n)
    d, a, w = ca.reshape(x[9:], 3, n), ca.reshape(p[: 3 * n], 3, n), p[3 * n:].T
    e = a - ca.repmat(x[6:9], 1, n) - ca.mtimes(lower_triangular(x[:6]), d)
    lagrangian = lam_f * ca.sum2(w * ca.sum1(e * e)) + ca.dot(lam_g, ca.sum1(d * d).T - 1.0)
    reference = ca.Function("ref", [x, p, lam_f, lam_g], [ca.triu(ca.hessian(lagrangian, x)[0])])
    mine = ExactProblem._hessian(x, p, n)
    rng = np.random.default_rng(0)
    args = [rng.normal(size=9 + 3 * n), rng.normal(size=4 * n), 0.7, rng.normal(size=n)]
    np.testing.assert_allclose(np.array(ca.densify(mine(*args))), np.array(ca.densify(reference(*args))), atol=1e-12)
