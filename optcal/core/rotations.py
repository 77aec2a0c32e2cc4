"""Rotations in three dimensions, written once for every layer.

Conventions
-----------
* Rotation matrices are active and act on column vectors: ``v' = R v``.
* ``[v×]`` is the cross-product matrix, ``[v×] w = v × w`` (:func:`skew`).
* A rotation vector ``θ`` (unit axis times angle, radians) gives the rotation
  ``R = exp([θ]×)`` (:func:`exponential_map`); :func:`logarithm_map` is its inverse.
* Quaternions are ``[w, x, y, z]``, scalar first (Lu 2017, section 3.1).
* The gravity direction of a roll φ and a pitch θ is
  ``f = [−sin θ, cos θ sin φ, cos θ cos φ]`` (Yin 2014, eq. 2): the specific force of a
  level platform seen by a body rolled by φ about x, then pitched by θ about y.
* A three-axis turntable's attitude is ``C_b^n = R_z(−ψ) R_x(θ) R_y(γ)`` (Sun 2011,
  section 1; reproduces its eq. 14): heading ψ on the outer, vertical axis (clockwise
  from north), pitch θ on the middle axis (x), roll γ on the inner axis (y).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Below this squared rotation angle (rad²) the coefficients of the right Jacobian use their Taylor series.
SMALL_ANGLE_SQ: float = 1e-8
#: Below this ``‖a × b‖`` two unit vectors are taken as parallel or opposite (:func:`rotation_between`).
PARALLEL_SINE: float = 1e-12


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """``[v×]`` for vectors of shape (..., 3), shape (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def _series(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
    """For rotation vectors ``θ`` (n, 3): ``α²``, ``c₁ = sin α/α``, ``c₂ = (1 − cos α)/α² = 2 sin²(α/2)/α²`` and
    ``c₃ = (α − sin α)/α³`` (Taylor series below :data:`SMALL_ANGLE_SQ`)."""
    a2 = np.einsum("ni,ni->n", theta, theta)
    small = a2 < SMALL_ANGLE_SQ
    a2_safe = np.where(small, 1.0, a2)
    a = np.sqrt(a2_safe)
    sin, half = np.sin(a), np.sin(0.5 * a)
    c1 = np.where(small, 1.0 - a2 / 6 + a2**2 / 120, sin / a)
    c2 = np.where(small, 0.5 - a2 / 24 + a2**2 / 720, 2.0 * half * half / a2_safe)
    c3 = np.where(small, 1.0 / 6 - a2 / 120 + a2**2 / 5040, (a - sin) / (a2_safe * a))
    return a2, c1, c2, c3


def exponential_map(rotation_vectors: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices ``exp([θ]×)`` of rotation vectors ``θ`` (radians), by Rodrigues' formula
    ``I + (sin α/α)[θ]× + ((1 − cos α)/α²)[θ]×²``, ``α = ‖θ‖`` (:func:`_series`; numpy only: scipy.spatial
    costs 0.2-0.4 s to import, more than a gyro calibration takes).

    Parameters
    ----------
    rotation_vectors : array_like, shape (3,) or (n, 3)

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    given = np.asarray(rotation_vectors, dtype=float)
    theta = given.reshape(-1, 3)
    _, c1, c2, _ = _series(theta)
    return _rodrigues(skew(theta), c1, c2).reshape(given.shape[:-1] + (3, 3))


def _rodrigues(K: NDArray[np.float64], c1: NDArray[np.float64], c2: NDArray[np.float64]) -> NDArray[np.float64]:
    """``I + c₁ K + c₂ K²`` for each ``K = [θ]×`` (n, 3, 3)."""
    R = c1[:, None, None] * K + c2[:, None, None] * (K @ K)
    diagonal = np.arange(3)
    R[:, diagonal, diagonal] += 1.0
    return np.asarray(R)


def exponential_map_with_right_jacobian(
    rotation_vectors: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``exp([θ]×)`` (:func:`exponential_map`) and the right Jacobian ``J_r(−θ)`` for every row of ``θ`` (n, 3).

    ``J_r(−θ) = I + c₂[θ]× + c₃[θ]×² = (1 − c₃α²) I + c₂[θ]× + c₃θθᵀ`` with
    ``c₂ = (1 − cos α)/α²``, ``c₃ = (α − sin α)/α³``, ``α = ‖θ‖`` (:func:`_series`).  The derivative of
    ``exp([θ]×)ᵀ v`` with respect to ``θ`` is ``exp([θ]×)ᵀ [v]× J_r(−θ)`` (used by
    :mod:`optcal.families.gyro.propagation`).

    Returns
    -------
    E, Jr : ndarray, each shape (n, 3, 3)
    """
    theta = np.asarray(rotation_vectors, dtype=float).reshape(-1, 3)
    a2, c1, c2, c3 = _series(theta)
    K = skew(theta)
    Jr = c2[:, None, None] * K + c3[:, None, None] * (theta[:, :, None] * theta[:, None, :])
    diagonal = np.arange(3)
    Jr[:, diagonal, diagonal] += 1 - c3[:, None] * a2[:, None]
    return _rodrigues(K, c1, c2), Jr


def logarithm_map(rotations: ArrayLike) -> NDArray[np.float64]:
    """Rotation vectors ``θ`` with ``exp([θ]×) = R`` (angles in [0, π]), shape (..., 3) for (..., 3, 3).

    For a near-identity ``R ≈ I + [θ×]`` this is the small rotation ``θ``.
    """
    R = np.asarray(rotations, dtype=float)
    from scipy.spatial.transform import Rotation  # on first use: scipy.spatial costs 0.2-0.4 s to import

    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec().reshape(R.shape[:-2] + (3,))


def rotation_angle_deg(R: ArrayLike) -> float:
    """The angle of a rotation matrix, degrees (``arccos((tr R − 1)/2)``)."""
    return float(np.degrees(np.arccos(np.clip((np.trace(np.asarray(R, dtype=float)) - 1.0) / 2.0, -1.0, 1.0))))


def rotate_about_axis(axis: ArrayLike, angles: ArrayLike, vector: ArrayLike) -> NDArray[np.float64]:
    """``vector`` turned about the unit ``axis`` by each of ``angles`` (active), shape (len(angles), 3).

    Rodrigues' rotation of a vector: ``v cos φ + (n × v) sin φ + n (n·v)(1 − cos φ)``.
    """
    n = np.asarray(axis, dtype=float)
    v = np.asarray(vector, dtype=float)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    return v * c + np.cross(n, v) * s + np.outer(1 - c[:, 0], n * np.dot(n, v))


def rotation_between(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """The smallest rotation taking the unit vector ``a`` onto the unit vector ``b``.

    ``R = I + [v×] + [v×]² (1 − c)/s²`` with ``v = a × b``, ``s = ‖v‖``, ``c = a·b``; for
    opposite vectors (``s`` below :data:`PARALLEL_SINE`) a half turn about x, which is one of
    the smallest when ``a`` and ``b`` are ±z.
    """
    v = np.cross(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    s, c = np.linalg.norm(v), float(np.dot(a, b))
    if s < PARALLEL_SINE:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    K = skew(v)
    return np.eye(3) + K + K @ K * ((1 - c) / s**2)


def quaternion_from_axis_angle(angle: float, axis: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternion ``q = [cos(θ/2), sin(θ/2) uᵀ]`` of a turn by ``angle`` about ``axis`` (Lu 2017, section 3.1)."""
    u = np.asarray(axis, dtype=float)
    u = u / np.linalg.norm(u)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * u])


def quaternion_to_matrix(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a quaternion ``[w, x, y, z]`` (normalised here; active, body to navigation)."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def axis_rotation(axis: int, angle: ArrayLike) -> NDArray[np.float64]:
    """Active rotations by ``angle`` (radians) about coordinate axis ``axis`` (0, 1, 2), shape (..., 3, 3)."""
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def turntable_attitude(pitch: ArrayLike, roll: ArrayLike, heading: ArrayLike) -> NDArray[np.float64]:
    """``C_b^n = R_z(−ψ) R_x(θ) R_y(γ)`` of a three-axis turntable (module docstring; Sun 2011, eq. 14).

    Angles in radians; broadcasting shapes give (..., 3, 3).
    """
    return axis_rotation(2, -np.asarray(heading, float)) @ axis_rotation(0, pitch) @ axis_rotation(1, roll)


def gravity_direction(roll: ArrayLike, pitch: ArrayLike) -> NDArray[np.float64]:
    """``f = [−sin θ, cos θ sin φ, cos θ cos φ]`` for roll φ and pitch θ (radians; Yin 2014, eq. 2), shape (..., 3)."""
    r, p = np.asarray(roll, dtype=float), np.asarray(pitch, dtype=float)
    return np.stack([-np.sin(p), np.sin(r) * np.cos(p), np.cos(r) * np.cos(p)], axis=-1)


def roll_pitch(direction: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Roll and pitch (radians) of gravity directions (..., 3), the inverse of :func:`gravity_direction`.

    ``φ = atan2(f_y, f_z)``, ``θ = atan2(−f_x, √(f_y² + f_z²))`` (any length of ``f``; φ = 0
    when the x axis points straight up or down).
    """
    f = np.asarray(direction, dtype=float)
    return np.arctan2(f[..., 1], f[..., 2]), np.arctan2(-f[..., 0], np.hypot(f[..., 1], f[..., 2]))
