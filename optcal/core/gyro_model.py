"""The gyroscope error model and its identifiable parameterisation.

Measurement model (Tedaldi, Pretto, Menegatti 2014, eq. 9 written as a forward model)::

    g_k = K_g M_g ω_k + b_g + G_g f_k + n_k

* ``g_k`` raw gyro sample (counts, rad/s or °/s: "raw units"),
* ``ω_k`` the body rate in rad/s **in the calibrated accelerometer frame**,
* ``K_g`` diagonal scale factors (raw units per rad/s),
* ``M_g`` the gyro sensing axes: row ``i`` is the unit vector of gyro axis ``i`` expressed
  in the accelerometer frame (non-orthogonality of the gyro triad *and* its misalignment
  relative to the accelerometer, together),
* ``b_g`` bias (raw units), ``G_g`` optional g-sensitivity (raw units per g, ``f_k`` the
  calibrated specific force in g), ``n_k`` white noise.

Calibration (the inverse, Tedaldi 2014 eq. 9)::

    ω_k = T_g (g_k − b_g − G_g f_k),      T_g = (K_g M_g)⁻¹   (rad/s per raw unit)

Identifiable parameterisation
-----------------------------
All nine entries of ``T_g`` are identifiable from a static-pose recording with moves about
three non-coplanar axes, unlike the accelerometer's ``T`` of which only ``A = Tᵀ T`` is
(:mod:`optcal.core.model`).  The reason: the accelerometer sees gravity only through its norm
in a single pose, so any rotation ``Q`` of its frame fits equally well; optcal fixes that
freedom by the canonical lower-triangular ``T`` (calibrated x along the accelerometer's x
sensing axis, y in the plane of its x and y axes).  Once that frame is fixed, every static
pose gives a *known* gravity direction ``u_i`` in it, and the gyro, integrated across a
move, must carry ``u_i`` onto ``u_{i+1}`` (Tedaldi 2014, eq. 13-14).  A rotation of the
gyro's frame relative to the accelerometer's changes the predicted direction, so it is
observed: the three angles of the gyro-to-accelerometer rotation, the three
non-orthogonality angles of the gyro triad and the three scales (= 9 numbers, one per
entry of ``T_g``) all are.  Changing the accelerometer convention by a rotation ``Q``
(for instance imu_tk's upper-triangular ``T``) changes ``T_g`` to ``Q T_g``; figures that
do not depend on the convention (scales ``‖row_i(T_g⁻¹)‖``, the gravity-prediction angle)
stay the same.  Each move constrains two of the three rotation components (the one about
gravity is invisible to the accelerometer), so the rotation axes of the moves must span
three dimensions: rotations about two axes only leave ``T_g`` applied to the third axis
undetermined (:mod:`optcal.families.gyro.identifiability`).  The bias is identified by the still
intervals (mean rate = Earth rate, 7.3e-5 rad/s, neglected); ``G_g`` by the regression of
the still-interval gyro means on the gravity direction (four or more non-coplanar poses).

Parameter vector (order of every covariance and standard error)::

    θ_g = [T_xx, T_xy, T_xz, T_yx, T_yy, T_yz, T_zx, T_zy, T_zz, b_x, b_y, b_z]

row-major ``T_g`` (``T_xy`` row x, column y), then the bias.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.model import AXES

#: Names of the nine entries of ``T_g`` (row-major) and of the bias.
T_NAMES: tuple[str, ...] = tuple(f"Tg_{AXES[i]}{AXES[j]}" for i in range(3) for j in range(3))
BIAS_NAMES: tuple[str, ...] = tuple(f"bg_{a}" for a in AXES)
G_NAMES: tuple[str, ...] = tuple(f"Gg_{AXES[i]}{AXES[j]}" for i in range(3) for j in range(3))
PARAM_NAMES: tuple[str, ...] = T_NAMES + BIAS_NAMES


@dataclass(frozen=True)
class GyroPhysical:
    """Physical parameters equivalent to a gyro calibration.

    Attributes
    ----------
    scale : ndarray, shape (3,)
        Diagonal of ``K_g``, raw units per rad/s.
    axes : ndarray, shape (3, 3)
        ``M_g``: row ``i`` is the unit sensing axis of gyro ``i`` in the accelerometer frame.
    misalignment_deg : ndarray, shape (3,)
        Angle between each gyro sensing axis and the same accelerometer-frame axis, degrees.
    bias : ndarray, shape (3,)
        Raw units.
    """

    scale: NDArray[np.float64]
    axes: NDArray[np.float64]
    misalignment_deg: NDArray[np.float64]
    bias: NDArray[np.float64]


@dataclass(frozen=True)
class GyroModel:
    """The gyro model ``g = K_g M_g ω + b_g + G_g f`` and its calibration ``ω = T_g (g − b_g − G_g f)``.

    Attributes
    ----------
    T : ndarray, shape (3, 3)
        ``T_g = (K_g M_g)⁻¹``, rad/s per raw unit, full (module docstring).
    bias : ndarray, shape (3,)
        ``b_g``, raw units.
    g_sensitivity : ndarray, shape (3, 3) or None
        ``G_g``, raw units per g (``None``: not modelled).
    """

    T: NDArray[np.float64]
    bias: NDArray[np.float64]
    g_sensitivity: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        T = np.asarray(self.T, dtype=float).reshape(3, 3)
        if not np.all(np.isfinite(T)) or abs(np.linalg.det(T)) < 1e-300:
            raise InputError("the gyro calibration matrix T must be finite and invertible")
        object.__setattr__(self, "T", T)
        object.__setattr__(self, "bias", np.asarray(self.bias, dtype=float).reshape(3))
        if self.g_sensitivity is not None:
            object.__setattr__(self, "g_sensitivity", np.asarray(self.g_sensitivity, dtype=float).reshape(3, 3))

    @classmethod
    def from_physical(
        cls,
        scale: ArrayLike,
        axes: ArrayLike | None = None,
        bias: ArrayLike = (0.0, 0.0, 0.0),
        g_sensitivity: ArrayLike | None = None,
    ) -> "GyroModel":
        """Build the model from ``K_g`` (diagonal, raw units per rad/s), ``M_g`` and ``b_g``.

        The rows of ``axes`` are normalised to unit length (identity when omitted).
        """
        M = np.eye(3) if axes is None else np.asarray(axes, dtype=float).reshape(3, 3)
        M = M / np.linalg.norm(M, axis=1, keepdims=True)
        KM = np.diag(np.asarray(scale, dtype=float).reshape(3)) @ M
        return cls(np.linalg.inv(KM), np.asarray(bias, float), None if g_sensitivity is None else np.asarray(g_sensitivity, float))

    @classmethod
    def from_theta(cls, theta: ArrayLike, g_sensitivity: ArrayLike | None = None) -> "GyroModel":
        """Build the model from θ_g (module docstring)."""
        th = np.asarray(theta, dtype=float).reshape(-1)
        if th.size != len(PARAM_NAMES):
            raise InputError(f"theta must have {len(PARAM_NAMES)} entries ({', '.join(PARAM_NAMES)}), got {th.size}")
        return cls(th[:9].reshape(3, 3), th[9:12], None if g_sensitivity is None else np.asarray(g_sensitivity, float))

    @property
    def theta(self) -> NDArray[np.float64]:
        """θ_g = (row-major T_g, b_g)."""
        return np.concatenate([self.T.ravel(), self.bias])

    def physical(self) -> GyroPhysical:
        """Decompose ``T_g⁻¹ = K_g M_g`` into scales, sensing axes and misalignment angles."""
        KM = np.linalg.inv(self.T)
        scale = np.linalg.norm(KM, axis=1)
        axes = KM / scale[:, None]
        mis = np.degrees(np.arccos(np.clip(np.abs(np.diag(axes)), -1.0, 1.0)))
        return GyroPhysical(scale, axes, mis, self.bias.copy())

    def measure(self, omega: ArrayLike, specific_force: ArrayLike | None = None) -> NDArray[np.float64]:
        """Noise-free raw gyro ``K_g M_g ω + b_g + G_g f`` for rates ``omega`` (n, 3) in rad/s."""
        w = np.asarray(omega, dtype=float).reshape(-1, 3)
        raw = w @ np.linalg.inv(self.T).T + self.bias
        if self.g_sensitivity is not None:
            if specific_force is None:
                raise InputError("this gyro model has a g-sensitivity: pass specific_force (calibrated, in g)")
            raw = raw + np.asarray(specific_force, float).reshape(-1, 3) @ self.g_sensitivity.T
        return raw

    def correct(self, raw: ArrayLike, specific_force: ArrayLike | None = None) -> NDArray[np.float64]:
        """Body rate ``T_g (g − b_g − G_g f)`` in rad/s in the accelerometer frame, for raw samples (..., 3)."""
        g = np.asarray(raw, dtype=float)
        if g.shape[-1] != 3:
            raise InputError(f"raw gyro samples must have 3 columns, got shape {g.shape}")
        g = g - self.bias
        if self.g_sensitivity is not None:
            if specific_force is None:
                raise InputError("this gyro calibration has a g-sensitivity: pass specific_force (calibrated, in g)")
            g = g - np.asarray(specific_force, float) @ self.g_sensitivity.T
        return g @ self.T.T
