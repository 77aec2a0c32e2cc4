"""The norm-residual kernel (Lu 2017, eq. 13, 15-16) that every estimator uses.

Checked against the formula written out directly, central differences, and CasADi's automatic
derivative of the same residual; the paper's 12-parameter Jacobian against the θ one.
"""

import numpy as np
import pytest

from optcal.core.model import theta_from, unpack_theta
from optcal.core.norm_residual import (
    NormResidualKernel,
    casadi_lower_triangular,
    casadi_norm_residual,
    norm_residual_jacobian,
    norm_residuals,
    normal_gain,
)
from optcal.families.simulate.poses import simulate_poses, uniform_directions

from helpers.common import rngs


@pytest.fixture
def measurements(lu_model):
    rd, rn = rngs(11)
    return simulate_poses(lu_model, uniform_directions(40, rd), 0.01, rng=rn).acc


@pytest.fixture
def theta(lu_model):
    return lu_model.theta + np.random.default_rng(3).normal(0, 0.02, 9)


def test_residuals_and_gain_match_the_formula_written_out(measurements, theta):
    T, o = unpack_theta(theta)
    v = (measurements - o) @ T.T
    expected = np.linalg.norm(v, axis=1) - 1.0  # Lu 2017, eq. 13
    np.testing.assert_allclose(norm_residuals(T, o, measurements), expected, rtol=0, atol=1e-14)
    abar = v / np.linalg.norm(v, axis=1, keepdims=True)
    np.testing.assert_allclose(normal_gain(T, o, measurements), np.linalg.norm(abar @ T, axis=1), rtol=1e-14)


def test_theta_jacobian_matches_central_differences(measurements, theta):
    T, o = unpack_theta(theta)
    J = norm_residual_jacobian(T, o, measurements)
    h = 1e-6
    numeric = np.column_stack([
        (norm_residuals(*unpack_theta(theta + h * e), measurements) - norm_residuals(*unpack_theta(theta - h * e), measurements))
        / (2 * h)
        for e in np.eye(9)
    ])
    np.testing.assert_allclose(J, numeric, rtol=1e-7, atol=1e-9)


def test_theta_jacobian_matches_casadi_automatic_derivative(measurements, theta):
    import casadi as ca

    r = casadi_norm_residual()
    x = ca.SX.sym("x", 9)
    a = ca.SX.sym("a", 3)
    dr = ca.Function("dr", [x, a], [ca.jacobian(r(x, a), x)])
    T, o = unpack_theta(theta)
    J = norm_residual_jacobian(T, o, measurements)
    for k in (0, 17, 39):
        np.testing.assert_allclose(np.asarray(dr(theta, measurements[k])).ravel(), J[k], rtol=1e-12, atol=1e-15)
        assert float(r(theta, measurements[k])) == pytest.approx(norm_residuals(T, o, measurements[k:k + 1])[0], abs=1e-15)
    np.testing.assert_array_equal(np.asarray(casadi_lower_triangular(ca.DM(theta[:6]))), T)


def test_full_jacobian_is_the_theta_jacobian_plus_the_upper_entries(measurements, theta):
    """The paper's x = [vec(T), o] (gradient descent) and θ share their columns; the upper entries
    of T are the extra three, and the derivative holds for a full T as well (finite differences)."""
    kernel = NormResidualKernel(measurements)
    T, o = unpack_theta(theta)
    point = kernel.at(T, o)
    full, J = point.jacobian_full(), point.jacobian()
    np.testing.assert_array_equal(full[[0, 3, 4, 6, 7, 8]], J[:6])
    np.testing.assert_array_equal(full[9:], J[6:])
    x = np.concatenate([(T + np.triu(np.full((3, 3), 0.03), 1)).ravel(), o])
    h = 1e-6
    numeric = np.stack([(kernel.at_full(x + h * e).residuals - kernel.at_full(x - h * e).residuals) / (2 * h)
                        for e in np.eye(12)])
    np.testing.assert_allclose(kernel.at_full(x).jacobian_full(), numeric, rtol=1e-7, atol=1e-9)


def test_theta_and_full_parameterisations_evaluate_the_same_point(measurements, theta):
    kernel = NormResidualKernel(measurements)
    T, o = unpack_theta(theta)
    a = kernel.at_theta(theta_from(T, o))
    b = kernel.at_full(np.concatenate([T.ravel(), o]))
    np.testing.assert_array_equal(a.residuals, b.residuals)
    np.testing.assert_array_equal(a.direction, b.direction)
