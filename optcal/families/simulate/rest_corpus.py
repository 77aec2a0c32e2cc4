"""A corpus of generated recordings whose rests are known, and the score of a rest detector on it.

Each case is a :class:`~optcal.data.recording.Recording` built in memory, with its truth: the
sample ranges and times of the true rests, the true specific force of each rest, and whether the
recording rests at all.  The motion is built by the kinematics engine of
:mod:`optcal.families.simulate.kinematics` (rests kept by :class:`MotionBuilder`, turns about a
body-fixed axis in closed form by :func:`turn`), one kind of recording per generator:

``hand_held``
    15–30 rests of 1.5–4 s held by hand: white noise whose σ is drawn per rest over a 3× range
    (0.02–0.06 m/s²) and a hand tremor (a few-Hz oscillation of the orientation about a random
    axis, its amplitude drawn per rest); moves of 1–3 s turning by 30–150° with a twist about the
    vertical (peak rates of tens to a couple of hundred °/s).
``turntable``
    A motorised single-axis table: trapezoidal rate profiles (ramp, constant rate, ramp) through
    multiples of 45° between rests of 2.4–2.9 s, quiet noise.
``low_pass``
    A bio-logging tag set down in 6–12 orientations for 14–50 s each, the whole recording passed
    through a 4th-order Butterworth low-pass at 1–5 Hz (forwards and backwards, so without delay)
    as such tags store it.
``holds_only``
    A logger that stores N samples per hold and nothing while the sensor moves: consecutive holds
    differ by a jump, with no motion samples and no time gap (no time column, as
    ../shared/data/ckexplorer-holds).
``slow_turns``
    Never at rest: a continuous turn at 2–30 °/s whose body axis changes every 5–30 s, a third
    of the axes within 2–15° of the vertical (which the accelerometer barely sees).
``slow_drift``
    Never at rest: the orientation drifts at 0.1–1 °/s about one axis for the whole recording.

Every case is drawn once per seed (motion and noise) and rendered in four variants that share
them: with or without the gyro columns, float (m/s², rad/s) or quantised (16-bit counts at ±2 g
and ±250 °/s).  The sampling rate is drawn in 50–400 Hz and the number of rests trimmed so that
a case has at most ``max_samples`` samples (10³–10⁵).  The sensor itself is ideal (unit scale,
no offset, no misalignment): the corpus tests where the rests are, not a calibration.

:func:`score_case` scores a detector's poses against the truth: **recall** (the fraction of the
true rests longer than the detector's minimum dwell matched by exactly one pose lying at least
:data:`INSIDE_FRACTION` inside it), **false rests** (poses inside no true rest, per recording and
per minute; for the never-resting kinds, whether any pose is found) and the **pose error** (the
pose mean against the true specific force, in units of the pose's own standard error of the
mean).  :func:`summarise` tabulates the scores.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from optcal.core.model import EARTH_RATE as EARTH_RATE_RAD_S, STANDARD_GRAVITY
from optcal.core.rotations import rotate_about_axis
from optcal.data.readers import source_from_frame
from optcal.data.recording import Recording, recording_from_source
from optcal.data.static import Segmentation, StaticSettings, detect_static
from optcal.errors import InputError
from optcal.families.simulate.kinematics import (
    Motion,
    MotionBuilder,
    half_cosine_profile,
    random_perpendicular,
    turn,
    white_noise,
)

#: The kinds of recording, in the order of the tables.
KINDS: tuple[str, ...] = ("hand_held", "turntable", "low_pass", "holds_only", "slow_turns", "slow_drift")
#: The kinds that never rest: any pose found in them is a false rest.
NEVER_RESTING: tuple[str, ...] = ("slow_turns", "slow_drift")
#: Sampling rates drawn (uniformly), Hz: from a slow logger to a fast IMU.
RATE_RANGE_HZ: tuple[float, float] = (50.0, 400.0)
#: Largest number of samples of a case unless told otherwise (the number of rests is trimmed to fit).
MAX_SAMPLES: int = 100_000
#: Counts per g of a 16-bit accelerometer at ±2 g full scale (32768 counts for 2 g).
ACC_COUNTS_PER_G: float = 32768.0 / 2.0
#: Counts per °/s of a 16-bit gyro at ±250 °/s full scale.
GYRO_COUNTS_PER_DPS: float = 32768.0 / 250.0
#: The range of a signed 16-bit converter, counts.
INT16_RANGE: tuple[float, float] = (-32768.0, 32767.0)
#: White noise of the gyro per sample and axis, °/s (a MEMS gyro at 50-400 Hz: 0.05-0.15 °/s),
#: drawn per recording; and the largest constant bias of each axis, °/s.
GYRO_NOISE_DPS: tuple[float, float] = (0.05, 0.15)
GYRO_BIAS_DPS: float = 0.5
#: A pose matches a true rest when at least this fraction of its time lies inside the rest.
INSIDE_FRACTION: float = 0.8

# ----------------------------------------------------------------------------- a real gyro's effects
#: g-sensitivity of a MEMS gyro, °/s per g, drawn log-uniformly per recording (datasheets: 0.005 °/s/g for a
#: tactical part, 0.1 °/s/g for the MPU-6050, 0.2 °/s/g for the worst consumer parts); each entry of the 3×3
#: matrix is that level times a uniform draw in ±1 (mostly off-diagonal terms in measured parts).
G_SENSITIVITY_DPS_PER_G: tuple[float, float] = (0.005, 0.2)
#: A bias step after a knock, °/s, drawn log-uniformly (in-run steps of consumer MEMS gyros: 0.01-0.5 °/s), at
#: one to :data:`MAX_BIAS_STEPS` moves of a recording, in a random direction.
BIAS_STEP_DPS: tuple[float, float] = (0.01, 0.5)
MAX_BIAS_STEPS: int = 3
#: A warming gyro's thermal bias drift over the session, °/s (its full change, log-uniform), approached with a
#: time constant drawn in :data:`WARMUP_TAU_S` (a package's thermal time constant, minutes).
THERMAL_DRIFT_DPS: tuple[float, float] = (0.01, 0.2)
WARMUP_TAU_S: tuple[float, float] = (60.0, 600.0)


@dataclass(frozen=True)
class RealGyro:
    """The effects a real MEMS gyro adds to its rate, which the ideal one of the corpus lacks.

    Attributes
    ----------
    g_sensitivity : ndarray, shape (3, 3)
        Rate error per specific force, rad/s per g (``ω_err = G f``).
    step_at : ndarray of int
        Samples from which each bias step holds (inside a move: the knock).
    steps : ndarray, shape (k, 3)
        Each step, rad/s.
    drift : ndarray, shape (3,)
        The thermal drift's full change, rad/s, approached as ``1 − exp(−t / tau_s)``.
    tau_s : float
    latitude_rad : float
        Where the Earth's rate is felt: ``Ω sin φ`` about the vertical, ``Ω cos φ`` about a horizontal axis.
    """

    g_sensitivity: NDArray[np.float64]
    step_at: NDArray[np.int64]
    steps: NDArray[np.float64]
    drift: NDArray[np.float64]
    tau_s: float
    latitude_rad: float

    def rate_error(self, specific_force: NDArray[np.float64], rests: Sequence[tuple[int, int]], rate_hz: float,
                   rng: np.random.Generator) -> NDArray[np.float64]:
        """The rate these effects add, rad/s (n, 3), for the true ``specific_force`` (g, n × 3).

        The Earth's rate about the vertical follows the specific force's direction exactly; its horizontal part
        needs the heading, which the corpus does not keep: each rest takes a random horizontal axis (``rng``),
        the moves none (a few thousandths of a °/s: far below any test's noise).
        """
        n = specific_force.shape[0]
        out = specific_force @ self.g_sensitivity.T
        for at, step in zip(self.step_at, self.steps):
            out[int(at):] += step
        t = np.arange(n) / rate_hz
        out += np.outer(1.0 - np.exp(-t / self.tau_s), self.drift)
        norm = np.maximum(np.linalg.norm(specific_force, axis=1, keepdims=True), 1e-9)
        up = specific_force / norm
        out += EARTH_RATE_RAD_S * np.sin(self.latitude_rad) * up
        for a, b in rests:
            out[a:b] += EARTH_RATE_RAD_S * np.cos(self.latitude_rad) * random_perpendicular(up[a], rng)
        return np.asarray(out)


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def draw_real_gyro(rng: np.random.Generator, motion: Motion) -> RealGyro:
    """Draw a :class:`RealGyro` for ``motion``: its bias steps fall in the moves before randomly chosen rests."""
    level = np.radians(_log_uniform(rng, *G_SENSITIVITY_DPS_PER_G))
    g = level * rng.uniform(-1.0, 1.0, (3, 3))
    starts = [a for a, _ in motion.rests[1:]]
    count = min(len(starts), int(rng.integers(1, MAX_BIAS_STEPS + 1)))
    at = np.sort(rng.choice(starts, size=count, replace=False)).astype(np.int64) - 1 if count else np.zeros(0, np.int64)
    steps = np.array([np.radians(_log_uniform(rng, *BIAS_STEP_DPS)) * _random_direction(rng) for _ in range(count)])
    drift = np.radians(_log_uniform(rng, *THERMAL_DRIFT_DPS)) * _random_direction(rng)
    return RealGyro(g, at, steps.reshape(-1, 3), drift, float(rng.uniform(*WARMUP_TAU_S)),
                    float(np.radians(rng.uniform(-70.0, 70.0))))


@dataclass
class RestCase:
    """One generated recording and its truth.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
    gyro, quantised : bool
        The variant: gyro columns present; samples in 16-bit counts (else m/s² and rad/s).
    recording : Recording
    rest_samples : ndarray of int, shape (k, 2)
        Sample range ``[start, stop)`` of each true rest.
    rest_times : ndarray, shape (k, 2)
        The same in seconds, ``[t_start, t_stop)`` (``t_stop`` one sample period after the last sample).
    rest_force : ndarray, shape (k, 3)
        True specific force of each rest in the recording's units (the held orientation; a hand's
        tremor oscillates about it).
    motion : Motion
        The held motion (specific force in g, body rate in rad/s), rests exactly still.
    specific_force, body_rate : ndarray, shape (n, 3)
        The true specific force (g) and body rate (rad/s) sample by sample, tremor included.
    lowpass_hz : float or None
        Cut-off of the low-pass the recording went through.
    """

    kind: str
    seed: int
    gyro: bool
    quantised: bool
    recording: Recording
    rest_samples: NDArray[np.int64]
    rest_times: NDArray[np.float64]
    rest_force: NDArray[np.float64]
    motion: Motion
    specific_force: NDArray[np.float64]
    body_rate: NDArray[np.float64]
    lowpass_hz: float | None = None

    @property
    def rests(self) -> bool:
        """Whether the recording rests at all."""
        return bool(self.rest_samples.shape[0])

    @property
    def duration_min(self) -> float:
        """Length of the recording, minutes."""
        return self.recording.n / self.recording.rate_hz / 60.0


@dataclass
class SimulatedKind:
    """One draw of a kind (motion and noise), before it is rendered as a variant (:func:`render`).

    Attributes
    ----------
    kind : str
    seed : int
    rate_hz : float
        Sampling rate drawn in :data:`RATE_RANGE_HZ`.
    motion : Motion
        The held motion from :class:`MotionBuilder` (rests exactly still).
    specific_force, body_rate : ndarray, shape (n, 3)
        The true motion, g and rad/s, the hand's tremor included.
    acc_noise : ndarray, shape (n, 3)
        White noise of the accelerometer, m/s² (σ per segment).
    gyro_noise : ndarray, shape (n, 3)
        White noise of the gyro and its constant bias, rad/s.
    lowpass_hz : float or None
        Cut-off of the low-pass every channel goes through (the ``low_pass`` kind).
    time_column : bool
        Whether the logger stores a time column (not the ``holds_only`` kind: the row over the rate).
    gyro_effects : ndarray, shape (n, 3), or None
        The rate a real gyro adds (:class:`RealGyro`), rad/s; None for the ideal gyro.
    real_gyro : RealGyro or None
        The effects drawn.
    """

    kind: str
    seed: int
    rate_hz: float
    motion: Motion
    specific_force: NDArray[np.float64]
    body_rate: NDArray[np.float64]
    acc_noise: NDArray[np.float64]
    gyro_noise: NDArray[np.float64]
    lowpass_hz: float | None = None
    time_column: bool = True
    gyro_effects: NDArray[np.float64] | None = None
    real_gyro: RealGyro | None = None


# ----------------------------------------------------------------------------- motion pieces
def _random_direction(rng: np.random.Generator) -> NDArray[np.float64]:
    v = rng.standard_normal(3)
    return v / np.linalg.norm(v)


def _tilted_axis(d: NDArray[np.float64], angle: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """A unit axis at ``angle`` (rad) from the unit vector ``d``, in a random azimuth about it."""
    return np.cos(angle) * d + np.sin(angle) * random_perpendicular(d, rng)


def _end_of_turn(start: NDArray[np.float64], axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    """The specific force once a :func:`turn` about ``axis`` has gone through ``angle``."""
    return rotate_about_axis(axis, np.array([-angle]), start)[0]


def _hand_move(motion: MotionBuilder, d0: NDArray[np.float64], m: int, rate_hz: float, angle: float,
               twist_dps: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """A turn by ``angle`` about an axis perpendicular to ``d0`` over ``m`` samples (half-cosine speed), with a
    twist about the specific force peaking at ``twist_dps`` (invisible to the accelerometer, as in
    :func:`optcal.families.simulate.recording.synthesize_recording`); returns the direction reached."""
    axis = random_perpendicular(d0, rng)
    s, ds = half_cosine_profile(m)
    f, w = turn(d0, axis, angle * s, angle * ds * rate_hz / m)
    motion.move(f, w + np.deg2rad(twist_dps) * np.sin(np.pi * s)[:, None] * f)
    return _end_of_turn(d0, axis, angle)


def trapezoid(angle: float, rate: float, ramp_s: float, rate_hz: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A trapezoidal rate profile through ``angle`` (rad, > 0): ramp up in ``ramp_s``, constant ``rate`` (rad/s),
    ramp down; the angle turned and its rate at the mid-points of the samples.

    The ramp is shortened to ``angle / rate`` when the turn is too short to reach ``rate`` (a triangle);
    the constant rate is adjusted so that the profile lasts a whole number of samples.
    """
    ramp = min(ramp_s, angle / rate)
    m = max(2, int(round((angle / rate + ramp) * rate_hz)))
    total_s = m / rate_hz
    peak = angle / (total_s - ramp)  # angle = peak (T − ramp)
    t = (np.arange(m) + 0.5) / rate_hz
    up, down = t < ramp, t > total_s - ramp
    angles = peak * (t - ramp / 2)
    angles[up] = peak * t[up] ** 2 / (2 * ramp)
    angles[down] = angle - peak * (total_s - t[down]) ** 2 / (2 * ramp)
    rates = peak * np.minimum(1.0, np.minimum(t, total_s - t) / ramp)
    return np.asarray(angles, dtype=np.float64), np.asarray(rates, dtype=np.float64)


#: What a kind's generator draws: the motion, the white noise σ (m/s²) and sample count of each segment in
#: order, and what else the kind needs (``tremor`` of each rest, ``lowpass_hz``, ``time_column``).
Drawn = tuple[MotionBuilder, list[tuple[float, int]], dict[str, Any]]


def _fits(motion: MotionBuilder, extra: int, max_samples: int) -> bool:
    return motion.n + extra <= max_samples


# ----------------------------------------------------------------------------- the kinds
def _hand_held(rng: np.random.Generator, rate_hz: float, max_samples: int) -> Drawn:
    # White noise per rest and move, m/s² (a 3× range: hands and sensors differ); tremor amplitude of the
    # orientation per rest (rad) and its frequency (Hz, physiological tremor of a held object).
    noise_ms2, tremor_rad, tremor_hz = (0.02, 0.06), (np.radians(0.02), np.radians(0.15)), (3.0, 8.0)
    motion, sigmas = MotionBuilder(), []
    d = _random_direction(rng)
    for i in range(int(rng.integers(15, 31))):
        m_rest = int(round(rng.uniform(1.5, 4.0) * rate_hz))
        m_move = int(round(rng.uniform(1.0, 3.0) * rate_hz)) if i else 0
        if i and not _fits(motion, m_move + m_rest, max_samples):
            break
        if i:
            angle = rng.uniform(np.radians(30), np.radians(150)) * rng.choice([-1.0, 1.0])
            d = _hand_move(motion, d, m_move, rate_hz, angle, rng.uniform(0, 90) * rng.choice([-1.0, 1.0]), rng)
            sigmas.append((rng.uniform(*noise_ms2), m_move))
        motion.rest(d, m_rest)
        sigmas.append((rng.uniform(*noise_ms2), m_rest))
    tremor = [(rng.uniform(*tremor_rad), rng.uniform(*tremor_hz), _random_direction(rng)) for _ in motion.rests]
    return motion, sigmas, {"tremor": tremor}


def _turntable(rng: np.random.Generator, rate_hz: float, max_samples: int) -> Drawn:
    # Quiet noise of a sensor bolted to a table, m/s²; cruise rate °/s; ramp s.
    noise = rng.uniform(0.003, 0.01)
    axis = _random_direction(rng)
    d = _tilted_axis(axis, rng.uniform(np.radians(45), np.radians(90)), rng)  # the table's axis is not vertical
    motion, sigmas = MotionBuilder(), []
    for i in range(int(rng.integers(12, 31))):
        m_rest = int(round(rng.uniform(2.4, 2.9) * rate_hz))
        angle = np.radians(45.0 * rng.integers(1, 5))
        angles, rates = trapezoid(angle, np.radians(rng.uniform(20, 120)), rng.uniform(0.2, 0.6), rate_hz)
        sign = rng.choice([-1.0, 1.0])
        if i and not _fits(motion, angles.size + m_rest, max_samples):
            break
        if i:
            motion.move(*turn(d, axis, sign * angles, sign * rates))
            d = _end_of_turn(d, axis, sign * angle)
            sigmas.append((noise, angles.size))
        motion.rest(d, m_rest)
        sigmas.append((noise, m_rest))
    return motion, sigmas, {}


def _low_pass(rng: np.random.Generator, rate_hz: float, max_samples: int) -> Drawn:
    # White noise before the filter, m/s² (a tag's accelerometer); the cut-off of its low-pass, Hz.
    noise = rng.uniform(0.02, 0.06)
    motion, sigmas = MotionBuilder(), []
    d = _random_direction(rng)
    for i in range(int(rng.integers(6, 13))):
        m_rest = int(round(rng.uniform(14.0, 50.0) * rate_hz))
        m_move = int(round(rng.uniform(2.0, 6.0) * rate_hz)) if i else 0
        if i >= 2 and not _fits(motion, m_move + m_rest, max_samples):
            break
        if i:
            angle = rng.uniform(np.radians(45), np.radians(180)) * rng.choice([-1.0, 1.0])
            d = _hand_move(motion, d, m_move, rate_hz, angle, rng.uniform(0, 60) * rng.choice([-1.0, 1.0]), rng)
            sigmas.append((noise, m_move))
        motion.rest(d, m_rest)
        sigmas.append((noise, m_rest))
    return motion, sigmas, {"lowpass_hz": float(rng.uniform(1.0, 5.0))}


def _holds_only(rng: np.random.Generator, rate_hz: float, max_samples: int) -> Drawn:
    # The logger's N samples per hold: 1-3 s at the rate (../shared/data/ckexplorer-holds stores 100 samples
    # per hold, 1 s at 100 Hz); white noise m/s².
    n_hold = int(round(rng.uniform(1.0, 3.0) * rate_hz))
    noise = rng.uniform(0.01, 0.04)
    motion, sigmas = MotionBuilder(), []
    for i in range(int(rng.integers(20, 61))):
        if i and not _fits(motion, n_hold, max_samples):
            break
        motion.rest(_random_direction(rng), n_hold)
        sigmas.append((noise, n_hold))
    return motion, sigmas, {"time_column": False}


def _slow_turns(rng: np.random.Generator, rate_hz: float, max_samples: int) -> Drawn:
    # Rate 2-30 °/s (log-uniform), a new body axis every 5-30 s, a third of them 2-15° from the vertical.
    duration = min(rng.uniform(60.0, 240.0), max_samples / rate_hz)
    noise = rng.uniform(0.005, 0.06)
    motion, sigmas = MotionBuilder(), []
    d = _random_direction(rng)
    while motion.n < int(duration * rate_hz):
        m = min(int(round(rng.uniform(5.0, 30.0) * rate_hz)), int(duration * rate_hz) - motion.n)
        m = max(m, 2)
        near_vertical = rng.uniform() < 1 / 3
        tilt = rng.uniform(np.radians(2), np.radians(15)) if near_vertical else np.arccos(rng.uniform(-1, 1))
        axis = _tilted_axis(d, tilt, rng)
        rate = np.exp(rng.uniform(np.log(np.radians(2)), np.log(np.radians(30)))) * rng.choice([-1.0, 1.0])
        angles = rate * (np.arange(m) + 0.5) / rate_hz
        motion.move(*turn(d, axis, angles, np.full(m, rate)))
        d = _end_of_turn(d, axis, rate * m / rate_hz)
        sigmas.append((noise, m))
    return motion, sigmas, {}


def _slow_drift(rng: np.random.Generator, rate_hz: float, max_samples: int) -> Drawn:
    # Drift of the orientation at 0.1-1 °/s (log-uniform) about one random axis.
    m = int(min(rng.uniform(60.0, 240.0), max_samples / rate_hz) * rate_hz)
    noise = rng.uniform(0.005, 0.06)
    d, axis = _random_direction(rng), _random_direction(rng)
    rate = np.exp(rng.uniform(np.log(np.radians(0.1)), np.log(np.radians(1.0)))) * rng.choice([-1.0, 1.0])
    motion = MotionBuilder()
    motion.move(*turn(d, axis, rate * (np.arange(m) + 0.5) / rate_hz, np.full(m, rate)))
    return motion, [(noise, m)], {}


GENERATORS: dict[str, Callable[[np.random.Generator, float, int], Drawn]] = {
    "hand_held": _hand_held, "turntable": _turntable, "low_pass": _low_pass, "holds_only": _holds_only,
    "slow_turns": _slow_turns, "slow_drift": _slow_drift,
}


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise InputError(f"unknown kind of recording {kind!r}; use one of {', '.join(KINDS)}")


def simulate_kind(kind: str, seed: int, max_samples: int = MAX_SAMPLES, real: bool = False) -> SimulatedKind:
    """Draw one case of ``kind`` from ``seed``: rate, motion, tremor and noise (the same for every variant).

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
    max_samples : int
        The number of rests (or the duration) is trimmed so that the case has at most this many samples
        (but a ``low_pass`` case keeps two rests: up to 42,400 samples at 400 Hz).
    real : bool
        Give the gyro a real MEMS gyro's effects (:class:`RealGyro`: g-sensitivity, bias steps after knocks, a
        thermal drift, the Earth's rate), drawn from a stream of their own: the motion and the noise are those of
        the ideal case of the same seed.
    """
    _check_kind(kind)
    if max_samples < 1000:
        raise InputError(f"max_samples must be at least 1000 (a case of 10³-10⁵ samples), got {max_samples}")
    rng = np.random.default_rng([seed, KINDS.index(kind)])
    rate_hz = float(rng.uniform(*RATE_RANGE_HZ))
    builder, sigmas, extra = GENERATORS[kind](rng, rate_hz, max_samples)
    motion = builder.finish()
    f, w = motion.specific_force.copy(), motion.rate.copy()
    for (a, b), (amplitude, hz, axis), d in zip(motion.rests, extra.get("tremor", []), motion.rest_directions):
        # tremor: whole cycles of a sine in the orientation about `axis`, so the rest ends where it began
        cycles = max(1, int(round(hz * (b - a) / rate_hz)))
        phase = 2 * np.pi * cycles * np.arange(b - a) / (b - a)
        f[a:b], w[a:b] = turn(d, axis, amplitude * np.sin(phase), amplitude * 2 * np.pi * cycles * rate_hz / (b - a)
                              * np.cos(phase))
    # the noise σ of each segment (rest or move), in the order they were appended, on its samples
    sigma = np.repeat([sd for sd, _ in sigmas], [m for _, m in sigmas])
    acc_noise = sigma[:, None] * rng.standard_normal((motion.n, 3))
    gyro_sd = np.radians(rng.uniform(*GYRO_NOISE_DPS))
    gyro_noise = white_noise(rng, gyro_sd, (motion.n, 3)) + np.radians(rng.uniform(-GYRO_BIAS_DPS, GYRO_BIAS_DPS, 3))
    effects = real_gyro = None
    if real:
        effects_rng = np.random.default_rng([seed, KINDS.index(kind), 1])
        real_gyro = draw_real_gyro(effects_rng, motion)
        effects = real_gyro.rate_error(f, motion.rests, rate_hz, effects_rng)
    return SimulatedKind(kind, seed, rate_hz, motion, f, w, acc_noise, gyro_noise,
                         lowpass_hz=extra.get("lowpass_hz"), time_column=bool(extra.get("time_column", True)),
                         gyro_effects=effects, real_gyro=real_gyro)


def render(sim: SimulatedKind, gyro: bool, quantised: bool) -> RestCase:
    """The recording of one variant of ``sim``: with or without the gyro, float or 16-bit counts."""
    acc = sim.specific_force * STANDARD_GRAVITY + sim.acc_noise  # m/s²
    rate = sim.body_rate + sim.gyro_noise  # rad/s
    if sim.gyro_effects is not None:
        rate = rate + sim.gyro_effects
    if sim.lowpass_hz is not None:
        from scipy.signal import butter, sosfiltfilt

        sos = butter(4, sim.lowpass_hz, fs=sim.rate_hz, output="sos")
        acc, rate = sosfiltfilt(sos, acc, axis=0), sosfiltfilt(sos, rate, axis=0)
    scale = ACC_COUNTS_PER_G / STANDARD_GRAVITY if quantised else 1.0
    if quantised:
        acc = np.clip(np.round(acc * scale), *INT16_RANGE)
        rate = np.clip(np.round(np.degrees(rate) * GYRO_COUNTS_PER_DPS), *INT16_RANGE)
    n = sim.motion.n
    t = np.arange(n) / sim.rate_hz
    units = "counts" if quantised else "m/s^2"
    name = f"rest corpus: {sim.kind}, seed {sim.seed}, {'gyro' if gyro else 'no gyro'}, {units}"
    rec = Recording(
        t=t, acc=np.ascontiguousarray(acc), gyro=np.ascontiguousarray(rate) if gyro else None, temp=None,
        row=np.arange(1, n + 1, dtype=np.int32), usable=np.ones(n, dtype=bool), units=units,
        units_reason="generated (rest corpus)", gyro_units=("counts" if quantised else "rad/s") if gyro else None,
        rate_hz=sim.rate_hz, time_reason=("time column" if sim.time_column else "no time column: row over the rate"),
        path=name, file_type="generated",
    )
    rests = np.array(sim.motion.rests, dtype=np.int64).reshape(-1, 2)
    force = np.array(sim.motion.rest_directions, float).reshape(-1, 3) * STANDARD_GRAVITY * scale
    return RestCase(sim.kind, sim.seed, gyro, quantised, rec, rests, rests / sim.rate_hz, force, sim.motion,
                    sim.specific_force, sim.body_rate, sim.lowpass_hz)


#: Host stamps in bursts (:func:`render_read`): the logger's host stamps the samples as they arrive, this many
#: at a time with one stamp (a USB or serial buffer), the stamps themselves jittered by a tenth of a burst.
BURST_SAMPLES: int = 8


def render_read(sim: SimulatedKind, gyro: bool, quantised: bool, plain: bool, bursts: bool) -> RestCase:
    """A variant of ``sim`` written as a logger writes it and read back through optcal's reader.

    Parameters
    ----------
    sim : SimulatedKind
    gyro, quantised : bool
        As :func:`render`.
    plain : bool
        Columns named ``t, ax, ay, az, gx, gy, gz`` (no unit in the names: the reader decides the units from
        the data, and the rest model the gyro's); else ``t_s, ax_m_s2 ...`` / ``..._counts``, ``gx_rad_s ...``.
    bursts : bool
        Host stamps in bursts of :data:`BURST_SAMPLES` (the reader's time decision spreads them).
    """
    case = render(sim, gyro, quantised)
    rec = case.recording
    n = rec.n
    t = rec.t.copy()
    if bursts:
        rng = np.random.default_rng([sim.seed, KINDS.index(sim.kind), 2])
        period = BURST_SAMPLES / sim.rate_hz
        arrival = (np.arange(n) // BURST_SAMPLES + 1) * period
        t = arrival + rng.uniform(0.0, 0.1 * period, n // BURST_SAMPLES + 1)[np.arange(n) // BURST_SAMPLES]
    acc_unit = "counts" if quantised else "m_s2"
    gyro_unit = "counts" if quantised else "rad_s"
    names = (["t"] + [f"a{a}" for a in "xyz"] + [f"g{a}" for a in "xyz"]) if plain else \
        (["t_s"] + [f"a{a}_{acc_unit}" for a in "xyz"] + [f"g{a}_{gyro_unit}" for a in "xyz"])
    columns = [t] + [rec.acc[:, j] for j in range(3)]
    if gyro:
        assert rec.gyro is not None
        columns += [rec.gyro[:, j] for j in range(3)]
    frame = pd.DataFrame(dict(zip(names, columns)))
    if not sim.time_column:
        frame = frame.drop(columns=names[0])
    label = (f"rest corpus (read): {sim.kind}, seed {sim.seed}, {'gyro' if gyro else 'no gyro'}, "
             f"{'counts' if quantised else 'float'}, {'plain' if plain else 'named'}{', bursts' if bursts else ''}")
    read = recording_from_source(source_from_frame(frame, label, "csv"),
                                 rate=sim.rate_hz if not sim.time_column else None)
    return RestCase(case.kind, case.seed, gyro, quantised, read, case.rest_samples, case.rest_samples / sim.rate_hz,
                    case.rest_force, case.motion, case.specific_force, case.body_rate, case.lowpass_hz)


#: The variants of the real-sensor corpus (:func:`real_corpus`), ``(gyro, quantised, plain, bursts)``.
REAL_VARIANTS: tuple[tuple[bool, bool, bool, bool], ...] = (
    (True, False, False, False), (True, False, True, False), (True, True, True, False), (True, False, True, True),
    (False, False, True, False),
)


def real_corpus(seeds: Iterable[int], kinds: Sequence[str] = KINDS,
                max_samples: int = MAX_SAMPLES) -> Iterable[tuple[tuple[bool, bool, bool, bool], RestCase]]:
    """Every kind for every seed with a real gyro's effects (:class:`RealGyro`), in the :data:`REAL_VARIANTS`,
    each written and read back (:func:`render_read`)."""
    for kind in kinds:
        _check_kind(kind)
    for kind in kinds:
        for seed in seeds:
            sim = simulate_kind(kind, seed, max_samples, real=True)
            for variant in REAL_VARIANTS:
                yield variant, render_read(sim, *variant)


VARIANTS: tuple[tuple[bool, bool], ...] = ((True, False), (False, False), (True, True), (False, True))
"""The four variants of a case, ``(gyro, quantised)``."""


def rest_corpus(seeds: Iterable[int], kinds: Sequence[str] = KINDS,
                max_samples: int = MAX_SAMPLES) -> Iterable[RestCase]:
    """Every kind for every seed, each in the four :data:`VARIANTS` (generated one at a time)."""
    for kind in kinds:
        _check_kind(kind)
    for kind in kinds:
        for seed in seeds:
            sim = simulate_kind(kind, seed, max_samples)
            for gyro, quantised in VARIANTS:
                yield render(sim, gyro, quantised)


# ----------------------------------------------------------------------------- scoring
@dataclass(frozen=True)
class DetectedPose:
    """A detector's pose: its time span ``[t_start, t_stop)`` in seconds, and optionally its mean and σ of the mean."""

    t_start: float
    t_stop: float
    mean: NDArray[np.float64] | None = None
    sigma: float | None = None


def detected_poses(seg: Segmentation) -> list[DetectedPose]:
    """The poses of a segmentation, each from its first sample to one period after its last."""
    rec = seg.recording
    period = 1.0 / rec.rate_hz
    return [DetectedPose(float(rec.t[iv.start]), float(rec.t[iv.stop - 1]) + period, np.asarray(iv.mean, float),
                         float(iv.sigma)) for iv in seg.intervals]


@dataclass
class CaseScore:
    """A detector's score on one case (:func:`score_case`).

    Attributes
    ----------
    kind, seed, gyro, quantised : the case.
    rests : bool
        Whether the case rests at all.
    duration_min : float
    eligible : int
        True rests longer than the detector's minimum dwell (the recall's denominator).
    recalled : int
        Eligible rests matched by exactly one pose lying at least :data:`INSIDE_FRACTION` inside them.
    split : int
        Eligible rests with two or more poses inside them (not recalled).
    poses : int
        Poses detected.
    false : int
        Poses that lie inside no true rest.
    pose_errors : list of float
        For each recalled pose with a σ: the rms over the axes of (mean − true specific force) / σ.
    outcomes : list of str
        For each true rest in order: ``recalled``, ``missed`` (no pose inside), ``split`` (two or more
        poses inside) or ``short`` (no longer than the minimum dwell: not counted).
    refused : str or None
        The detector's message when it refused the recording (no pose).
    """

    kind: str
    seed: int
    gyro: bool
    quantised: bool
    rests: bool
    duration_min: float
    eligible: int
    recalled: int
    split: int
    poses: int
    false: int
    pose_errors: list[float] = field(default_factory=list)
    outcomes: list[str] = field(default_factory=list)
    refused: str | None = None

    @property
    def recall(self) -> float:
        return self.recalled / self.eligible if self.eligible else float("nan")


def score_case(case: RestCase, poses: Sequence[DetectedPose], min_dwell_s: float,
               refused: str | None = None) -> CaseScore:
    """Score ``poses`` against the truth of ``case`` (module docstring).

    Parameters
    ----------
    case : RestCase
    poses : sequence of DetectedPose
    min_dwell_s : float
        The detector's minimum dwell: true rests no longer than it are not counted in the recall
        (a pose inside one is not false either).
    refused : str, optional
        The detector's message when it refused the recording.
    """
    truth = case.rest_times
    inside = np.full(len(poses), -1)
    for i, p in enumerate(poses):
        span = p.t_stop - p.t_start
        if span <= 0 or not truth.size:
            continue
        overlap = np.clip(np.minimum(truth[:, 1], p.t_stop) - np.maximum(truth[:, 0], p.t_start), 0.0, None)
        best = int(np.argmax(overlap))
        if overlap[best] >= INSIDE_FRACTION * span:
            inside[i] = best
    eligible = (truth[:, 1] - truth[:, 0] > min_dwell_s) if truth.size else np.zeros(0, bool)
    counts = np.bincount(inside[inside >= 0], minlength=truth.shape[0])
    errors = []
    for i, r in enumerate(inside):
        p = poses[i]
        if r < 0 or not eligible[r] or counts[r] != 1 or p.mean is None or not p.sigma:
            continue
        errors.append(float(np.sqrt(np.mean(((p.mean - case.rest_force[r]) / p.sigma) ** 2))))
    return CaseScore(
        kind=case.kind, seed=case.seed, gyro=case.gyro, quantised=case.quantised, rests=case.rests,
        duration_min=case.duration_min, eligible=int(eligible.sum()),
        recalled=int(np.sum(eligible & (counts == 1))), split=int(np.sum(eligible & (counts > 1))),
        poses=len(poses), false=int(np.sum(inside < 0)), pose_errors=errors,
        outcomes=["short" if not ok else "recalled" if c == 1 else "split" if c > 1 else "missed"
                  for ok, c in zip(eligible, counts)],
        refused=refused,
    )


def score_detector(case: RestCase, settings: StaticSettings | None = None) -> CaseScore:
    """Run :func:`optcal.data.static.detect_static` on the case and score its poses (a refusal scores no pose)."""
    s = settings or StaticSettings()
    try:
        seg = detect_static(case.recording, s)
    except InputError as exc:
        return score_case(case, [], s.min_dwell_s, refused=str(exc))
    return score_case(case, detected_poses(seg), s.min_dwell_s)


def summarise(scores: Iterable[CaseScore], by: Sequence[str] = ("kind",)) -> pd.DataFrame:
    """Per group of ``by`` (among ``kind, gyro, quantised``): recall, false rests, pose error.

    Columns: ``recordings``; ``rests`` (eligible), ``recall`` (pooled over the group's rests; NaN for
    the never-resting kinds), ``split``; ``false_per_recording``, ``false_per_min``;
    ``with_pose`` (the fraction of recordings where any pose is found: the false-rest rate of the
    never-resting kinds); ``refused`` (recordings the detector refused); ``pose_error_rms`` and
    ``pose_error_p95`` (the pose error in units of the pose's σ, pooled over the recalled poses).
    """
    rows = []
    frame = pd.DataFrame([{**{k: getattr(s, k) for k in ("kind", "seed", "gyro", "quantised")}, "score": s}
                          for s in scores])
    if frame.empty:
        return pd.DataFrame()
    for key, group in frame.groupby(list(by), sort=False):
        items: list[CaseScore] = list(group["score"])
        eligible = sum(s.eligible for s in items)
        errors = np.array([e for s in items for e in s.pose_errors])
        minutes = sum(s.duration_min for s in items)
        keys = key if isinstance(key, tuple) else (key,)
        rows.append({
            **dict(zip(by, keys)),
            "recordings": len(items),
            "rests": eligible,
            "recall": sum(s.recalled for s in items) / eligible if eligible else float("nan"),
            "split": sum(s.split for s in items),
            "false_per_recording": sum(s.false for s in items) / len(items),
            "false_per_min": sum(s.false for s in items) / minutes if minutes else float("nan"),
            "with_pose": float(np.mean([s.poses > 0 for s in items])),
            "refused": sum(s.refused is not None for s in items),
            "pose_error_rms": float(np.sqrt(np.mean(errors**2))) if errors.size else float("nan"),
            "pose_error_p95": float(np.quantile(errors, 0.95)) if errors.size else float("nan"),
        })
    return pd.DataFrame(rows)
