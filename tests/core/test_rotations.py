"""Rotations written once (optcal.core.rotations): orthonormality, known rotations, exp/log round trip."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.core.rotations import (
    SMALL_ANGLE_SQ,
    axis_rotation,
    exponential_map,
    exponential_map_with_right_jacobian,
    gravity_direction,
    logarithm_map,
    quaternion_from_axis_angle,
    quaternion_to_matrix,
    roll_pitch,
    rotate_about_axis,
    rotation_between,
    skew,
    turntable_attitude,
)


def random_rotation_vectors(n: int, seed: int = 0) -> np.ndarray:
    """Rotation vectors with angles from 1e-9 rad (the Taylor branch) up to nearly π."""
    rng = np.random.default_rng(seed)
    axes = rng.standard_normal((n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([np.geomspace(1e-9, 1e-3, n // 2), rng.uniform(1e-3, np.pi - 1e-3, n - n // 2)])
    return axes * angles[:, None]


def assert_rotations(R: np.ndarray) -> None:
    eye = np.broadcast_to(np.eye(3), R.shape)
    np.testing.assert_allclose(np.swapaxes(R, -1, -2) @ R, eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)


def test_skew_is_the_cross_product() -> None:
    rng = np.random.default_rng(1)
    v, w = rng.standard_normal((2, 5, 3))
    np.testing.assert_allclose((skew(v) @ w[:, :, None])[:, :, 0], np.cross(v, w), atol=1e-15)
    np.testing.assert_array_equal(skew(v), -np.swapaxes(skew(v), -1, -2))


def test_exponential_map_gives_orthonormal_matrices_and_inverts_the_logarithm() -> None:
    theta = random_rotation_vectors(200)
    R = exponential_map(theta)
    assert_rotations(R)
    np.testing.assert_allclose(logarithm_map(R), theta, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(exponential_map(logarithm_map(R)), R, atol=1e-14)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_known_rotations_about_the_coordinate_axes(axis: int) -> None:
    e = np.eye(3)
    quarter = exponential_map(np.pi / 2 * e[axis])
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    np.testing.assert_allclose(quarter @ e[i], e[j], atol=1e-15)  # x → y about z, y → z about x, z → x about y
    np.testing.assert_allclose(quarter @ e[axis], e[axis], atol=1e-15)
    for angle in (-2.0, 0.3, np.pi):
        np.testing.assert_allclose(axis_rotation(axis, angle), exponential_map(angle * e[axis]), atol=1e-15)
    np.testing.assert_allclose(exponential_map(np.pi * e[axis]), 2 * np.outer(e[axis], e[axis]) - np.eye(3), atol=1e-15)


def test_single_vector_and_rows_agree_bit_for_bit() -> None:
    theta = random_rotation_vectors(20, seed=2)
    rows = exponential_map(theta)
    for k, t in enumerate(theta):
        np.testing.assert_array_equal(exponential_map(t), rows[k])
    E, _ = exponential_map_with_right_jacobian(theta)
    np.testing.assert_array_equal(E, rows)


def test_the_jacobian_series_for_small_angles_has_no_seam() -> None:
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    below, above = np.sqrt(SMALL_ANGLE_SQ) * np.array([1 - 1e-9, 1 + 1e-9])
    _, Jr = exponential_map_with_right_jacobian(np.outer([below, above], axis))
    np.testing.assert_allclose(Jr[0], Jr[1], atol=1e-13)
    E, Jr = exponential_map_with_right_jacobian(np.zeros((1, 3)))
    np.testing.assert_array_equal(E[0], np.eye(3))
    np.testing.assert_array_equal(Jr[0], np.eye(3))


def test_right_jacobian_is_the_derivative_of_the_transposed_rotation() -> None:
    # d(exp([θ]×)ᵀ v)/dθ = exp([θ]×)ᵀ [v]× J_r(−θ)
    rng = np.random.default_rng(3)
    v = rng.standard_normal(3)
    for theta in (rng.standard_normal(3), 1e-6 * rng.standard_normal(3)):
        E, Jr = exponential_map_with_right_jacobian(theta)
        analytic = E[0].T @ skew(v) @ Jr[0]
        step = 1e-6
        numeric = np.column_stack([
            (exponential_map(theta + step * e).T @ v - exponential_map(theta - step * e).T @ v) / (2 * step)
            for e in np.eye(3)
        ])
        np.testing.assert_allclose(analytic, numeric, atol=1e-9)


def test_rotating_a_vector_is_applying_the_exponential_map() -> None:
    rng = np.random.default_rng(4)
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    v = rng.standard_normal(3)
    angles = np.linspace(-3.0, 3.0, 13)
    expected = np.array([exponential_map(a * axis) @ v for a in angles])
    np.testing.assert_allclose(rotate_about_axis(axis, angles, v), expected, atol=1e-14)


def test_rotation_between_takes_one_direction_onto_the_other() -> None:
    rng = np.random.default_rng(5)
    a, b = rng.standard_normal((2, 50, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    for u, w in zip(a, b):
        R = rotation_between(u, w)
        assert_rotations(R)
        np.testing.assert_allclose(R @ u, w, atol=1e-14)
        np.testing.assert_allclose(R @ np.cross(u, w), np.cross(u, w), atol=1e-14)  # about their common normal
    z = np.array([0.0, 0.0, 1.0])
    np.testing.assert_array_equal(rotation_between(z, z), np.eye(3))
    np.testing.assert_array_equal(rotation_between(-z, z) @ -z, z)


def test_quaternions_match_the_exponential_map() -> None:
    theta = random_rotation_vectors(30, seed=6)
    for t in theta:
        angle = np.linalg.norm(t)
        R = quaternion_to_matrix(quaternion_from_axis_angle(angle, t / angle))
        assert_rotations(R)
        np.testing.assert_allclose(R, exponential_map(t), atol=1e-14)
    # a quaternion is normalised before use, and q and −q are the same rotation
    q = np.array([2.0, -1.0, 0.5, 3.0])
    np.testing.assert_allclose(quaternion_to_matrix(q), quaternion_to_matrix(-q / 7.0), atol=1e-15)


def test_turntable_attitude_is_a_rotation_with_the_gimbal_order_of_sun2011() -> None:
    rng = np.random.default_rng(7)
    pitch, roll, heading = rng.uniform(-np.pi, np.pi, (3, 10))
    C = turntable_attitude(pitch, roll, heading)
    assert C.shape == (10, 3, 3)
    assert_rotations(C)
    expected = axis_rotation(2, -heading) @ axis_rotation(0, pitch) @ axis_rotation(1, roll)
    np.testing.assert_array_equal(C, expected)
    # level and facing north: the body axes are east, north, up
    np.testing.assert_array_equal(turntable_attitude(0.0, 0.0, 0.0), np.eye(3))


def test_roll_pitch_inverts_the_gravity_direction() -> None:
    rng = np.random.default_rng(8)
    roll = rng.uniform(-np.pi, np.pi, 100)
    pitch = rng.uniform(-np.pi / 2 + 1e-6, np.pi / 2 - 1e-6, 100)
    f = gravity_direction(roll, pitch)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 1.0, atol=1e-15)
    r, p = roll_pitch(3.0 * f)  # any length
    np.testing.assert_allclose(r, roll, atol=1e-12)
    np.testing.assert_allclose(p, pitch, atol=1e-12)
    # level, z up; and the specific force of a body pitched nose-up by 90°: along −x
    np.testing.assert_array_equal(gravity_direction(0.0, 0.0), [-0.0, 0.0, 1.0])
    np.testing.assert_allclose(gravity_direction(0.0, np.pi / 2), [-1.0, 0.0, 0.0], atol=1e-16)


def test_exponential_map_is_scipys_rotation_at_every_angle() -> None:
    """Rodrigues' formula (numpy, with its series below SMALL_ANGLE_SQ) against scipy's Rotation.from_rotvec,
    from 1e-9 rad to nearly π, alone and with the right Jacobian."""
    from scipy.spatial.transform import Rotation

    from optcal.core.rotations import exponential_map, exponential_map_with_right_jacobian

    rng = np.random.default_rng(0)
    for scale in (1e-9, 1e-5, 1e-3, 0.1, 1.0, 3.1):
        theta = rng.normal(size=(50, 3)) * scale
        reference = Rotation.from_rotvec(theta).as_matrix()
        assert np.abs(exponential_map(theta) - reference).max() < 1e-15
        assert np.abs(exponential_map_with_right_jacobian(theta)[0] - reference).max() < 1e-15
    assert exponential_map([0.1, 0.2, 0.3]).shape == (3, 3)
