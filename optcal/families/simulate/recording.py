"""Synthetic raw recordings with known truth.

:func:`synthesize_recording` turns a :class:`~optcal.core.model.LumpedModel` and a list of
unit specific-force directions (from :mod:`optcal.families.simulate.poses`) into a time series as a
hand-held or turntable calibration produces it: a static dwell in each pose, smooth
rotations between poses, optional slow rotations (a slow creep between two dwells, or a
turn about the vertical that no accelerometer can see), with a gyro signal consistent
with the motion, optional temperature (with an optional temperature coefficient of the
bias), optional shocks and saturation, and the truth kept: which samples are at rest in
which pose, which rotate slowly, which are clipped.

The motion is built by :mod:`optcal.families.simulate.kinematics` (sensor frame): the
specific force at rest is ``f = ā`` (unit, in g).  A rotation through the angle ``φ`` about
the fixed body axis ``n = ā_k × ā_{k+1}/‖·‖`` moves it as ``f(s) = Rot(n, s φ) ā_k``, ``s``
from 0 to 1 along a smooth profile
(:func:`~optcal.families.simulate.kinematics.half_cosine_profile`); the body angular rate is
``ω = −φ ṡ n + ψ̇ f`` (``ψ̇`` a turn about the vertical), which satisfies ``ḟ = −ω × f``.
Translational acceleration is neglected (the sensor turns about its own centre).  The
measurement is ``a = C f + o + n`` (Lu 2017, eq. 5).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.model import LumpedModel
from optcal.core.rotations import rotate_about_axis
from optcal.families.simulate.kinematics import (
    MotionBuilder,
    axis_between,
    half_cosine_profile,
    random_perpendicular,
    turn,
    white_noise,
)
from optcal.families.simulate.poses import user_directions


@dataclass
class SyntheticRecording:
    """A synthetic raw recording and its truth.

    Attributes
    ----------
    frame : pandas.DataFrame
        Columns ``t`` (s), ``ax, ay, az`` (raw units), and when simulated ``gx, gy, gz``
        (``gyro_units``) and ``temp`` (°C).
    model : LumpedModel
        The true sensor.
    directions : ndarray, shape (k, 3)
        True unit specific-force direction of each dwell.
    dwells : ndarray of int, shape (k, 2)
        Sample range ``[start, stop)`` of each dwell (the sensor exactly at rest).
    slow : ndarray of int, shape (m, 2)
        Sample ranges of slow rotations (creeps and turns about the vertical).
    saturated : ndarray of bool
        Samples clipped at full scale.
    sigma : float
        Per-sample white noise of each accelerometer axis, raw units.
    rate_hz : float
    units : str
    gyro_units : str
    meta : dict
        Everything else that was set (gyro bias, temperature coefficient, ...).
    """

    frame: pd.DataFrame
    model: LumpedModel
    directions: NDArray[np.float64]
    dwells: NDArray[np.int64]
    slow: NDArray[np.int64]
    saturated: NDArray[np.bool_]
    sigma: float
    rate_hz: float
    units: str
    gyro_units: str
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return int(len(self.frame))

    def true_pose_means(self) -> NDArray[np.float64]:
        """Noise-free measurement ``C ā_k + o`` of each dwell (at the dwell's mean temperature)."""
        clean = self.model.measure(self.directions)
        coeff = self.meta.get("bias_temp_coeff")
        if coeff is not None and "temp" in self.frame:
            temp = self.frame["temp"].to_numpy()
            t_ref = self.meta["temp_ref"]
            mean_temp = np.array([temp[a:b].mean() for a, b in self.dwells])
            clean = clean + np.outer(mean_temp - t_ref, coeff)
        return clean

    def to_csv(self, path: str, float_format: str = "%.9g") -> None:
        """Write the frame as CSV (``t, ax, ay, az[, gx, gy, gz][, temp]``)."""
        self.frame.to_csv(path, index=False, float_format=float_format)


def synthesize_recording(
    model: LumpedModel,
    directions: ArrayLike,
    *,
    rate_hz: float = 100.0,
    dwell_s: float | tuple[float, float] = 5.0,
    initial_rest_s: float = 0.0,
    transition_s: float | tuple[float, float] = 2.0,
    sigma: float = 0.002,
    gyro: bool = True,
    gyro_sigma_dps: float = 0.1,
    gyro_bias_dps: ArrayLike = (0.5, -0.3, 0.2),
    gyro_units: str = "deg/s",
    yaw_rate_dps: float = 30.0,
    slow_creeps: int = 0,
    slow_turns: int = 0,
    slow_rate_dps: float = 1.0,
    slow_s: float = 8.0,
    temperature: tuple[float, float] | None = None,
    bias_temp_coeff: ArrayLike | None = None,
    shocks: int = 0,
    shock_g: float = 4.0,
    full_scale: float | tuple[float, float] | None = None,
    quantum: float | None = None,
    units: str = "g",
    t0: float = 0.0,
    rng: np.random.Generator | int | None = None,
) -> SyntheticRecording:
    """Simulate a raw calibration recording with known truth.

    Parameters
    ----------
    model : LumpedModel
        The sensor; ``C`` in raw units per g and ``o`` in raw units.
    directions : array_like, shape (k, 3)
        Unit specific-force direction of each static pose, in order (e.g.
        :func:`optcal.families.simulate.poses.tilted_sweeps`).
    rate_hz : float
        Sampling rate.
    dwell_s : float or (float, float)
        Rest in each pose, seconds (or a range drawn uniformly per pose).
    initial_rest_s : float
        Extra rest before the first pose's dwell (IMU-TK's initial rest).
    transition_s : float or (float, float)
        Duration of each rotation between poses.
    sigma : float
        White noise per sample and axis, raw units.
    gyro : bool
        Simulate gyro columns ``gx, gy, gz``.
    gyro_sigma_dps, gyro_bias_dps : float, array_like
        Gyro white noise per sample and constant bias, deg/s.
    gyro_units : {"deg/s", "rad/s"}
    yaw_rate_dps : float
        Peak rate of a turn about the vertical superimposed on each transition (so that the
        gyro sees all three axes move).
    slow_creeps : int
        Number of dwells followed by a slow rotation (``slow_rate_dps`` for ``slow_s``
        about a horizontal axis) into a new pose with its own dwell.
    slow_turns : int
        Number of dwells interrupted by a slow turn about the vertical (the specific force
        does not change; only the gyro sees it).
    slow_rate_dps, slow_s : float
        Rate (constant) and duration of each slow rotation.
    temperature : (float, float), optional
        Start temperature (°C) and drift (°C per second); adds a ``temp`` column.
    bias_temp_coeff : array_like, shape (3,), optional
        Bias change per °C (raw units), relative to the start temperature.
    shocks : int
        Number of short bumps (30 ms, ``shock_g`` g along a random axis) during transitions.
    full_scale : float or (float, float), optional
        Clip every axis to ±full_scale, or to (low, high) (raw units, e.g. (−32768, 32767)
        for a 16-bit converter); the clipped samples are the truth of
        :attr:`SyntheticRecording.saturated`.
    quantum : float, optional
        Round the accelerometer output to multiples of this (1 for integer counts).
    units : {"g", "m/s^2", "counts"}
        Units of the raw output (must match ``model``).
    t0 : float
        Time of the first sample.
    rng : Generator or int, optional

    Returns
    -------
    SyntheticRecording
    """
    rng = np.random.default_rng(rng)
    d = user_directions(directions)
    k = d.shape[0]
    if k < 1:
        raise InputError("at least one direction is needed")
    if gyro_units not in ("deg/s", "rad/s"):
        raise InputError("gyro_units must be 'deg/s' or 'rad/s'")

    def draw(v: float | tuple[float, float]) -> float:
        return float(rng.uniform(*v)) if isinstance(v, tuple) else float(v)

    # pose schedule: (direction, dwell samples); slow creeps insert a new pose after a dwell
    creep_after = set(rng.choice(k, size=min(slow_creeps, k), replace=False).tolist()) if slow_creeps else set()
    turn_in = set(rng.choice(k, size=min(slow_turns, k), replace=False).tolist()) if slow_turns else set()
    motion = MotionBuilder()
    slow_rate = np.deg2rad(slow_rate_dps)
    m_slow = max(1, int(round(slow_s * rate_hz)))

    def rest(direction: NDArray[np.float64], seconds: float) -> None:
        motion.rest(direction, max(1, int(round(seconds * rate_hz))))

    def rotate(d0: NDArray[np.float64], d1: NDArray[np.float64], seconds: float, yaw_dps: float) -> None:
        m = max(2, int(round(seconds * rate_hz)))
        axis, angle = axis_between(d0, d1, rng)
        s, ds = half_cosine_profile(m)
        dt_total = m / rate_hz
        # a turn by −φ s about n (f(s) = Rot(n, φ s) ā_k), plus ψ̇ f, a turn about the vertical (ḟ = −ω × f)
        f, w = turn(d0, axis, -(s * angle), -(angle * ds / dt_total))
        motion.move(f, w + np.deg2rad(yaw_dps) * np.sin(np.pi * s)[:, None] * f)

    def slow_rotation(d0: NDArray[np.float64], about_vertical: bool) -> NDArray[np.float64]:
        if about_vertical:
            f = np.tile(d0, (m_slow, 1))
            motion.move(f, slow_rate * f, slow=True)
            return d0
        perp = random_perpendicular(d0, rng)
        angles = slow_rate * (np.arange(m_slow) + 0.5) / rate_hz
        motion.move(*turn(d0, perp, -angles, np.full(m_slow, -slow_rate)), slow=True)
        return rotate_about_axis(perp, np.array([slow_rate * m_slow / rate_hz]), d0)[0]

    current = d[0]
    for i in range(k):
        if i > 0:
            rotate(current, d[i], draw(transition_s), yaw_rate_dps * rng.choice([-1.0, 1.0]))
        current = d[i]
        seconds = draw(dwell_s) + (initial_rest_s if i == 0 else 0.0)
        if i in turn_in:
            rest(current, seconds / 2)
            slow_rotation(current, about_vertical=True)
            rest(current, seconds / 2)
        else:
            rest(current, seconds)
        if i in creep_after:
            current = slow_rotation(current, about_vertical=False)
            rest(current, draw(dwell_s))

    truth = motion.finish()
    f, w, n = truth.specific_force, truth.rate, truth.n
    t = t0 + np.arange(n) / rate_hz
    # shocks: 30 ms half-sine bumps in the middle of transitions (never in a dwell or slow rotation)
    moving = truth.moving()
    shock_acc = np.zeros((n, 3))
    if shocks:
        candidates = np.flatnonzero(moving)
        width = max(1, int(round(0.03 * rate_hz)))
        for c in rng.choice(candidates, size=min(shocks, candidates.size), replace=False):
            a, b = max(0, c - width // 2), min(n, c - width // 2 + width)
            if not moving[a:b].all():
                continue
            axis = rng.standard_normal(3)
            shock_acc[a:b] += shock_g * np.sin(np.pi * (np.arange(b - a) + 0.5) / (b - a))[:, None] * axis / np.linalg.norm(axis)
    acc = model.measure(f + shock_acc)
    temp = None
    meta: dict[str, Any] = {"gyro_bias_dps": list(np.asarray(gyro_bias_dps, float)), "gyro_sigma_dps": gyro_sigma_dps}
    if temperature is not None:
        temp = temperature[0] + temperature[1] * (t - t0) + white_noise(rng, 0.05, n)
        meta["temp_ref"] = float(temperature[0])
        if bias_temp_coeff is not None:
            coeff = np.asarray(bias_temp_coeff, float).reshape(3)
            acc = acc + np.outer(temp - temperature[0], coeff)
            meta["bias_temp_coeff"] = coeff
    elif bias_temp_coeff is not None:
        raise InputError("bias_temp_coeff needs a temperature profile")
    acc = acc + white_noise(rng, sigma, (n, 3))
    if quantum:
        acc = np.round(acc / quantum) * quantum
    saturated = np.zeros(n, dtype=bool)
    if full_scale is not None:
        low, high = full_scale if isinstance(full_scale, tuple) else (-full_scale, full_scale)
        saturated = np.any((acc <= low) | (acc >= high), axis=1)
        acc = np.clip(acc, low, high)
    frame = pd.DataFrame({"t": t, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]})
    if gyro:
        wg = np.rad2deg(w) + np.asarray(gyro_bias_dps, float) + white_noise(rng, gyro_sigma_dps, (n, 3))
        if gyro_units == "rad/s":
            wg = np.deg2rad(wg)
        frame["gx"], frame["gy"], frame["gz"] = wg[:, 0], wg[:, 1], wg[:, 2]
    if temp is not None:
        frame["temp"] = temp
    return SyntheticRecording(
        frame=frame,
        model=model,
        directions=np.array(truth.rest_directions),
        dwells=np.array(truth.rests, dtype=int),
        slow=np.array(truth.slow, dtype=int).reshape(-1, 2),
        saturated=saturated,
        sigma=float(sigma),
        rate_hz=float(rate_hz),
        units=units,
        gyro_units=gyro_units,
        meta=meta,
    )
