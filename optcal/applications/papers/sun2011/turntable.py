"""Three-axis turntable simulator for the ten-position calibration of Sun & Cao 2011.

Frames and attitude (Sun 2011, section 1)
-----------------------------------------
* ``n``: navigation frame, east-north-up (ENU).  ``b``: body frame of the strapdown unit,
  x right, y forward, z up.  At (pitch, roll, heading) = (0, 0, 0) the body axes are
  east, north, up.
* Attitude: ``C_b^n = R_z(−ψ) R_x(θ) R_y(γ)`` (active rotations; pitch θ about x, roll γ
  about y, heading ψ clockwise from north).  This is the convention that reproduces the
  paper's eq. 14 exactly (:func:`optcal.core.rotations.turntable_attitude`), e.g. for
  (θ, γ, ψ) = (π/2, π/2, β)::

      C_b^n = [[sin β, 0, cos β], [cos β, 0, −sin β], [0, 1, 0]]

  Each position of Table 1 is a (pitch, roll, heading) triple of the three gimbals: heading
  is the outer (vertical) axis, pitch the middle axis, roll the inner axis.
* Specific force at rest (eq. 1): ``f^b = C_n^b [0, 0, g]ᵀ = g [C31, C32, C33]ᵀ`` with
  ``C_ij`` the entries of ``C_b^n``.

Accelerometer error model (eq. 2-3)
-----------------------------------
``V̄^b = b_a + (ΔC_b^a + S_a) f^b`` with the biases ``b_a = [b_x, b_y, b_z]`` and the
installation-error matrix::

    ΔC_b^a = [[ 0,     τ_xz, −τ_xy],
              [−τ_yz,  0,     τ_yx],
              [ τ_zy, −τ_zx,  0   ]]

``τ_ij`` is the small rotation of accelerometer axis ``i`` about body axis ``j`` (x about
z → sensitivity to f_y, x about y → −f_z, and so on).  The extracted text of eq. 2 is
garbled (τ_xx for τ_xz, τ_xy for τ_zy) and its second row reads ``[−τ_yx, 0, τ_yz]``; with
that row, step 1 of Table 1 (z vertical) would excite τ_yz, not τ_yx as Table 1, eq. 29
and Table 3 say.  The row above is the one consistent with Table 1, eq. 29, eq. 30 and
Table 3 (every τ_ij is "axis i about axis j").  The scale factors ``S_a`` are zero here:
the method cannot determine them (eq. 11; the paper's conclusion) and the simulation, like
the paper's, injects only residual biases and installation errors.

Simulated errors (section 3)
----------------------------
* residual bias 100 µg on every axis, residual installation error 0.1′ on every τ (the
  "set values" of Tables 2 and 3: 0.978e-3 m/s² with g = 9.78 m/s², 2.909e-5 rad);
* turntable angle-control error 1″ (σ of each gimbal angle, independently at each position);
* axis non-orthogonality 2″ (the middle axis tilted from its nominal direction by 2″, and
  the inner axis likewise, each in a random direction fixed for one turntable, i.e. one
  Monte Carlo run);
* gyro constant drift 0.01 °/h on each axis (random sign per run);
* white noise with the paper's Q as spectral densities: 50 µg/√Hz (accelerometers),
  0.005 °/h/√Hz (gyros);
* latitude 45.78° N (the longitude, 126.67° E, does not enter a static-base model);
* 60 s per position; the SINS is initialised at each position from the turntable's nominal
  attitude with the coarse-alignment misalignment φ0 = (0.1°, 0.1°, 0.5°), so that the
  true initial misalignment is φ0 plus the turntable's attitude error at that position.

What the paper leaves open (the noise densities, the statistics of the turntable errors,
the sign of the drifts, re-initialisation per position) is fixed as above and stated again
in the reproduction's output.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from optcal.core.model import EARTH_RATE
from optcal.core.rotations import axis_rotation, exponential_map, logarithm_map, turntable_attitude
from optcal.errors import InputError

#: Gravity used by Sun 2011 (100 µg = 0.978e-3 m/s², Table 2), m/s².
SUN2011_GRAVITY: float = 9.78
ARCSEC: float = np.pi / (180.0 * 3600.0)
ARCMIN: float = np.pi / (180.0 * 60.0)
DEG_PER_HOUR: float = np.pi / 180.0 / 3600.0
#: Names of the installation errors, in the order of Table 3.
TAU_NAMES: tuple[str, ...] = ("tau_xy", "tau_yx", "tau_xz", "tau_zx", "tau_yz", "tau_zy")
#: Calibration parameters: biases (Table 2) then installation errors (Table 3).
PARAM_NAMES: tuple[str, ...] = ("b_x", "b_y", "b_z") + TAU_NAMES
#: (row, column) of each τ in ΔC_b^a and its sign (Sun 2011, eq. 2, corrected row 2).
TAU_ENTRIES: dict[str, tuple[int, int, float]] = {
    "tau_xz": (0, 1, +1.0),
    "tau_xy": (0, 2, -1.0),
    "tau_yz": (1, 0, -1.0),
    "tau_yx": (1, 2, +1.0),
    "tau_zy": (2, 0, +1.0),
    "tau_zx": (2, 1, -1.0),
}


@dataclass(frozen=True)
class TurntablePosition:
    """One turntable position of Table 1 (angles in radians).

    Attributes
    ----------
    label : str
        ``"1a"`` … ``"4b"`` (step and order within the step).
    step : int
        Step of Table 1 (1-4).
    pitch, roll, heading : float
        Gimbal angles (θ, γ, ψ).
    """

    label: str
    step: int
    pitch: float
    roll: float
    heading: float

    @property
    def attitude(self) -> NDArray[np.float64]:
        """Nominal ``C_b^n``."""
        return turntable_attitude(self.pitch, self.roll, self.heading)

    def degrees(self) -> tuple[float, float, float]:
        """(pitch, roll, heading) in degrees."""
        return tuple(float(np.rad2deg(a)) for a in (self.pitch, self.roll, self.heading))  # type: ignore[return-value]


def step3_positions(beta1: float, beta2: float) -> tuple[TurntablePosition, TurntablePosition]:
    """Step 3 of Table 1: (π/2, π/2, β1) and (−π/2, π/2, β2) (radians)."""
    h = np.pi / 2
    return TurntablePosition("3a", 3, h, h, beta1), TurntablePosition("3b", 3, -h, h, beta2)


def ten_position_scheme(
    step3_beta: tuple[float, float] = (np.pi / 4, -np.pi / 4),
    step4_beta: tuple[float, float] = (np.pi / 4, -np.pi / 4),
) -> tuple[TurntablePosition, ...]:
    """The ten positions of Table 1 in the order of the four steps.

    Step 3 defaults to the paper's optimal path β1 = 45°, β2 = −45° (Table 4, path 4; the
    sign that makes eq. 27 follow from eq. 17).  Step 4 uses β3 = 45°, β4 = −45°, which
    gives the 1/√2 of eq. 30.
    """
    h, p = np.pi / 2, np.pi
    return (
        TurntablePosition("1a", 1, 0.0, 0.0, 0.0),
        TurntablePosition("1b", 1, 0.0, 0.0, p),
        TurntablePosition("1c", 1, p, 0.0, 0.0),
        TurntablePosition("1d", 1, 0.0, p, 0.0),
        TurntablePosition("2a", 2, h, 0.0, 0.0),
        TurntablePosition("2b", 2, -h, 0.0, 0.0),
        *step3_positions(*step3_beta),
        TurntablePosition("4a", 4, 0.0, h, step4_beta[0]),
        TurntablePosition("4b", 4, p, -h, step4_beta[1]),
    )


@dataclass(frozen=True)
class AccelerometerErrors:
    """Biases (m/s²) and installation errors (rad) of Sun 2011, eq. 2.

    Attributes
    ----------
    values : ndarray, shape (..., 9)
        In the order of :data:`PARAM_NAMES`; leading dimensions are Monte Carlo runs.
    """

    values: NDArray[np.float64]

    def __post_init__(self) -> None:
        v = np.asarray(self.values, dtype=float)
        if v.shape[-1:] != (len(PARAM_NAMES),):
            raise InputError(f"accelerometer errors need {len(PARAM_NAMES)} values ({', '.join(PARAM_NAMES)})")
        object.__setattr__(self, "values", v)

    @classmethod
    def uniform(cls, bias: float, tau: float) -> "AccelerometerErrors":
        """The same bias on every axis and the same value for every τ (the paper's set values)."""
        return cls(np.array([bias] * 3 + [tau] * 6))

    @property
    def bias(self) -> NDArray[np.float64]:
        """``b_a``, shape (..., 3)."""
        return self.values[..., :3]

    def tau(self, name: str) -> NDArray[np.float64]:
        """One installation error by name."""
        return self.values[..., PARAM_NAMES.index(name)]

    def misalignment_matrix(self) -> NDArray[np.float64]:
        """``ΔC_b^a``, shape (..., 3, 3) (module docstring)."""
        M = np.zeros(self.values.shape[:-1] + (3, 3))
        for name, (i, j, sign) in TAU_ENTRIES.items():
            M[..., i, j] = sign * self.tau(name)
        return M

    def error(self, f_b: ArrayLike) -> NDArray[np.float64]:
        """``V̄^b = b_a + ΔC_b^a f^b`` (eq. 2 without scale factors) for f^b of shape (..., 3)."""
        f = np.asarray(f_b, dtype=float)
        return self.bias + np.einsum("...ij,...j->...i", self.misalignment_matrix(), f)


@dataclass(frozen=True)
class SimulationSettings:
    """Section 3 of Sun 2011 (defaults) and the choices it leaves open (module docstring)."""

    latitude_deg: float = 45.78
    gravity: float = SUN2011_GRAVITY
    duration_s: float = 60.0
    dt_s: float = 1.0
    residual_bias_ug: float = 100.0
    residual_installation_arcmin: float = 0.1
    angle_error_arcsec: float = 1.0
    non_orthogonality_arcsec: float = 2.0
    gyro_drift_deg_h: float = 0.01
    initial_misalignment_deg: tuple[float, float, float] = (0.1, 0.1, 0.5)
    accel_noise_ug_rthz: float = 50.0
    gyro_noise_deg_h_rthz: float = 0.005

    def __post_init__(self) -> None:
        if self.dt_s <= 0 or self.duration_s < self.dt_s:
            raise InputError("the time step must be positive and no longer than the time per position")
        if abs(self.latitude_deg) >= 90:
            raise InputError("latitude must be strictly between −90° and 90°")

    @property
    def latitude(self) -> float:
        """Latitude, rad."""
        return float(np.deg2rad(self.latitude_deg))

    @property
    def n_steps(self) -> int:
        """Samples per position."""
        return int(round(self.duration_s / self.dt_s))

    def set_errors(self) -> AccelerometerErrors:
        """The injected residual errors (Tables 2 and 3, "set value")."""
        return AccelerometerErrors.uniform(
            self.residual_bias_ug * 1e-6 * self.gravity, self.residual_installation_arcmin * ARCMIN
        )

    @property
    def earth_rate_n(self) -> NDArray[np.float64]:
        """``ω_ie^n`` in ENU, rad/s."""
        return EARTH_RATE * np.array([0.0, np.cos(self.latitude), np.sin(self.latitude)])


@dataclass(frozen=True)
class Turntable:
    """One realisation of the turntable's errors per Monte Carlo run.

    Attributes
    ----------
    tilt_middle, tilt_inner : ndarray, shape (runs, 3)
        Rotation vectors tilting the middle (pitch) and inner (roll) axes from their nominal
        directions (axis non-orthogonality), radians.
    gyro_drift : ndarray, shape (runs, 3)
        Constant gyro drift in the body frame, rad/s.
    """

    tilt_middle: NDArray[np.float64]
    tilt_inner: NDArray[np.float64]
    gyro_drift: NDArray[np.float64]

    @classmethod
    def draw(cls, settings: SimulationSettings, runs: int, rng: np.random.Generator) -> "Turntable":
        """Draw the turntable and gyro errors of ``runs`` Monte Carlo runs."""
        eta = settings.non_orthogonality_arcsec * ARCSEC

        def tilt(axis: int) -> NDArray[np.float64]:
            # a rotation of size η about a random direction perpendicular to the gimbal axis
            a = rng.uniform(0, 2 * np.pi, runs)
            i, j = [k for k in range(3) if k != axis]
            v = np.zeros((runs, 3))
            v[:, i], v[:, j] = eta * np.cos(a), eta * np.sin(a)
            return v

        drift = settings.gyro_drift_deg_h * DEG_PER_HOUR * rng.choice([-1.0, 1.0], size=(runs, 3))
        return cls(tilt(0), tilt(1), drift)

    @property
    def runs(self) -> int:
        return int(self.gyro_drift.shape[0])

    def true_attitude(self, position: TurntablePosition, angle_errors: NDArray[np.float64]) -> NDArray[np.float64]:
        """Actual ``C_b^n`` (runs, 3, 3) for gimbal-angle errors (runs, 3) = (δθ, δγ, δψ).

        A rotation about a tilted axis ``E u`` is ``E R_u E^T``, so each tilted gimbal
        contributes ``E R E^T`` in place of ``R``.
        """
        Em = exponential_map(self.tilt_middle)
        Ei = exponential_map(self.tilt_inner)
        Rz = axis_rotation(2, -(position.heading + angle_errors[:, 2]))
        Rx = Em @ axis_rotation(0, position.pitch + angle_errors[:, 0]) @ np.swapaxes(Em, -1, -2)
        Ry = Ei @ axis_rotation(1, position.roll + angle_errors[:, 1]) @ np.swapaxes(Ei, -1, -2)
        return Rz @ Rx @ Ry


@dataclass(frozen=True)
class PositionData:
    """What the strapdown unit sees at one position, for every Monte Carlo run.

    Attributes
    ----------
    position : TurntablePosition
    C_nominal : ndarray, shape (3, 3)
        ``C_b^n`` commanded (what the turntable reports; used by the filter and eq. 12-13).
    C_true : ndarray, shape (runs, 3, 3)
        Actual ``C_b^n``.
    phi0 : ndarray, shape (runs, 3)
        True initial misalignment of the navigation attitude (ENU, rad): φ0 plus the
        turntable's attitude error, from ``C_b^p(0) = (I − φ0×) C_nominal = (I − φ×) C_true``.
    f_ideal, omega_ideal : ndarray, shape (3,)
        Specific force (m/s²) and angular rate (rad/s) in the body frame at the nominal attitude.
    f_true, omega_true : ndarray, shape (runs, 3)
        The same at the actual attitude.
    f_meas, omega_meas : ndarray, shape (runs, n_steps, 3)
        Accelerometer and gyro outputs (mean over each step of length dt), with errors.
    """

    position: TurntablePosition
    C_nominal: NDArray[np.float64]
    C_true: NDArray[np.float64]
    phi0: NDArray[np.float64]
    f_ideal: NDArray[np.float64]
    omega_ideal: NDArray[np.float64]
    f_true: NDArray[np.float64]
    omega_true: NDArray[np.float64]
    f_meas: NDArray[np.float64]
    omega_meas: NDArray[np.float64]

    def accel_error_b(self, compensation: AccelerometerErrors | None = None) -> NDArray[np.float64]:
        """Accelerometer error in the body frame after compensation, (runs, n_steps, 3).

        ``compensation`` holds the estimated errors (runs, 9); they are removed from the
        output to first order, ``f_c = f_meas − b̂ − ΔĈ f_meas`` (the note of Table 1).
        """
        f = self.f_meas
        if compensation is not None:
            f = f - compensation.bias[:, None, :] - np.einsum(
                "rij,rkj->rki", compensation.misalignment_matrix(), f
            )
        return f - self.f_true[:, None, :]

    def gyro_error_b(self) -> NDArray[np.float64]:
        """Gyro error in the body frame, (runs, n_steps, 3)."""
        return self.omega_meas - self.omega_true[:, None, :]

    def mean_output(self) -> NDArray[np.float64]:
        """Mean accelerometer output over the position, (runs, 3), m/s²."""
        return self.f_meas.mean(axis=1)


def simulate_position(
    position: TurntablePosition,
    settings: SimulationSettings,
    turntable: Turntable,
    errors: AccelerometerErrors,
    rng: np.random.Generator,
) -> PositionData:
    """Simulate one position for every run of ``turntable`` (module docstring).

    ``errors`` are the true accelerometer errors, shape (9,) or (runs, 9).
    """
    runs, n = turntable.runs, settings.n_steps
    g_n = np.array([0.0, 0.0, settings.gravity])
    C_nom = position.attitude
    angle_err = rng.normal(0.0, settings.angle_error_arcsec * ARCSEC, (runs, 3))
    C_true = turntable.true_attitude(position, angle_err)
    # (I − φ×) = (I − φ0×) C_nom C_trueᵀ, exactly as a rotation: φ = −rotvec(...)
    phi0 = np.deg2rad(np.asarray(settings.initial_misalignment_deg, float))
    C_p_n = exponential_map(-phi0) @ C_nom @ np.swapaxes(C_true, -1, -2)
    phi = -logarithm_map(C_p_n)
    f_true = np.einsum("rji,j->ri", C_true, g_n)  # f^b = C_n^b g^n (eq. 1)
    w_true = np.einsum("rji,j->ri", C_true, settings.earth_rate_n)
    acc_sd = settings.accel_noise_ug_rthz * 1e-6 * settings.gravity / np.sqrt(settings.dt_s)
    gyro_sd = settings.gyro_noise_deg_h_rthz * DEG_PER_HOUR / np.sqrt(settings.dt_s)
    err = np.broadcast_to(errors.values, (runs, len(PARAM_NAMES)))
    f_meas = (f_true + AccelerometerErrors(err).error(f_true))[:, None, :] + rng.normal(0.0, acc_sd, (runs, n, 3))
    w_meas = (w_true + turntable.gyro_drift)[:, None, :] + rng.normal(0.0, gyro_sd, (runs, n, 3))
    return PositionData(
        position=position,
        C_nominal=C_nom,
        C_true=C_true,
        phi0=phi,
        f_ideal=C_nom.T @ g_n,
        omega_ideal=C_nom.T @ settings.earth_rate_n,
        f_true=f_true,
        omega_true=w_true,
        f_meas=f_meas,
        omega_meas=w_meas,
    )


@dataclass
class TurntableRun:
    """A simulated session: the turntable, the true errors and the data of each position.

    Positions are simulated on demand (:meth:`position`) and cached by label, so that a
    scheme and its variants (Table 4 paths) share the data of common positions.
    """

    settings: SimulationSettings
    turntable: Turntable
    errors: AccelerometerErrors
    rng: np.random.Generator
    data: dict[str, PositionData] = field(default_factory=dict)

    @classmethod
    def start(
        cls,
        settings: SimulationSettings,
        runs: int,
        seed: int | Sequence[int] = 0,
        errors: AccelerometerErrors | None = None,
    ) -> "TurntableRun":
        """A new session of ``runs`` Monte Carlo runs (errors default to the set values)."""
        if runs < 1:
            raise InputError("at least one Monte Carlo run is needed")
        rng = np.random.default_rng(seed)
        return cls(settings, Turntable.draw(settings, runs, rng), errors or settings.set_errors(), rng)

    def position(self, position: TurntablePosition) -> PositionData:
        """Data of one position (simulated at the first request)."""
        key = f"{position.pitch:.12f},{position.roll:.12f},{position.heading:.12f}"
        if key not in self.data:
            self.data[key] = simulate_position(position, self.settings, self.turntable, self.errors, self.rng)
        return self.data[key]


def mean_outputs_g(data: list[PositionData], gravity: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-position mean accelerometer outputs in g, for static calibration.

    Returns
    -------
    acc : ndarray, shape (runs, positions, 3)
        Mean output of each position divided by the local gravity (so that the true
        specific force has norm 1).
    n_samples : ndarray, shape (positions,)
        Samples averaged per position.
    """
    acc = np.stack([d.mean_output() for d in data], axis=1) / gravity
    return acc, np.array([d.f_meas.shape[1] for d in data], dtype=float)
