"""The motion of a simulated recording: rests and turns, sample by sample, with the truth kept.

Every simulated raw recording is built here: the accelerometer recordings of
:func:`optcal.families.simulate.recording.synthesize_recording` (and, on top of them, the
recordings with a hidden effect of :mod:`optcal.families.simulate.effects`), and the IMU
recordings of :func:`optcal.families.simulate.gyro.simulate_imu`.  A :class:`MotionBuilder`
appends segments sample by sample: a rest in one orientation (:meth:`MotionBuilder.rest`: the
specific force constant, the body rate zero, the sample range kept as the truth), and moves
(:meth:`MotionBuilder.move`) whose specific force follows from the body rate, in closed form
for a turn about a body-fixed axis (:func:`turn`) or integrated (:func:`integrate_attitude`).
The simulators then apply their sensor models to the specific force and the rate of the
finished :class:`Motion`, and add noise: :func:`white_noise`, or a first-order Gauss–Markov
process (:func:`gauss_markov`).

Kinematics (sensor frame)
-------------------------
A world-fixed vector seen from the body obeys ``u̇ = −ω × u``; the specific force at rest
``f`` (unit, in g) is one.  A turn through the angle ``φ(t)`` about the fixed body axis ``n``
has the body rate ``ω = φ̇ n`` and moves the specific force as ``f(t) = Rot(n, −φ(t)) f(0)``
(Rodrigues' rotation of a vector).  The attitude ``R`` (world ← body) obeys ``Ṙ = R [ω×]``.
Translational acceleration is neglected: the sensor turns about its own centre.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.rotations import rotate_about_axis, skew

#: Below this ``‖d₀ × d₁‖`` two directions are the same or opposite, and a turn between them
#: goes about any perpendicular axis (:func:`axis_between`).
SAME_DIRECTION_SINE: float = 1e-9


@dataclass
class Motion:
    """The true motion of a recording, sample by sample.

    Attributes
    ----------
    specific_force : ndarray, shape (n, 3)
        Specific force in the sensor frame, g (unit at rest).
    rate : ndarray, shape (n, 3)
        Body rate in the sensor frame, rad/s.
    rests : list of (int, int)
        Sample range ``[start, stop)`` of each rest (the sensor exactly still).
    rest_directions : list of ndarray
        Specific force of each rest.
    slow : list of (int, int)
        Sample ranges of the moves marked slow.
    """

    specific_force: NDArray[np.float64]
    rate: NDArray[np.float64]
    rests: list[tuple[int, int]] = field(default_factory=list)
    rest_directions: list[NDArray[np.float64]] = field(default_factory=list)
    slow: list[tuple[int, int]] = field(default_factory=list)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.specific_force.shape[0])

    def moving(self) -> NDArray[np.bool_]:
        """Samples in no rest and in no slow move."""
        moving = np.ones(self.n, dtype=bool)
        for a, b in self.rests + self.slow:
            moving[a:b] = False
        return moving


class MotionBuilder:
    """Appends rests and moves, sample by sample, and keeps where each rest lies (module docstring)."""

    def __init__(self) -> None:
        self._forces: list[NDArray[np.float64]] = []
        self._rates: list[NDArray[np.float64]] = []
        self.n = 0
        self.rests: list[tuple[int, int]] = []
        self.rest_directions: list[NDArray[np.float64]] = []
        self.slow: list[tuple[int, int]] = []

    def rest(self, direction: NDArray[np.float64], samples: int) -> None:
        """``samples`` samples at rest with the specific force ``direction``."""
        self._forces.append(np.tile(direction, (samples, 1)))
        self._rates.append(np.zeros((samples, 3)))
        self.rests.append((self.n, self.n + samples))
        self.rest_directions.append(direction)
        self.n += samples

    def move(self, specific_force: NDArray[np.float64], rate: NDArray[np.float64], slow: bool = False) -> None:
        """A move, given sample by sample (each (m, 3)); ``slow`` marks it in :attr:`Motion.slow`."""
        m = specific_force.shape[0]
        self._forces.append(specific_force)
        self._rates.append(rate)
        if slow:
            self.slow.append((self.n, self.n + m))
        self.n += m

    def finish(self) -> Motion:
        """The motion built so far."""
        return Motion(np.concatenate(self._forces), np.concatenate(self._rates), list(self.rests),
                      list(self.rest_directions), list(self.slow))


def turn(
    start: NDArray[np.float64], axis: NDArray[np.float64], angles: NDArray[np.float64], rates: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A turn about the fixed unit body ``axis``: the specific force and body rate at each sample.

    Parameters
    ----------
    start : ndarray, shape (3,)
        Specific force when the turn starts.
    axis : ndarray, shape (3,)
    angles, rates : ndarray, shape (m,)
        Angle turned (rad) and its rate (rad/s) at each sample.

    Returns
    -------
    specific_force, rate : ndarray, shape (m, 3)
        ``Rot(axis, −φ) start`` and ``φ̇ axis`` (module docstring).
    """
    return rotate_about_axis(axis, -angles, start), rates[:, None] * axis


def axis_between(
    d0: NDArray[np.float64], d1: NDArray[np.float64], rng: np.random.Generator
) -> tuple[NDArray[np.float64], float]:
    """The unit axis and the angle of the shortest turn taking the direction ``d0`` onto ``d1``.

    For the same or opposite directions any perpendicular axis, drawn from ``rng``.
    """
    cross = np.cross(d0, d1)
    angle = float(np.arctan2(np.linalg.norm(cross), np.dot(d0, d1)))
    if np.linalg.norm(cross) < SAME_DIRECTION_SINE:  # same or opposite direction: any perpendicular axis
        return random_perpendicular(d0, rng), angle
    return cross / np.linalg.norm(cross), angle


def random_perpendicular(d: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
    """A random unit vector perpendicular to ``d`` (``d × n`` for a standard normal ``n`` drawn from ``rng``, normalised)."""
    perp = np.cross(d, rng.standard_normal(3))
    out: NDArray[np.float64] = perp / np.linalg.norm(perp)
    return out


def half_cosine_profile(m: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``s(τ) = (1 − cos πτ)/2`` at the mid-points of ``m`` samples, and ``ds/dτ``: 0 to 1, at rest at both ends."""
    tau = (np.arange(m) + 0.5) / m
    return 0.5 * (1 - np.cos(np.pi * tau)), 0.5 * np.pi * np.sin(np.pi * tau)


def raised_cosine_turn(
    angle: float, duration_s: float, tau: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Angle turned and its rate for a turn by ``angle`` in ``duration_s`` with the speed ``∝ 1 − cos 2πτ``.

    ``τ = t / duration_s`` in [0, 1]; the rate is ``(angle/T)(1 − cos 2πτ)`` and the angle
    ``angle (τ − sin(2πτ)/2π)``, both zero at the start, the rate zero at the end.
    """
    rate = angle / duration_s * (1 - np.cos(2 * np.pi * tau))
    return angle * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi)), rate


def integrate_attitude(
    start: NDArray[np.float64],
    rate: Callable[[float], NDArray[np.float64]],
    duration_s: float,
    times: ArrayLike,
) -> NDArray[np.float64]:
    """The attitude ``R(t)`` (world ← body) from ``Ṙ = R [ω(t)×]`` at ``times``, shape (len(times), 3, 3).

    Integrated from ``R(0) = start`` by scipy's adaptive DOP853 at tight tolerance (relative
    1e-12, absolute 1e-13), independently of any estimator's integrator.
    """
    from scipy.integrate import solve_ivp

    def derivative(t: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
        return (y.reshape(3, 3) @ skew(rate(t))).ravel()

    solution = solve_ivp(derivative, (0.0, duration_s), start.ravel(), method="DOP853", rtol=1e-12, atol=1e-13,
                         t_eval=times)
    return solution.y.T.reshape(-1, 3, 3)


def white_noise(rng: np.random.Generator, sd: float, shape: int | tuple[int, ...]) -> NDArray[np.float64]:
    """Independent normal noise of standard deviation ``sd``, drawn from ``rng``."""
    return sd * rng.standard_normal(shape)


def gauss_markov(shape: tuple[int, int], dt: float, sigma: float, correlation_s: float,
                 rng: np.random.Generator) -> NDArray[np.float64]:
    """First-order Gauss–Markov noise (stationary, standard deviation ``sigma``) along axis 0.

    ``x_{k+1} = φ x_k + σ √(1 − φ²) w_k`` with ``φ = exp(−dt/τ_c)`` (the discretised
    exponentially correlated process; IEEE Std 952, annex C), started in its stationary law.
    """
    from scipy.signal import lfilter

    phi = float(np.exp(-dt / correlation_s))
    w = white_noise(rng, sigma, shape) * np.sqrt(1 - phi**2)
    w[0] = white_noise(rng, sigma, shape[1])
    return lfilter([1.0], [1.0, -phi], w, axis=0)
