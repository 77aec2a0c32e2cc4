"""The extended Kalman filter of Yin 2014 (eqs. 7-13): compensated accelerometer output.

Reconstruction of the lost equations
------------------------------------
The paper builds a state-space model "x_k = A_{k−1} x_{k−1} + U_{k−1} μ_{k−1}" (eq. 7),
"z_k = h(x_k, ν_k)" (eq. 8) whose parameters are the calibration W, V (eq. 4) and the
velocity random walk and bias instability read from the Allan deviation (Table 3); its
Fig. 3 shows the *attitude-angle* variance converging within about 100 s and Fig. 4 the
compensated acceleration.  The reference for the separate bias state is Foxlin 1996 (the
paper's [12]).  The filter written here is the one those statements determine:

State (5): roll φ, pitch θ of the platform (rad) and the slowly varying bias of each axis
(raw units, on top of the calibrated V)::

    x = [φ, θ, b_x, b_y, b_z]ᵀ

Process model (eq. 7), static platform::

    x_k = A x_{k−1} + U μ_{k−1},   μ ~ N(0, I),   Q = U Uᵀ
    A = diag(1, 1, β_x, β_y, β_z),   β_i = exp(−Δt / τ_c)
    Q = diag(q_a Δt, q_a Δt, B_i² (1 − β_i²) + K_i² Δt)

The attitude is a slow random walk (``q_a``, rad²/s, a tuning constant: the platform is
nominally still).  The bias is a first-order Gauss–Markov process of standard deviation
B_i (bias instability) and correlation time τ_c (the τ of the Allan minimum) — whose Allan
deviation peaks at ≈ 0.62 B_i, the usual stand-in for the flat 0.664 B_i of flicker noise —
driven in addition by the rate random walk K_i.

Measurement model (eq. 8): the raw sample is the inverse of the calibration (eq. 3) applied
to the true specific force of eq. 2, plus the bias state and white noise::

    z_k = h(x_k) + ν_k,   h(x) = W⁻¹ (G f(φ, θ) − V) + b,   f = [−sin θ, cos θ sin φ, cos θ cos φ]ᵀ
    ν_k ~ N(0, R),   R = diag(N_i² f_s)

with N_i the velocity random walk (white noise density, raw units·√s) so that N_i √f_s is
the standard deviation of one sample.

Prediction (eqs. 9-10) and update (eqs. 11-13)::

    x̂⁻_k = A x̂_{k−1}                                                                   (9)
    P⁻_k = A P_{k−1} Aᵀ + Q                                                            (10)
    K_k = P⁻_k Hᵀ (H P⁻_k Hᵀ + R)⁻¹,   H = ∂h/∂x at x̂⁻_k                               (11)
    x̂_k = x̂⁻_k + K_k (z_k − h(x̂⁻_k))                                                  (12)
    P_k = (I − K_k H) P⁻_k (I − K_k H)ᵀ + K_k R K_kᵀ                                   (13)

(eq. 13 in Joseph form, which equals ``(I − K H) P⁻`` in exact arithmetic and stays
symmetric).  The compensated output is ``G f(φ̂_k, θ̂_k)``, in the output units of W (g in
optcal).  With a static accelerometer only, attitude and the bias components perpendicular
to gravity are told apart only by their prior variances, so the filter splits them by Q.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.model import AXES
from optcal.core.rotations import gravity_direction, roll_pitch
from optcal.families.noise.allan import NoiseParameters

#: Default attitude random walk of a nominally still platform, rad/√s.
ATTITUDE_RANDOM_WALK: float = 1e-4
#: Default prior standard deviation of the initial roll and pitch, rad.
INITIAL_ATTITUDE_STD: float = 0.05


@dataclass
class EKFOutput:
    """What the filter produced, one row per sample.

    Attributes
    ----------
    compensated : ndarray, shape (n, 3)
        ``G f(φ̂, θ̂)``, the compensated specific force (output units of W).
    attitude : ndarray, shape (n, 2)
        Roll and pitch estimates, rad.
    bias : ndarray, shape (n, 3)
        Bias-state estimates, raw units.
    attitude_variance : ndarray, shape (n, 2)
        Posterior variance of roll and pitch, rad² (Yin 2014, Fig. 3).
    """

    compensated: NDArray[np.float64]
    attitude: NDArray[np.float64]
    bias: NDArray[np.float64]
    attitude_variance: NDArray[np.float64]


class YinEKF:
    """The extended Kalman filter of Yin 2014, eqs. 7-13 (model in the module docstring).

    Parameters
    ----------
    W, V : array_like
        Calibration matrix (output units per raw unit) and bias (output units), eq. 3/4.
    rate_hz : float
        Sample rate.
    velocity_random_walk : array_like, shape (3,)
        White-noise density N per axis, raw units·√s.
    bias_instability : array_like, shape (3,)
        B per axis, raw units.
    rate_random_walk : array_like, shape (3,), optional
        K per axis, raw units/√s (zero when absent).
    correlation_time_s : float
        Bias correlation time τ_c, s.
    attitude_random_walk : float
        √q_a, rad/√s.
    gravity : float
        G in the output units of W (1 for g).
    initial_attitude_std : float
        Prior standard deviation of the initial roll and pitch, rad.
    """

    def __init__(
        self,
        W: ArrayLike,
        V: ArrayLike,
        rate_hz: float,
        velocity_random_walk: ArrayLike,
        bias_instability: ArrayLike,
        rate_random_walk: ArrayLike | None = None,
        correlation_time_s: float = 100.0,
        attitude_random_walk: float = ATTITUDE_RANDOM_WALK,
        gravity: float = 1.0,
        initial_attitude_std: float = INITIAL_ATTITUDE_STD,
    ) -> None:
        self.W = np.asarray(W, dtype=float).reshape(3, 3)
        self.V = np.asarray(V, dtype=float).reshape(3)
        if not np.all(np.isfinite(self.W)) or abs(np.linalg.det(self.W)) == 0:
            raise InputError("the calibration matrix W must be finite and invertible")
        if not (rate_hz > 0 and correlation_time_s > 0):
            raise InputError("the sample rate and the bias correlation time must be positive")
        self.rate_hz = float(rate_hz)
        self.N = np.asarray(velocity_random_walk, dtype=float).reshape(3)
        self.B = np.asarray(bias_instability, dtype=float).reshape(3)
        self.K = np.zeros(3) if rate_random_walk is None else np.asarray(rate_random_walk, dtype=float).reshape(3)
        if np.any(self.N <= 0) or np.any(self.B < 0) or np.any(self.K < 0):
            raise InputError("noise parameters must be non-negative (velocity random walk positive)")
        self.correlation_time_s = float(correlation_time_s)
        self.attitude_random_walk = float(attitude_random_walk)
        self.gravity = float(gravity)
        self.initial_attitude_std = float(initial_attitude_std)
        self._W_inv = np.linalg.inv(self.W)
        self._offset = self._W_inv @ self.V  # h = G W⁻¹ f − W⁻¹ V + b
        self._GW_inv = self.gravity * self._W_inv

    @classmethod
    def from_noise(
        cls,
        W: ArrayLike,
        V: ArrayLike,
        rate_hz: float,
        noise: Mapping[str, NoiseParameters] | Sequence[NoiseParameters],
        **settings: float,
    ) -> "YinEKF":
        """Build the filter from per-axis :class:`~optcal.families.noise.allan.NoiseParameters` in raw units.

        The bias correlation time is the median of the axes' τ at the Allan minimum; an
        absent rate random walk counts as zero; a bias instability that is only an upper bound
        (no flat region resolved) is used as it is, a conservative prior.
        """
        params = [noise[a] for a in AXES] if isinstance(noise, Mapping) else list(noise)
        return cls(
            W,
            V,
            rate_hz,
            velocity_random_walk=[p.noise_density for p in params],
            bias_instability=[p.bias_instability for p in params],
            rate_random_walk=[p.rate_random_walk or 0.0 for p in params],
            correlation_time_s=settings.pop("correlation_time_s", float(np.median([p.correlation_time_s for p in params]))),
            **settings,
        )

    # ------------------------------------------------------------------ model
    def transition(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``A`` and ``Q = U Uᵀ`` of eq. 7."""
        dt = 1.0 / self.rate_hz
        beta = math.exp(-dt / self.correlation_time_s)
        A = np.diag([1.0, 1.0, beta, beta, beta])
        q_att = self.attitude_random_walk**2 * dt
        q_bias = self.B**2 * (1.0 - beta**2) + self.K**2 * dt
        return A, np.diag([q_att, q_att, *q_bias])

    def measurement_model(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``h(x)`` of eq. 8 and its Jacobian ``H = ∂h/∂x`` (3×5) used in eq. 11."""
        H = np.empty((3, 5))
        H[:, 2:] = np.eye(3)
        return self._measure(x, np.empty((3, 3)), H), H

    def _measure(self, x: NDArray[np.float64], F: NDArray[np.float64], H: NDArray[np.float64]) -> NDArray[np.float64]:
        """``h(x)`` of eq. 8, its attitude columns ``H[:, :2]`` written into ``H`` (whose bias block ``H[:, 2:] = I``
        the caller keeps): one 3×3 product ``G W⁻¹ [f, ∂f/∂φ, ∂f/∂θ]`` into the scratch ``F`` (speed: the filter calls
        it once a sample, no array allocated but the product)."""
        sp, cp = math.sin(x[0]), math.cos(x[0])
        st, ct = math.sin(x[1]), math.cos(x[1])
        F[0] = -st, 0.0, -ct  # columns f = [−sin θ, cos θ sin φ, cos θ cos φ] (eq. 2), ∂f/∂φ, ∂f/∂θ
        F[1] = ct * sp, ct * cp, -st * sp
        F[2] = ct * cp, -ct * sp, -st * cp
        GF = self._GW_inv @ F
        H[:, :2] = GF[:, 1:]
        return GF[:, 0] - self._offset + x[2:]

    def measurement_noise(self) -> NDArray[np.float64]:
        """``R = diag(N_i² f_s)`` of eq. 8."""
        return np.diag(self.N**2 * self.rate_hz)

    # ------------------------------------------------------------------ filter
    def run(self, raw: ArrayLike) -> EKFOutput:
        """Filter raw samples (n, 3) of a still sensor; return the compensated output.

        The initial roll and pitch come from the first calibrated sample ``W z_1 + V``; the
        initial bias state is zero with variance B².
        """
        z = np.asarray(raw, dtype=float)
        if z.ndim != 2 or z.shape[1] != 3 or z.shape[0] == 0:
            raise InputError(f"raw samples must have shape (n, 3), got {z.shape}")
        if not np.all(np.isfinite(z)):
            raise InputError("raw samples contain NaN or infinite values")
        n = z.shape[0]
        a_diag, outer_a, Q, R, r_diag, eye = self._recursion_constants()
        # speed only (a step 170-180 -> 75-87 CPU µs at a load of 8; the reproduction filters 10⁵ samples): H = [J | I]
        # kept in one array whose bias block never changes, the output G f(φ̂, θ̂) computed once after the loop
        H = np.zeros((3, 5))
        H[:, 2:] = np.eye(3)
        F = np.empty((3, 3))

        roll, pitch = roll_pitch(self.W @ z[0] + self.V)
        x = np.array([roll, pitch, 0.0, 0.0, 0.0])
        P = np.diag([self.initial_attitude_std**2] * 2 + list(np.maximum(self.B**2, 1e-30)))

        states = np.empty((n, 5))
        att_var = np.empty((n, 2))
        for k in range(n):
            # prediction, eqs. 9-10 (A is diagonal)
            x = a_diag * x
            P = outer_a * P + Q
            h = self._measure(x, F, H)  # h(x) and H = ∂h/∂x, eq. 8
            # update, eqs. 11-13
            PHt = P @ H.T
            S = H @ PHt + R
            gain = PHt @ _inverse_3x3(S)
            x = x + gain @ (z[k] - h)
            IKH = eye - gain @ H
            P = IKH @ P @ IKH.T + (gain * r_diag) @ gain.T
            states[k] = x
            att_var[k, 0] = P[0, 0]
            att_var[k, 1] = P[1, 1]
        attitude = states[:, :2].copy()
        bias = states[:, 2:].copy()
        compensated = self.gravity * gravity_direction(attitude[:, 0], attitude[:, 1])
        return EKFOutput(compensated=compensated, attitude=attitude, bias=bias, attitude_variance=att_var)

    def _recursion_constants(self) -> tuple[NDArray[np.float64], ...]:
        """What every step of the recursion (eqs. 9-13) reuses: ``diag(A)``, its outer product (``A P Aᵀ`` for a
        diagonal ``A``), ``Q``, ``R``, ``diag(R)`` and the 5×5 identity."""
        A, Q = self.transition()
        R = self.measurement_noise()
        a_diag = np.diag(A)
        return a_diag, a_diag[:, None] * a_diag[None, :], Q, R, np.diag(R), np.eye(5)

    def run_many(self, logs: Sequence[ArrayLike]) -> list[EKFOutput]:
        """:meth:`run` on several logs of a still sensor, the logs of one length filtered side by side.

        Speed only: each log's filter is the same recursion (eqs. 9-13) as :meth:`run`'s, its steps taken for all the
        logs of its length at once (stacked 3×3 and 5×5 products), so the outputs equal :meth:`run`'s to rounding
        (the products' summation order; 1e-15 on the reproduction's six 10,000-sample poses).
        """
        arrays = [np.asarray(log, dtype=float) for log in logs]
        out: list[EKFOutput | None] = [None] * len(arrays)
        lengths: dict[tuple[int, ...], list[int]] = {}
        for i, z in enumerate(arrays):
            lengths.setdefault(z.shape, []).append(i)
        for shape, members in lengths.items():
            if len(members) == 1 or len(shape) != 2 or shape[1] != 3 or shape[0] == 0:
                for i in members:
                    out[i] = self.run(arrays[i])  # one log, or a shape run() refuses with its message
                continue
            for i, result in zip(members, self._run_stacked(np.stack([arrays[i] for i in members]))):
                out[i] = result
        return [o for o in out if o is not None]

    def _run_stacked(self, z: NDArray[np.float64]) -> list[EKFOutput]:
        """:meth:`run` on ``z`` of shape (m, n, 3): m logs of n samples, each step taken for the m logs at once."""
        if not np.all(np.isfinite(z)):
            raise InputError("raw samples contain NaN or infinite values")
        m, n, _ = z.shape
        a_diag, outer_a, Q, R, r_diag, eye = self._recursion_constants()
        H = np.zeros((m, 3, 5))
        H[:, :, 2:] = np.eye(3)
        zero = np.zeros(m)
        x = np.zeros((m, 5))
        for j in range(m):
            x[j, :2] = roll_pitch(self.W @ z[j, 0] + self.V)
        P0 = np.diag([self.initial_attitude_std**2] * 2 + list(np.maximum(self.B**2, 1e-30)))
        P = np.repeat(P0[None], m, axis=0)
        states = np.empty((n, m, 5))
        att_var = np.empty((n, m, 2))
        for k in range(n):
            # prediction, eqs. 9-10 (A is diagonal)
            x = a_diag * x
            P = outer_a * P + Q
            # h(x) and H = ∂h/∂x, eq. 8 (as _measure, for the m logs)
            sp, cp, st, ct = np.sin(x[:, 0]), np.cos(x[:, 0]), np.sin(x[:, 1]), np.cos(x[:, 1])
            F = np.stack([-st, zero, -ct, ct * sp, ct * cp, -st * sp, ct * cp, -ct * sp, -st * cp], axis=1)
            GF = self._GW_inv @ F.reshape(m, 3, 3)
            H[:, :, :2] = GF[:, :, 1:]
            h = GF[:, :, 0] - self._offset + x[:, 2:]
            # update, eqs. 11-13
            PHt = P @ np.swapaxes(H, 1, 2)
            S = H @ PHt + R
            gain = PHt @ _inverse_3x3_stacked(S)
            x = x + (gain @ (z[:, k] - h)[:, :, None])[:, :, 0]
            IKH = eye - gain @ H
            P = IKH @ P @ np.swapaxes(IKH, 1, 2) + (gain * r_diag) @ np.swapaxes(gain, 1, 2)
            states[k] = x
            att_var[k] = np.diagonal(P, axis1=1, axis2=2)[:, :2]
        outputs = []
        for j in range(m):
            attitude = states[:, j, :2].copy()
            compensated = self.gravity * gravity_direction(attitude[:, 0], attitude[:, 1])
            outputs.append(EKFOutput(compensated=compensated, attitude=attitude, bias=states[:, j, 2:].copy(),
                                     attitude_variance=att_var[:, j].copy()))
        return outputs


def _cofactors(S: list[list[float]]) -> tuple[list[list[float]], float]:
    """The transposed cofactors (the adjugate) and the determinant of a 3×3 matrix given as nested lists."""
    (a, b, c), (d, e, f), (g, h, i) = S
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * c00 + b * c01 + c * c02
    return [[c00, c * h - b * i, b * f - c * e],
            [c01, a * i - c * g, c * d - a * f],
            [c02, b * g - a * h, a * e - b * d]], det


def _inverse_3x3(S: NDArray[np.float64]) -> NDArray[np.float64]:
    """The inverse of a 3×3 matrix by its cofactors (the innovation covariance of eq. 11, positive definite since R
    is: its determinant is positive).  Speed only: about a third of ``np.linalg.solve``'s cost on a 3×3, the same
    gain to rounding (1e-16)."""
    adjugate, det = _cofactors(S.tolist())
    return np.array(adjugate) / det


def _inverse_3x3_stacked(S: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_inverse_3x3` of each of a stack of 3×3 matrices, shape (m, 3, 3) (the same cofactors, the same numbers)."""
    pairs = [_cofactors(M) for M in S.tolist()]
    return np.array([p[0] for p in pairs]) / np.array([p[1] for p in pairs])[:, None, None]


def sum_squared_errors(estimate: ArrayLike, truth: ArrayLike) -> NDArray[np.float64]:
    """Per-axis sum of squared errors ``Σ_k (estimate_k − truth_k)²`` (Yin 2014, Table 4).

    ``truth`` may be one vector (a static pose) or one row per sample.
    """
    e = np.asarray(estimate, dtype=float)
    t = np.broadcast_to(np.asarray(truth, dtype=float), e.shape)
    return np.sum((e - t) ** 2, axis=0)
