"""The lumped accelerometer error model of Lu et al. 2017 and its identifiable form.

Conventions (written down once, used everywhere in optcal)
----------------------------------------------------------
* Units: the calibrated output is in g (standard gravity = 1).  Raw input may be in g,
  m/s² or counts; ``C``, ``T`` and ``o`` are then in the raw units (``o``) and
  raw-units-per-g (``C``) or g-per-raw-unit (``T``).
* Measurement model (Lu 2017, eq. 5)::

      a_meas,k = C ā_k + o + n_k,      C = S_M C_NO ||g|| V_L,   n_k ~ N(0, σ_k² I)

  with ``ā_k`` the unit specific-force direction in the sensor frame, ``S_M`` the diagonal
  scale factors, ``C_NO`` the non-orthogonality matrix, ``V_L`` the mounting
  misalignment and ``o`` the bias (zero offset).
* ``C_NO`` (Lu 2017, eq. 1; the form that reproduces Table 1)::

      C_NO = [[1,            0,     0          ],
              [sin ρ,        cos ρ, 0          ],
              [sin φ cos λ,  sin λ, cos φ cos λ]]

  ρ is the angle between Y^a and Y^p, φ between Z^a and the plane X^p O Z^p, λ between
  Z^a and the plane Y^p O Z^p.  Every row of ``C_NO`` has unit norm.
* Calibration (Lu 2017, eq. 6): ``ā = T (a_meas − o)`` with ``T = C⁻¹``.
* Identifiability: from static data only ``A = Tᵀ T`` (6 numbers) and ``o`` (3) are
  identifiable, because ``‖Q T u‖ = ‖T u‖`` for every rotation ``Q``.  optcal's canonical
  identifiable form is **T lower-triangular with a positive diagonal** (``A = Tᵀ T``,
  a "reversed" Cholesky factor).  Then ``C = T⁻¹`` is lower-triangular as well and equals
  ``S_M C_NO`` with the mounting misalignment absorbed (``V_L = I``), so the nine
  identifiable numbers map one-to-one onto (S_x, S_y, S_z, ρ, φ, λ, o_x, o_y, o_z).
* Parameter vector (order used by every estimator, covariance and standard error)::

      θ = [T_xx, T_yx, T_yy, T_zx, T_zy, T_zz, o_x, o_y, o_z]

  where ``T_yx`` is row y, column x of ``T``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError

AXES: tuple[str, str, str] = ("x", "y", "z")
#: Row/column of each free entry of the lower-triangular ``T`` in the parameter vector.
TRIL_INDEX: tuple[tuple[int, int], ...] = ((0, 0), (1, 0), (1, 1), (2, 0), (2, 1), (2, 2))
PARAM_NAMES: tuple[str, ...] = tuple(
    f"T_{AXES[i]}{AXES[j]}" for i, j in TRIL_INDEX
) + ("o_x", "o_y", "o_z")
N_PARAMS: int = len(PARAM_NAMES)

#: Standard gravity, m/s² (used for unit conversions only).
STANDARD_GRAVITY: float = 9.80665
#: The Earth's rotation rate, rad/s (IERS: the sidereal day): what a resting gyroscope reads beside its bias.
EARTH_RATE: float = 7.292115e-5


def non_orthogonality_matrix(rho: float, phi: float, lam: float) -> NDArray[np.float64]:
    """Return ``C_NO`` for the three small angles (radians), Lu 2017 eq. 1."""
    return np.array(
        [
            [1.0, 0.0, 0.0],
            [np.sin(rho), np.cos(rho), 0.0],
            [np.sin(phi) * np.cos(lam), np.sin(lam), np.cos(phi) * np.cos(lam)],
        ]
    )


def lumped_matrix(
    scale: ArrayLike,
    rho: float = 0.0,
    phi: float = 0.0,
    lam: float = 0.0,
    mounting: ArrayLike | None = None,
    gravity: float = 1.0,
) -> NDArray[np.float64]:
    """Return ``C = S_M C_NO ||g|| V_L`` (Lu 2017, eq. 5).

    Parameters
    ----------
    scale : array_like, shape (3,)
        Diagonal of ``S_M``.
    rho, phi, lam : float
        Non-orthogonality angles in radians.
    mounting : array_like, shape (3, 3), optional
        Mounting misalignment ``V_L`` (identity when omitted).
    gravity : float
        ``||g||`` in the output units (1 for g).
    """
    s = np.asarray(scale, dtype=float).reshape(3)
    v = np.eye(3) if mounting is None else np.asarray(mounting, dtype=float).reshape(3, 3)
    return np.diag(s) @ non_orthogonality_matrix(rho, phi, lam) * gravity @ v


def canonical_T(A: ArrayLike) -> NDArray[np.float64]:
    """Lower-triangular ``T`` with positive diagonal such that ``Tᵀ T = A`` (``A`` (3, 3) or a stack (..., 3, 3)).

    Raises
    ------
    InputError
        If ``A`` (any of the stack) is not symmetric positive definite.
    """
    a = np.asarray(A, dtype=float)
    a = 0.5 * (a + np.swapaxes(a, -1, -2))
    P = np.eye(3)[::-1]
    try:
        L = np.linalg.cholesky(P @ a @ P)  # P A P = L Lᵀ
    except np.linalg.LinAlgError as exc:
        raise InputError(
            "the fitted quadric is not an ellipsoid (A is not positive definite); "
            'use method="convex", which constrains A to be positive definite'
        ) from exc
    U = np.swapaxes(L, -1, -2)  # upper, Uᵀ U = P A P
    return P @ U @ P  # lower, Tᵀ T = A


def canonicalise(T: ArrayLike) -> NDArray[np.float64]:
    """Map any invertible ``T`` (or a stack (..., 3, 3)) to the canonical lower-triangular ``T`` with the same ``A``;
    a ``T`` already canonical (lower-triangular, positive diagonal) is returned as it is, not rounded through
    ``TᵀT`` and its Cholesky factor (a bound on an entry then holds to the last bit)."""
    T = np.asarray(T, dtype=float)
    upper = np.triu(np.ones((3, 3), dtype=bool), 1)
    diagonal = np.diagonal(T, axis1=-2, axis2=-1)
    done = ~np.any(T[..., upper] != 0.0, axis=-1) & np.all(diagonal > 0.0, axis=-1)
    if np.all(done):
        return T.copy()
    return np.where(done[..., None, None], T, canonical_T(np.swapaxes(T, -1, -2) @ T))


def theta_from(T: ArrayLike, o: ArrayLike) -> NDArray[np.float64]:
    """Pack a lower-triangular ``T`` and ``o`` into the parameter vector θ (or a stack: T (..., 3, 3), o (..., 3))."""
    T = np.asarray(T, dtype=float)
    lower = T[..., [i for i, _ in TRIL_INDEX], [j for _, j in TRIL_INDEX]]
    return np.concatenate([lower, np.asarray(o, float).reshape(T.shape[:-2] + (3,))], axis=-1)


def unpack_theta(theta: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unpack θ (or a stack (..., 9)) into the lower-triangular ``T`` and ``o``."""
    theta = np.asarray(theta, dtype=float)
    T = np.zeros(theta.shape[:-1] + (3, 3))
    T[..., [i for i, _ in TRIL_INDEX], [j for _, j in TRIL_INDEX]] = theta[..., :6]
    return T, theta[..., 6:9].copy()


@dataclass(frozen=True)
class PhysicalParameters:
    """Physical error parameters equivalent to an identifiable calibration.

    Attributes
    ----------
    scale : ndarray, shape (3,)
        Diagonal of ``S_M`` (raw units per g).
    rho, phi, lam : float
        Non-orthogonality angles, radians (Lu 2017, eq. 1).
    bias : ndarray, shape (3,)
        Zero offset ``o`` in raw units.
    """

    scale: NDArray[np.float64]
    rho: float
    phi: float
    lam: float
    bias: NDArray[np.float64]

    def lumped_matrix(self) -> NDArray[np.float64]:
        """``C = S_M C_NO`` with ``V_L = I``."""
        return lumped_matrix(self.scale, self.rho, self.phi, self.lam)


@dataclass(frozen=True)
class LumpedModel:
    """The lumped model ``a_meas = C ā + o`` (Lu 2017, eq. 5-6).

    ``C`` may be any invertible matrix (a mounting misalignment included); the identifiable
    quantities are :attr:`A` and :attr:`o`, and :attr:`T_canonical` is the canonical
    lower-triangular calibration matrix.
    """

    C: NDArray[np.float64]
    o: NDArray[np.float64]

    def __post_init__(self) -> None:
        C = np.asarray(self.C, dtype=float).reshape(3, 3)
        o = np.asarray(self.o, dtype=float).reshape(3)
        if not np.all(np.isfinite(C)) or abs(np.linalg.det(C)) < 1e-300:
            raise InputError("the lumped matrix C must be finite and invertible")
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "o", o)

    @classmethod
    def from_physical(
        cls,
        scale: ArrayLike,
        rho: float,
        phi: float,
        lam: float,
        bias: ArrayLike,
        mounting: ArrayLike | None = None,
        gravity: float = 1.0,
    ) -> "LumpedModel":
        """Build the model from physical parameters (angles in radians)."""
        return cls(lumped_matrix(scale, rho, phi, lam, mounting, gravity), np.asarray(bias, float))

    @classmethod
    def from_T(cls, T: ArrayLike, o: ArrayLike) -> "LumpedModel":
        """Build the model from a calibration matrix ``T`` and bias ``o``."""
        return cls(np.linalg.inv(np.asarray(T, dtype=float)), np.asarray(o, float))

    @classmethod
    def from_theta(cls, theta: ArrayLike) -> "LumpedModel":
        """Build the model from the parameter vector θ."""
        T, o = unpack_theta(theta)
        return cls.from_T(T, o)

    @property
    def T(self) -> NDArray[np.float64]:
        """``T = C⁻¹`` (not canonicalised)."""
        return np.linalg.inv(self.C)  # type: ignore[return-value]  # numpy stubs type inv of float64 as floating[Any]

    @property
    def A(self) -> NDArray[np.float64]:
        """``A = Tᵀ T`` (Lu 2017, eq. 19), identifiable."""
        T = self.T
        return T.T @ T

    @property
    def T_canonical(self) -> NDArray[np.float64]:
        """Lower-triangular ``T`` with ``Tᵀ T = A``."""
        return canonical_T(self.A)

    @property
    def theta(self) -> NDArray[np.float64]:
        """Identifiable parameter vector θ (see module docstring)."""
        return theta_from(self.T_canonical, self.o)

    def physical(self) -> PhysicalParameters:
        """Decompose the identifiable part into scale, non-orthogonality and bias.

        ``C = T_canonical⁻¹ = S_M C_NO`` exactly (the mounting rotation is not
        identifiable and is absorbed); each row of ``C_NO`` has unit norm.
        """
        C = np.linalg.inv(self.T_canonical)
        scale = np.linalg.norm(C, axis=1)
        cno = C / scale[:, None]
        rho = float(np.arcsin(np.clip(cno[1, 0], -1, 1)))
        lam = float(np.arcsin(np.clip(cno[2, 1], -1, 1)))
        phi = float(np.arcsin(np.clip(cno[2, 0] / np.cos(lam), -1, 1)))
        return PhysicalParameters(scale, rho, phi, lam, self.o.copy())

    def measure(self, directions: ArrayLike) -> NDArray[np.float64]:
        """Noise-free measurements ``C ā_k + o`` for unit directions (n, 3)."""
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        return d @ self.C.T + self.o

    def correct(self, raw: ArrayLike) -> NDArray[np.float64]:
        """Calibrated specific force ``T (a − o)`` in g (Lu 2017, eq. 6)."""
        a = np.asarray(raw, dtype=float)
        return (a - self.o) @ self.T.T


def lu2017_reference_model() -> LumpedModel:
    """The simulated sensor of Lu 2017, section 3.1 (reproduces Table 1's A and o)."""
    mounting = np.eye(3) + np.array([[0, -0.02, -0.05], [0.02, 0, -0.05], [0.05, 0.05, 0]])
    return LumpedModel.from_physical(
        scale=[1.2, 0.8, 1.3],
        rho=np.deg2rad(2.0),
        phi=np.deg2rad(1.0),
        lam=np.deg2rad(1.5),
        bias=[0.20, 0.15, 0.10],
        mounting=mounting,
    )


#: Lu 2017, Table 1, "reference value" row (4 decimals as printed).
LU2017_TABLE1_A_REF = np.array(
    [[0.6936, -0.0384, -0.0099], [-0.0384, 1.5610, -0.0260], [-0.0099, -0.0260, 0.5894]]
)
LU2017_TABLE1_O_REF = np.array([0.20, 0.15, 0.10])
#: Lu 2017, Table 1, "this paper's algorithm" row (Monte Carlo mean).
LU2017_TABLE1_A_PAPER = np.array(
    [[0.6936, -0.0386, -0.0099], [-0.0386, 1.5609, -0.0261], [-0.0099, -0.0261, 0.5893]]
)
LU2017_TABLE1_O_PAPER = np.array([0.19, 0.15, 0.10])
