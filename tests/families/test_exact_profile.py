"""The exact ML (Lu 2017, eq. 8) by variable projection against the full 9 + 3n NLP and brute force.

The secular-equation projection against a brute-force closest point (random points in and out,
a point on an ellipsoid's axis — the hard case — and equal semi-axes); the profile formulation
against the full IPOPT NLP (optimum and covariance); the profile Hessian against the Schur
complement of the full problem's Lagrangian Hessian built independently with CasADi (in T, not C)
and against finite differences of the profile cost; the curvature against its closed form at an
ellipsoid's vertex; the curvature-corrected score removes the O(σ²) bias of eq. 8's ML.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from optcal import calibrate
from optcal.core.poses import PoseTable
from optcal.core.model import lu2017_reference_model, unpack_theta
from optcal.errors import InputError
from optcal.families.accel.ellipsoid_projection import closest_points
from optcal.families.accel.exact_profile import curvature_sum, fit_corrected_score, fit_profile, profile_hessian
from optcal.families.simulate.poses import cap_directions, simulate_poses, uniform_directions

#: A lower-triangular C (semi-axes about 1.3, 1.2, 0.8) and a bias, in g: Lu 2017's sensor, roughly.
C_LU = np.array([[1.2, 0.0, 0.0], [0.03, 0.8, 0.0], [0.05, -0.02, 1.3]])
O_LU = np.array([0.20, 0.15, 0.10])


def brute_distance2(C: np.ndarray, o: np.ndarray, a: np.ndarray, rng: np.random.Generator) -> float:
    """min over the unit sphere of ‖a − o − C d‖² by BFGS from many starts (d = x/‖x‖)."""
    best = np.inf
    for _ in range(5):
        res = minimize(lambda x: np.sum((a - o - C @ (x / np.linalg.norm(x))) ** 2), rng.normal(size=3),
                       method="BFGS", options={"gtol": 1e-12})
        best = min(best, float(res.fun))
    return best


def test_secular_projection_matches_brute_force_and_kkt():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    scale = rng.uniform(0.1, 1.8, size=(40, 1))  # from deep inside to far outside
    a = O_LU + scale * (d @ C_LU.T)
    cp = closest_points(C_LU, O_LU, a)
    np.testing.assert_allclose(np.linalg.norm(cp.d, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(cp.r @ C_LU, cp.lam[:, None] * cp.d, atol=1e-12)  # Cᵀr = λd
    np.testing.assert_allclose(cp.r, cp.distance[:, None] * cp.normal, atol=1e-12)  # r along the normal
    assert np.all(np.sign(cp.distance) == np.sign(scale[:, 0] - 1.0))  # outside positive
    for k in range(0, 40, 4):
        assert np.sum(cp.r[k] ** 2) == pytest.approx(brute_distance2(C_LU, O_LU, a[k], rng), rel=1e-9, abs=1e-14)


def test_point_on_an_axis_inside_is_the_hard_case():
    """Inside, on the longest axis, within its evolute: λ = −s_min², two closest points, distance exact."""
    C = np.diag([2.0, 1.5, 1.0])
    a = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.4], [1.9, 0.0, 0.0]])
    cp = closest_points(C, np.zeros(3), a)
    assert cp.hard == 2  # the first two: on an axis longer than the shortest, near the centre
    rng = np.random.default_rng(1)
    for k in range(4):
        assert np.sum(cp.r[k] ** 2) == pytest.approx(brute_distance2(C, np.zeros(3), a[k], rng), rel=1e-9)
    np.testing.assert_allclose(cp.lam[:2], -1.0, atol=1e-12)
    np.testing.assert_allclose(cp.d[2], [0.0, 0.0, 1.0], atol=1e-14)  # the shortest axis itself: its vertex
    np.testing.assert_allclose(cp.d[3], [1.0, 0.0, 0.0], atol=1e-14)


@pytest.mark.parametrize("axes", [(1.3, 1.3, 1.3), (1.3, 1.3, 0.9), (1.1, 0.9, 0.9)])
def test_equal_semi_axes(axes):
    """A sphere (radial projection), and ellipsoids of revolution, against brute force; the centre of a sphere."""
    rng = np.random.default_rng(2)
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    C = R @ np.diag(axes)
    a = rng.normal(size=(6, 3))
    cp = closest_points(C, O_LU, O_LU + a)
    for k in range(6):
        assert np.sum(cp.r[k] ** 2) == pytest.approx(brute_distance2(C, O_LU, O_LU + a[k], rng), rel=1e-9)
    if len(set(axes)) == 1:
        np.testing.assert_allclose(cp.d @ C.T, axes[0] * a / np.linalg.norm(a, axis=1, keepdims=True), atol=1e-12)
        centre = closest_points(C, O_LU, O_LU[None, :])
        assert centre.distance[0] == pytest.approx(-axes[0]) and centre.hard == 1


def test_curvature_at_a_vertex():
    """κ₁ + κ₂ at the vertex (a, 0, 0) of the ellipsoid with semi-axes a, b, c is a/b² + a/c²."""
    a_, b_, c_ = 1.4, 1.1, 0.7
    T = np.diag([1 / a_, 1 / b_, 1 / c_])
    cp = closest_points(np.linalg.inv(T), np.zeros(3), np.array([[2.0, 0.0, 0.0]]))
    assert curvature_sum(T, cp)[0] == pytest.approx(a_ / b_**2 + a_ / c_**2, rel=1e-12)


@pytest.fixture(scope="module")
def noisy():
    return simulate_poses(lu2017_reference_model(), uniform_directions(40, np.random.default_rng(5)), 0.02, rng=np.random.default_rng(6))


@pytest.mark.parametrize("sigma_given", [False, True])
def test_profile_equals_full_nlp(noisy, sigma_given):
    poses = noisy if sigma_given else PoseTable(acc=noisy.acc)  # per-pose σ given (simulated) or not
    profile = calibrate(poses, method="exact")
    full = calibrate(poses, method="exact", formulation="full")
    assert profile.extra["formulation"] == "profile" and full.extra["formulation"] == "full"
    assert profile.solver.success and full.solver.success
    se = np.sqrt(np.diag(full.covariance))
    assert np.max(np.abs(profile.params - full.params) / se) < 1e-6
    np.testing.assert_allclose(profile.covariance, full.covariance, rtol=1e-6, atol=1e-6 * np.max(full.covariance))
    if sigma_given:  # with absolute weights the norm residual's Fisher information is the same to O(σ)
        se_mle = np.sqrt(np.diag(calibrate(poses, method="mle").covariance))
        assert np.all(np.abs(np.sqrt(np.diag(profile.covariance)) / se_mle - 1) < 0.05)


def test_profile_hessian_is_the_schur_complement_of_the_full_nlp(noisy):
    """∇² of the profile cost = the full Lagrangian's Hessian (CasADi, in T and o) reduced on the spheres' tangents."""
    import casadi as ca

    a = noisy.acc[:15]
    w = np.linspace(0.5, 2.0, len(a))
    theta = fit_profile(calibrate(noisy, method="mle").params[:9], a, w, True).theta
    T, o = unpack_theta(theta)
    cp = closest_points(np.linalg.inv(T), o, a)
    n = len(a)
    x = ca.SX.sym("x", 9 + 3 * n)
    Ts = ca.vertcat(ca.horzcat(x[0], 0, 0), ca.horzcat(x[1], x[2], 0), ca.horzcat(x[3], x[4], x[5]))
    D = ca.reshape(x[9:], 3, n)
    E = ca.DM(a.T) - ca.repmat(x[6:9], 1, n) - ca.mtimes(ca.inv(Ts), D)
    nu = w * cp.lam  # the multipliers of ‖d_k‖² = 1 (stationarity: w Cᵀr = ν d)
    lagrangian = ca.sum2(ca.DM(w).T * ca.sum1(E * E)) + ca.dot(ca.DM(nu), ca.sum1(D * D).T - 1.0)
    H = np.array(ca.Function("h", [x], [ca.hessian(lagrangian, x)[0]])(np.concatenate([theta, cp.d.ravel()])))
    Z = np.zeros((9 + 3 * n, 9 + 2 * n))  # tangent basis: θ free, each d_k on its sphere
    Z[:9, :9] = np.eye(9)
    for k in range(n):
        Z[9 + 3 * k: 12 + 3 * k, 9 + 2 * k: 11 + 2 * k] = np.linalg.svd(cp.d[k][None, :])[2][1:].T
    Hr = Z.T @ H @ Z
    schur = Hr[:9, :9] - Hr[:9, 9:] @ np.linalg.solve(Hr[9:, 9:], Hr[9:, :9])
    mine = profile_hessian(theta, a, w, cp)
    np.testing.assert_allclose(mine, schur, rtol=1e-7, atol=1e-7 * np.max(np.abs(schur)))

    def cost(th: np.ndarray) -> float:
        Tt, ot = unpack_theta(th)
        return float(np.sum(w * closest_points(np.linalg.inv(Tt), ot, a).distance ** 2))

    h = 1e-4
    k = 2  # T_yy, by central second differences
    e = np.zeros(9)
    e[k] = h
    fd = (cost(theta + e) - 2 * cost(theta) + cost(theta - e)) / h**2
    assert mine[k, k] == pytest.approx(fd, rel=1e-4)


def test_curvature_correction_removes_the_second_order_bias(lu_model):
    """At 50 mg and 4·10⁴ poses eq. 8's ML sits outside the true ellipsoid by several standard errors
    (its scale factors T_ii too small by ≈ σ²/R²); the corrected score does not."""
    n, sigma = 40_000, 0.05
    poses = simulate_poses(lu_model, uniform_directions(n, np.random.default_rng(7)), sigma, rng=np.random.default_rng(8))
    truth = lu_model.theta
    w = np.full(n, 1 / sigma**2)
    ml = fit_profile(truth, poses.acc, w, True)
    corrected = fit_corrected_score(ml.theta, poses.acc, 1 / w)
    assert ml.converged and corrected.converged
    T, _ = unpack_theta(ml.theta)
    sd = np.sqrt(np.diag(np.linalg.inv(0.5 * profile_hessian(ml.theta, poses.acc, w, ml.points))))
    diag = [0, 2, 5]
    z_ml = (ml.theta[diag] - truth[diag]) / sd[diag]
    z_corrected = (corrected.theta[diag] - truth[diag]) / sd[diag]
    assert np.mean(z_ml) < -3 and abs(np.mean(z_corrected)) < 2, (z_ml, z_corrected)


def test_formulation_arguments_are_checked(noisy):
    with pytest.raises(InputError, match="formulation must be one of"):
        calibrate(noisy, method="exact", formulation="dense")
    with pytest.raises(InputError, match="ipopt_options apply to the full NLP only"):
        calibrate(noisy, method="exact", formulation="profile", ipopt_options={"ipopt.tol": 1e-8})
    with pytest.raises(InputError, match="curvature_correction=True needs formulation='profile'"):
        calibrate(noisy, method="exact", formulation="full", curvature_correction=True)


def test_scaling_study_point():
    """One size of `optcal reproduce lu2017 --scaling`: every method, the two formulations on the same optimum."""
    from optcal.applications.papers.lu2017_scaling import METHODS, size_point

    point = size_point(60, 3, seed=0, full_nlp=True)
    assert set(point["methods"]) == set(METHODS)
    assert all(r["runs"] == 3 and r["failures"] == 0 for r in point["methods"].values())
    assert point["exact_vs_full_max_difference_in_stderr"] < 1e-5
    assert point["methods"]["exact"]["efficiency"] == pytest.approx(point["methods"]["exact-full"]["efficiency"], rel=1e-6)


def test_a_start_that_did_not_converge_is_replaced(lu_model):
    """On a 60° cap the mle start stops early far away (a huge ellipsoid); the profile fit restarts from
    the convex fit and reaches the full NLP's optimum, as the full NLP does from the same bad start."""
    import warnings

    poses = simulate_poses(lu_model, cap_directions(80, 60.0, np.random.default_rng(4)), 0.005, rng=np.random.default_rng(9))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        profile = calibrate(poses, method="exact", allow_degenerate=True)
        full = calibrate(poses, method="exact", formulation="full", allow_degenerate=True)
    assert profile.solver.success and "restarted from the convex fit (mle start did not converge)" in profile.solver.message
    assert np.max(np.abs(profile.params - full.params) / np.sqrt(np.diag(full.covariance))) < 1e-5
