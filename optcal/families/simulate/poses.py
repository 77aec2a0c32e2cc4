"""Simulation of static calibration data from a lumped model.

Orientation schedules give unit specific-force directions ``ā_k`` in the sensor frame;
:func:`simulate_poses` turns them into a :class:`~optcal.core.poses.PoseTable` through
``a_k = C ā_k + o + n_k`` (Lu 2017, eq. 5) with white noise per pose or per sample.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.model import LumpedModel
from optcal.core.poses import PoseTable
from optcal.core.rotations import (
    PARALLEL_SINE,
    gravity_direction,
    quaternion_from_axis_angle,
    quaternion_to_matrix,
    roll_pitch,
    rotation_between,
)

#: Specific force at rest, navigation frame, z up, in g (the accelerometer feels +1 g up).
GRAVITY_UP: NDArray[np.float64] = np.array([0.0, 0.0, 1.0])


def directions_from_rotations(rotations: Sequence[ArrayLike]) -> NDArray[np.float64]:
    """Sensor-frame directions ``ā_k = R_kᵀ g_up`` for body-to-navigation rotations ``R_k``."""
    return np.array([np.asarray(R, float).T @ GRAVITY_UP for R in rotations])


def lu2017_sweeps(n_per_axis: int = 40, include_endpoint: bool = False) -> NDArray[np.float64]:
    """The paper's schedule, literally: rotations about z, x, y with θ from 0 to 2π.

    Lu 2017, section 3.1: quaternions ``q = [cos(θ/2), sin(θ/2) uᵀ]`` with
    u = [0,0,1], [1,0,0], [0,1,0] and θ swept from 0 to 2π, each sweep starting from the
    level attitude.  Note that the z sweep leaves gravity on the z axis (every pose of that
    sweep is the same), and the x and y sweeps keep gravity in the planes x = 0 and y = 0
    of the sensor frame; see :mod:`optcal.core.identifiability` for what that does.
    """
    thetas = np.linspace(0.0, 2 * np.pi, n_per_axis, endpoint=include_endpoint)
    rots = [quaternion_to_matrix(quaternion_from_axis_angle(t, u)) for u in ([0, 0, 1], [1, 0, 0], [0, 1, 0]) for t in thetas]
    return directions_from_rotations(rots)


def tilted_sweeps(n_per_axis: int = 40, tilt_deg: float = 35.0) -> NDArray[np.float64]:
    """Three full sweeps about tilted axes: the paper's procedure made identifying.

    Each sweep turns the sensor through 2π about one of the body axes, as in Lu 2017,
    but starting from an attitude tilted by ``tilt_deg`` about a different axis, so that
    gravity traces three small circles that are not confined to coordinate planes.
    """
    thetas = np.linspace(0.0, 2 * np.pi, n_per_axis, endpoint=False)
    tilt = np.deg2rad(tilt_deg)
    rots: list[NDArray[np.float64]] = []
    for u, v in (([0, 0, 1], [1, 1, 0]), ([1, 0, 0], [0, 1, 1]), ([0, 1, 0], [1, 0, 1])):
        R0 = quaternion_to_matrix(quaternion_from_axis_angle(tilt, v))
        rots.extend(R0 @ quaternion_to_matrix(quaternion_from_axis_angle(t, u)) for t in thetas)
    return directions_from_rotations(rots)


def uniform_directions(n: int, rng: np.random.Generator | int | None = None) -> NDArray[np.float64]:
    """``n`` directions drawn uniformly on the unit sphere."""
    rng = np.random.default_rng(rng)
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def cap_directions(
    n: int, cap_deg: float, rng: np.random.Generator | int | None = None, axis: ArrayLike = (0, 0, 1)
) -> NDArray[np.float64]:
    """``n`` directions uniform on a spherical cap of half-angle ``cap_deg`` about ``axis``."""
    rng = np.random.default_rng(rng)
    cmin = np.cos(np.deg2rad(cap_deg))
    z = rng.uniform(cmin, 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z**2)
    d = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    if np.allclose(a, [0, 0, 1]):
        return d
    if np.linalg.norm(np.cross(GRAVITY_UP, a)) < PARALLEL_SINE:  # the cap about −z: the cap about +z turned over
        return -d
    return d @ rotation_between(GRAVITY_UP, a).T


def six_position() -> NDArray[np.float64]:
    """The six faces of a cube: ±x, ±y, ±z up (Yin 2014, Table 2)."""
    return np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)


def user_directions(values: ArrayLike, kind: str = "directions") -> NDArray[np.float64]:
    """Directions from user-given orientations.

    Parameters
    ----------
    values : array_like
        ``kind="directions"``: (n, 3) vectors (normalised here); ``kind="quaternions"``:
        (n, 4) ``[w, x, y, z]``; ``kind="euler_deg"``: (n, 2) or (n, 3) roll, pitch[, yaw]
        in degrees (roll about x then pitch about y).
    """
    v = np.asarray(values, dtype=float)
    if kind == "directions":
        if v.ndim != 2 or v.shape[1] != 3:
            raise InputError("directions must have shape (n, 3)")
        norms = np.linalg.norm(v, axis=1, keepdims=True)
        if np.any(norms == 0):
            raise InputError("a direction of zero length was given")
        return v / norms
    if kind == "quaternions":
        if v.ndim != 2 or v.shape[1] != 4:
            raise InputError("quaternions must have shape (n, 4), [w, x, y, z]")
        return directions_from_rotations([quaternion_to_matrix(q) for q in v])
    if kind == "euler_deg":
        if v.ndim != 2 or v.shape[1] not in (2, 3):
            raise InputError("euler angles must have shape (n, 2) or (n, 3): roll, pitch[, yaw] in degrees")
        # specific force of a level platform seen in a body rolled by r and pitched by p
        return gravity_direction(np.deg2rad(v[:, 0]), np.deg2rad(v[:, 1]))
    raise InputError(f"unknown orientation kind {kind!r}")


def angles_from_directions(directions: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Roll and pitch in degrees of unit specific-force directions: the inverse of ``user_directions(..., "euler_deg")``.

    :func:`optcal.core.rotations.roll_pitch` of the directions (Yin 2014, eq. 2).
    """
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    roll, pitch = roll_pitch(d / np.linalg.norm(d, axis=1, keepdims=True))
    return np.degrees(roll), np.degrees(pitch) + 0.0  # + 0.0: no "-0" in the table


SCHEDULES = ("lu2017", "tilted", "uniform", "sixpos")


def schedule(name: str, n: int, rng: np.random.Generator | int | None = None) -> NDArray[np.float64]:
    """Directions of a named schedule with about ``n`` poses.

    ``lu2017`` (literal paper sweeps, n/3 per axis), ``tilted`` (paper sweeps about tilted
    axes), ``uniform`` (random on the sphere), ``sixpos`` (the six cube faces, n ignored).
    """
    if name == "lu2017":
        return lu2017_sweeps(max(1, n // 3))
    if name == "tilted":
        return tilted_sweeps(max(1, n // 3))
    if name == "uniform":
        return uniform_directions(n, rng)
    if name == "sixpos":
        return six_position()
    raise InputError(f"unknown schedule {name!r}; use one of {', '.join(SCHEDULES)}")


def simulate_poses(
    model: LumpedModel,
    directions: ArrayLike,
    sigma: float | ArrayLike = 0.0,
    *,
    noise: str = "pose",
    samples_per_pose: int = 1,
    rng: np.random.Generator | int | None = None,
    units: str = "g",
    t: ArrayLike | None = None,
    temp: ArrayLike | None = None,
) -> PoseTable:
    """Simulate a pose table ``a_k = C ā_k + o + n_k`` (Lu 2017, eq. 5).

    Parameters
    ----------
    model : LumpedModel
        The sensor.
    directions : array_like, shape (n, 3)
        Unit specific-force directions in the sensor frame.
    sigma : float or array_like, shape (n,)
        White-noise standard deviation, raw units: of each pose mean (``noise="pose"``) or
        of each raw sample (``noise="sample"``, averaged over ``samples_per_pose``).
    noise : {"pose", "sample"}
    samples_per_pose : int
        Samples averaged per pose for ``noise="sample"``.
    rng : Generator or int, optional
        Seed or generator.
    units : str
        Units recorded in the table.
    t, temp : array_like, optional
        Pose times and temperatures to record.

    Returns
    -------
    PoseTable
        With ``sigma`` set to the standard deviation of each pose mean (omitted when 0).
    """
    rng = np.random.default_rng(rng)
    d = user_directions(directions)
    n = d.shape[0]
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (n,)).copy()
    if np.any(sig < 0):
        raise InputError("noise sigma must be non-negative")
    clean = model.measure(d)
    if noise == "pose":
        acc = clean + rng.standard_normal((n, 3)) * sig[:, None]
        pose_sigma = sig
        counts = None
    elif noise == "sample":
        if samples_per_pose < 1:
            raise InputError("samples_per_pose must be at least 1")
        acc = clean + rng.standard_normal((n, samples_per_pose, 3)).mean(axis=1) * sig[:, None]
        pose_sigma = sig / np.sqrt(samples_per_pose)
        counts = np.full(n, samples_per_pose, dtype=float)
    else:
        raise InputError("noise must be 'pose' or 'sample'")
    return PoseTable(
        acc=acc,
        sigma=pose_sigma if np.all(pose_sigma > 0) else None,
        n_samples=counts,
        t=None if t is None else np.asarray(t, dtype=float),
        temp=None if temp is None else np.asarray(temp, dtype=float),
        units=units,
        source="simulation",
        extra={"true_dx": d[:, 0], "true_dy": d[:, 1], "true_dz": d[:, 2]},
    )
