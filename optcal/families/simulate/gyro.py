"""Synthetic IMU recordings with known truth: still poses joined by smooth rotations.

The motion is built by :mod:`optcal.families.simulate.kinematics`, its truth independently of
the estimator's integrator: each move turns the body about one body-fixed axis by a
raised-cosine speed profile (:func:`~optcal.families.simulate.kinematics.raised_cosine_turn`),
so its orientation is known in closed form (``R(t) = R_i exp(φ s(t) [n]×)``), or, with
``wobble``, a transverse oscillation is added and the orientation is integrated by scipy's
adaptive DOP853 at tight tolerance
(:func:`~optcal.families.simulate.kinematics.integrate_attitude`; the estimator uses a
fixed-step exponential map on the samples).  The accelerometer reads ``C R(t)ᵀ ẑ + o``
(specific force of a sensor turned about its own origin, in g), the gyro
``K_g M_g ω + b_g + G_g f``, each with white noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.gyro_model import GyroModel
from optcal.core.model import LumpedModel
from optcal.core.rotations import exponential_map
from optcal.families.simulate.kinematics import (
    MotionBuilder,
    integrate_attitude,
    raised_cosine_turn,
    turn,
    white_noise,
)


@dataclass
class ImuRecording:
    """A synthetic recording and its truth.

    Attributes
    ----------
    t : ndarray, shape (n,)
    acc, gyro : ndarray, shape (n, 3)
        Raw samples (with noise).
    gyro_clean : ndarray, shape (n, 3)
        Raw gyro without noise.
    omega : ndarray, shape (n, 3)
        True body rate, rad/s, accelerometer frame.
    intervals : list of (start, stop)
        The still intervals (sample ranges).
    acc_model : LumpedModel
    gyro_model : GyroModel
    """

    t: NDArray[np.float64]
    acc: NDArray[np.float64]
    gyro: NDArray[np.float64]
    gyro_clean: NDArray[np.float64]
    omega: NDArray[np.float64]
    intervals: list[tuple[int, int]] = field(default_factory=list)
    acc_model: LumpedModel | None = None
    gyro_model: GyroModel | None = None

    @property
    def moving(self) -> NDArray[np.bool_]:
        """Samples outside the still intervals."""
        still = np.zeros(self.t.size, bool)
        for a, b in self.intervals:
            still[a:b] = True
        return ~still


def reference_gyro(scale: float = 1.0, rng: int | np.random.Generator | None = 0) -> GyroModel:
    """A gyro with scales 1-3 % off ``scale``, sensing axes misaligned by about 0.5°, and a bias."""
    gen = np.random.default_rng(rng)
    k = scale * (1 + gen.choice([-1, 1], 3) * gen.uniform(0.01, 0.03, 3))
    axes = np.array([exponential_map(gen.normal(0, np.radians(0.5) / np.sqrt(2), 3))[i] for i in range(3)])
    return GyroModel.from_physical(k, axes, scale * gen.uniform(-0.05, 0.05, 3))


def simulate_imu(
    acc_model: LumpedModel,
    gyro_model: GyroModel,
    n_poses: int = 24,
    *,
    rate_hz: float = 100.0,
    dwell_s: float = 2.0,
    move_s: float = 1.5,
    acc_noise: float = 0.0,
    gyro_noise: float = 0.0,
    axes: ArrayLike | None = None,
    wobble: float = 0.0,
    rng: int | np.random.Generator | None = None,
) -> ImuRecording:
    """Simulate still poses joined by smooth rotations.

    Parameters
    ----------
    acc_model, gyro_model : the true sensors (raw units).
    n_poses : int
        Still poses (``n_poses − 1`` moves).
    rate_hz, dwell_s, move_s : float
        Sampling rate, length of each still interval and of each move (both whole samples).
    acc_noise, gyro_noise : float
        White noise per axis, raw units.
    axes : array_like, shape (k, 3), optional
        Allowed rotation axes in the body (accelerometer) frame: each move turns about a
        random combination of them (default: any axis).  Two axes make a degenerate set.
    wobble : float
        Peak rate (rad/s) of a transverse oscillation added to every move (non-commuting
        motion, integrated by DOP853).
    rng : seed or Generator
    """
    if n_poses < 3:
        raise InputError("n_poses must be at least 3")
    gen = np.random.default_rng(rng)
    dwell = int(round(dwell_s * rate_hz))
    nmove = int(round(move_s * rate_hz))
    dt = 1.0 / rate_hz
    basis = None if axes is None else np.asarray(axes, float).reshape(-1, 3)
    R = exponential_map(gen.normal(size=3))  # world ← body at the first pose
    z = np.array([0.0, 0.0, 1.0])  # specific force at rest points up in the world
    motion = MotionBuilder()
    for pose in range(n_poses):
        motion.rest(R.T @ z, dwell)
        if pose == n_poses - 1:
            break
        axis = gen.normal(size=3) if basis is None else gen.normal(size=basis.shape[0]) @ basis
        axis /= np.linalg.norm(axis)
        angle = gen.uniform(np.radians(60), np.radians(150)) * gen.choice([-1, 1])
        tau = np.arange(1, nmove) / nmove  # interior samples; the ends are the still samples
        if wobble == 0.0:
            # closed form: f = exp(−s [n]×) Rᵀ z
            forces, omega = turn(R.T @ z, axis, *raised_cosine_turn(angle, move_s, tau))
            R = R @ exponential_map(axis * angle)
        else:
            perp = np.cross(axis, gen.normal(size=3))
            perp /= np.linalg.norm(perp)

            def rate(t: float) -> NDArray:
                # the raised-cosine turn about the axis (raised_cosine_turn), and the transverse wobble
                x = t / move_s
                return axis * angle / move_s * (1 - np.cos(2 * np.pi * x)) + perp * wobble * np.sin(2 * np.pi * x) ** 3

            mats = integrate_attitude(R, rate, move_s, np.concatenate([tau * move_s, [move_s]]))
            forces = mats[:-1].transpose(0, 2, 1) @ z
            omega = np.array([rate(x * move_s) for x in tau])
            U, _, Vt = np.linalg.svd(mats[-1])
            R = U @ Vt
        motion.move(forces, omega)
    truth = motion.finish()
    t = np.asarray(np.arange(truth.n) * dt, dtype=np.float64)
    f, omega = truth.specific_force, truth.rate
    acc = acc_model.measure(f) + white_noise(gen, acc_noise, f.shape)
    gyro_clean = gyro_model.measure(omega, f if gyro_model.g_sensitivity is not None else None)
    gyro = gyro_clean + white_noise(gen, gyro_noise, f.shape)
    return ImuRecording(t, acc, gyro, gyro_clean, omega, truth.rests, acc_model, gyro_model)
