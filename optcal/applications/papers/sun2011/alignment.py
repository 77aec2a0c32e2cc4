"""Static-base SINS error model (ENU) and the 10-state Kalman filter of fine alignment (Sun 2011).

Error model
-----------
Navigation frame ENU, body frame x right, y forward, z up; ``C = C_b^n``; ``φ`` the
misalignment of the computed frame p, ``C_b^p = (I − φ×) C_b^n``; static base, so the true
velocity is zero and the computed velocity is the velocity error.  Linearising the
strapdown equations gives (the standard static-alignment model that Sun 2011 takes as
given, refs. [13, 18, 19]; Ω the Earth rate, L the latitude, R the Earth radius)::

    δV̇ = f^n × φ − (2 ω_ie^n) × δV + C δf^b,                f^n = [0, 0, g]ᵀ
    φ̇  = φ × ω_ie^n + δω_en^n − C δω^b,                     ω_ie^n = [0, Ω cos L, Ω sin L]ᵀ
    δω_en^n = [−δV_n / R, δV_e / R, δV_e tan L / R]ᵀ

i.e., with the vertical channel left out::

    δV̇_e =  2Ω sin L δV_n − g φ_n + C11 ∇_x + C12 ∇_y
    δV̇_n = −2Ω sin L δV_e + g φ_e + C21 ∇_x + C22 ∇_y
    φ̇_e  = −δV_n/R + Ω sin L φ_n − Ω cos L φ_u − (C ε)_e
    φ̇_n  =  δV_e/R − Ω sin L φ_e − (C ε)_n
    φ̇_u  =  δV_e tan L/R + Ω cos L φ_e − (C ε)_u

with the ten states of Sun 2011, section 3: ``x = [δV_e, δV_n, φ_e, φ_n, φ_u, ∇_x, ∇_y, ε_x,
ε_y, ε_z]`` (∇, ε constant biases of the x, y accelerometers and the three gyros, body
frame) and velocity-error observations ``z = [δV_e, δV_n] + v``.

Why the horizontal misalignment estimate carries the accelerometer error (eq. 7)
-------------------------------------------------------------------------------
On a static base the horizontal accelerometer error ``V̄ = C δf^b`` and the tilt enter the
velocity error only as the sums ``−g φ_n + V̄_e`` and ``g φ_e + V̄_n``.  With the paper's P0
the filter attributes almost all of a constant sum to the tilt (prior (1°·g)² against
(100 µg)² for ∇: a fraction 3·10⁻⁵ goes to ∇), so after convergence
``φ̂_n = φ_n − V̄_e/g`` and ``φ̂_e = φ_e + V̄_n/g``: eq. 7-8, ``Δφ_e = V̄_n/g``,
``Δφ_n = −V̄_e/g``.  The accelerometer errors are not states of their own: they are what the
calibration of :mod:`optcal.applications.papers.sun2011.tenposition` reads out of the differences of φ̂ between positions.

Discretisation and step
-----------------------
Both the filter and the simulated truth use exact discretisations: ``Φ = expm(F Δt)``, the
process noise by Van Loan's method, and for the truth the zero-order hold of the sensor
outputs (each output is the mean over its step, as an IMU delivers increments), so the
step introduces no discretisation error.  The default step is 1 s: the fastest mode of the
static error model is the Schuler/Earth-rate coupling (‖F_φ,δV‖Δt ≈ 1.2·10⁻³ at 1 s, the
tilt–velocity coupling g·Δt acts through exactly integrated ramps), and the velocity error
is driven by accelerometer white noise (a random walk) with negligible read-out noise, so
60 velocity samples per position carry the same information on the slope as 600; the
study ``studies/sun2011_ten_position.py`` checks that 0.1 s gives the same estimates.  The
gain sequence does not depend on the data: it is computed once per attitude (cached) and
the filter then runs as a batched linear recursion over all Monte Carlo runs at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from optcal.core.model import EARTH_RATE
from optcal.errors import InputError

#: The Earth's equatorial radius, m (its rate: :data:`optcal.core.model.EARTH_RATE`).
EARTH_RADIUS: float = 6378137.0
STATE_NAMES: tuple[str, ...] = (
    "dV_e", "dV_n", "phi_e", "phi_n", "phi_u", "nabla_x", "nabla_y", "eps_x", "eps_y", "eps_z",
)
N_STATES: int = len(STATE_NAMES)
#: Observation matrix: the two horizontal velocity errors.
H: NDArray[np.float64] = np.eye(2, N_STATES)
_DEG = np.pi / 180.0
_DEG_H = _DEG / 3600.0


def navigation_block(latitude: float, gravity: float) -> NDArray[np.float64]:
    """The 5×5 block of F over [δV_e, δV_n, φ_e, φ_n, φ_u] (module docstring)."""
    W, sL, cL, R = EARTH_RATE, np.sin(latitude), np.cos(latitude), EARTH_RADIUS
    return np.array(
        [
            [0.0, 2 * W * sL, 0.0, -gravity, 0.0],
            [-2 * W * sL, 0.0, gravity, 0.0, 0.0],
            [0.0, -1 / R, 0.0, W * sL, -W * cL],
            [1 / R, 0.0, -W * sL, 0.0, 0.0],
            [np.tan(latitude) / R, 0.0, W * cL, 0.0, 0.0],
        ]
    )


def sensor_input_block() -> NDArray[np.float64]:
    """5×5 input matrix of the navigation block for [δf^n_e, δf^n_n, δω^n_e, δω^n_n, δω^n_u]."""
    B = np.zeros((5, 5))
    B[0, 0] = B[1, 1] = 1.0
    B[2:, 2:] = -np.eye(3)
    return B


def error_dynamics(C_bn: ArrayLike, latitude: float, gravity: float) -> NDArray[np.float64]:
    """Continuous-time ``F`` (10×10) of the 10-state alignment model at attitude ``C_b^n``."""
    C = np.asarray(C_bn, dtype=float).reshape(3, 3)
    F = np.zeros((N_STATES, N_STATES))
    F[:5, :5] = navigation_block(latitude, gravity)
    F[0:2, 5:7] = C[0:2, 0:2]  # body-frame ∇_x, ∇_y projected east/north
    F[2:5, 7:10] = -C  # body-frame ε projected (φ̇ = … − C ε)
    return F


def discretise(F: NDArray, Qc: NDArray, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``Φ = expm(F Δt)`` and ``Q_d = ∫ Φ(s) Q_c Φ(s)ᵀ ds`` (Van Loan)."""
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = Qc
    M[n:, n:] = F.T
    E = scipy.linalg.expm(M * dt)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    return Phi, 0.5 * (Qd + Qd.T)


def zero_order_hold(F: NDArray, B: NDArray, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact ``x_{k+1} = Φ x_k + Γ u_k`` for an input held constant over each step."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = F
    M[:n, n:] = B
    E = scipy.linalg.expm(M * dt)
    return E[:n, :n], E[:n, n:]


@dataclass(frozen=True)
class FilterTuning:
    """Initial covariance, process noise densities and measurement noise of the filter.

    Attributes
    ----------
    p0_sd : ndarray, shape (10,)
        Prior standard deviations (SI: m/s, rad, m/s², rad/s).
    q_sd : ndarray, shape (10,)
        White-noise densities driving each state (per √Hz), zero for the constant biases.
    r_sd : ndarray, shape (2,)
        Velocity-error measurement noise, m/s.
    """

    p0_sd: NDArray[np.float64]
    q_sd: NDArray[np.float64]
    r_sd: NDArray[np.float64]

    @classmethod
    def paper(cls, gravity: float) -> "FilterTuning":
        """P0, Q and R of Sun 2011, section 3 (µg with the paper's g)."""
        ug = 1e-6 * gravity
        p0 = [0.1, 0.1, 1 * _DEG, 1 * _DEG, 2 * _DEG, 100 * ug, 100 * ug] + [0.01 * _DEG_H] * 3
        q = [50 * ug, 50 * ug] + [0.005 * _DEG_H] * 3 + [0.0] * 5
        return cls(np.array(p0), np.array(q), np.array([0.1, 0.1]))

    def key(self) -> tuple[float, ...]:
        return tuple(np.concatenate([self.p0_sd, self.q_sd, self.r_sd]).tolist())


@dataclass(frozen=True)
class AlignmentFilter:
    """The 10-state fine-alignment Kalman filter at one fixed attitude, precomputed.

    Because the model is linear and the attitude fixed, the gains do not depend on the data:
    ``x̂_k = A_k x̂_{k−1} + K_k z_k`` with ``A_k = (I − K_k H) Φ`` (X0 = 0).

    Attributes
    ----------
    Phi, Qd : ndarray
        Transition and process noise of one step.
    gains : ndarray, shape (n, 10, 2)
    transitions : ndarray, shape (n, 10, 10)
        ``A_k``.
    covariances : ndarray, shape (n, 10, 10)
        Posterior covariance after each update (Joseph form).
    dt : float
    """

    Phi: NDArray[np.float64]
    Qd: NDArray[np.float64]
    gains: NDArray[np.float64]
    transitions: NDArray[np.float64]
    covariances: NDArray[np.float64]
    dt: float

    @classmethod
    def build(
        cls, C_bn: ArrayLike, latitude: float, gravity: float, dt: float, n_steps: int, tuning: FilterTuning
    ) -> "AlignmentFilter":
        """Build (or fetch from the cache) the filter for attitude ``C_b^n``."""
        C = tuple(np.round(np.asarray(C_bn, float).ravel(), 14).tolist())
        return _build_filter(C, float(latitude), float(gravity), float(dt), int(n_steps), tuning.key())

    @property
    def n_steps(self) -> int:
        return int(self.gains.shape[0])

    def run(self, z: ArrayLike) -> NDArray[np.float64]:
        """Filter velocity-error observations ``z`` (runs, n, 2); return x̂ (runs, n, 10)."""
        z = np.asarray(z, dtype=float)
        if z.ndim != 3 or z.shape[1:] != (self.n_steps, 2):
            raise InputError(f"observations must have shape (runs, {self.n_steps}, 2), got {z.shape}")
        x = np.zeros((z.shape[0], N_STATES))
        out = np.empty((z.shape[0], self.n_steps, N_STATES))
        for k in range(self.n_steps):
            x = x @ self.transitions[k].T + z[:, k] @ self.gains[k].T
            out[:, k] = x
        return out


@lru_cache(maxsize=256)
def _build_filter(
    C: tuple[float, ...], latitude: float, gravity: float, dt: float, n_steps: int, tuning_key: tuple[float, ...]
) -> AlignmentFilter:
    t = np.asarray(tuning_key)
    p0, q, r = t[:N_STATES], t[N_STATES : 2 * N_STATES], t[2 * N_STATES :]
    F = error_dynamics(np.reshape(C, (3, 3)), latitude, gravity)
    Phi, Qd = discretise(F, np.diag(q**2), dt)
    R = np.diag(r**2)
    P = np.diag(p0**2)
    I = np.eye(N_STATES)
    gains = np.empty((n_steps, N_STATES, 2))
    trans = np.empty((n_steps, N_STATES, N_STATES))
    covs = np.empty((n_steps, N_STATES, N_STATES))
    for k in range(n_steps):
        P = Phi @ P @ Phi.T + Qd
        K = np.linalg.solve(H @ P @ H.T + R, H @ P).T
        IKH = I - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T
        gains[k], trans[k], covs[k] = K, IKH @ Phi, P
    return AlignmentFilter(Phi, Qd, gains, trans, covs, dt)


def propagate_errors(
    phi0: ArrayLike,
    accel_error_n: ArrayLike,
    gyro_error_n: ArrayLike,
    latitude: float,
    gravity: float,
    dt: float,
) -> NDArray[np.float64]:
    """Simulate the true navigation errors of a static SINS (the truth of the simulation).

    Parameters
    ----------
    phi0 : array_like, shape (runs, 3)
        True initial misalignment, rad (δV(0) = 0).
    accel_error_n, gyro_error_n : array_like, shape (runs, n, 3)
        Sensor errors projected to the navigation frame, ``C_b^n δf^b`` and ``C_b^n δω^b``,
        each the mean over its step (zero-order hold).
    latitude, gravity, dt : float

    Returns
    -------
    ndarray, shape (runs, n, 5)
        [δV_e, δV_n, φ_e, φ_n, φ_u] at the end of each step.
    """
    df = np.asarray(accel_error_n, dtype=float)
    dw = np.asarray(gyro_error_n, dtype=float)
    Phi, Gam = _truth_transition(float(latitude), float(gravity), float(dt))
    u = np.concatenate([df[..., :2], dw], axis=-1) @ Gam.T  # (runs, n, 5)
    x = np.zeros((df.shape[0], 5))
    x[:, 2:] = np.asarray(phi0, dtype=float)
    out = np.empty(df.shape[:2] + (5,))
    for k in range(df.shape[1]):
        x = x @ Phi.T + u[:, k]
        out[:, k] = x
    return out


@lru_cache(maxsize=16)
def _truth_transition(latitude: float, gravity: float, dt: float) -> tuple[NDArray, NDArray]:
    return zero_order_hold(navigation_block(latitude, gravity), sensor_input_block(), dt)


@dataclass(frozen=True)
class AlignmentResult:
    """Fine alignment at one position for every run.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Time of each sample, s.
    truth : ndarray, shape (runs, n, 5)
        True [δV_e, δV_n, φ_e, φ_n, φ_u].
    estimate : ndarray, shape (runs, n, 10)
        Filter state x̂.
    sd : ndarray, shape (n, 10)
        Filter standard deviations.
    """

    t: NDArray[np.float64]
    truth: NDArray[np.float64]
    estimate: NDArray[np.float64]
    sd: NDArray[np.float64]

    @property
    def final_misalignment(self) -> NDArray[np.float64]:
        """φ̂ at the end of the position, (runs, 3) = [φ̂_e, φ̂_n, φ̂_u]."""
        return self.estimate[:, -1, 2:5]


def align(
    C_nominal: ArrayLike,
    C_true: ArrayLike,
    phi0: ArrayLike,
    accel_error_b: ArrayLike,
    gyro_error_b: ArrayLike,
    latitude: float,
    gravity: float,
    dt: float,
    tuning: FilterTuning,
) -> AlignmentResult:
    """Simulate the static SINS at one position and run the fine-alignment filter.

    The truth uses the actual attitude ``C_true`` (runs, 3, 3) to project the body-frame
    sensor errors (runs, n, 3); the filter uses the commanded attitude ``C_nominal``.
    """
    Ct = np.asarray(C_true, dtype=float)
    df_n = np.einsum("rij,rkj->rki", Ct, np.asarray(accel_error_b, float))
    dw_n = np.einsum("rij,rkj->rki", Ct, np.asarray(gyro_error_b, float))
    truth = propagate_errors(phi0, df_n, dw_n, latitude, gravity, dt)
    kf = AlignmentFilter.build(C_nominal, latitude, gravity, dt, truth.shape[1], tuning)
    est = kf.run(truth[..., :2])
    sd = np.sqrt(np.clip(np.diagonal(kf.covariances, axis1=1, axis2=2), 0.0, None))
    return AlignmentResult(dt * np.arange(1, truth.shape[1] + 1), truth, est, sd)
