"""Ferraris' calibration of accelerometer and gyroscope from six faces and three turns.

Ferraris, Grimaldi & Parvis (1995), "Procedure for effortless in-field calibration of three-axial
rate gyro and accelerometers", as imucal implements it (mad-lab-fau/imucal,
``imucal/ferraris_calibration.py``, ``FerrarisCalibration.compute``; the equation numbers are those
imucal's comments give).  With ``U_p`` (``U_n``) the 3×3 matrix whose columns are the mean
readings with +x, +y, +z (−x, −y, −z) up and ``g`` the gravity in the output unit::

    U_s = U_p + U_n,   B = U_s / 2,   b_a = diag(B)                         eq. 19, 20
    U_d = U_p − U_n                                                          eq. 21
    K_a = diag(√(diag(U_d U_dᵀ) / (4 g²)))                                   eq. 23
    R_a = K_a⁻¹ U_d / (2 g)                                                  eq. 22
    ā = R_a⁻¹ K_a⁻¹ (a − b_a)                                                (imucal ``_calibrate_acc``)

and for the gyroscope, with ``b_g`` the mean of every sample of the six faces, the g-sensitivity
from the faces' gyro means and ``W_s`` the integrals over the three turns of the gyro, bias and
g-sensitivity removed (its columns: the x, y, z turns), and ``Θ`` the turn angles::

    K_ga = (U_g,p − U_g,n) / (2 g)                                           eq. 9
    W_s[:, i] = Σ_k (ω_k − b_g − K_ga ā_k) Δt                                eq. 13/14
    M = W_s Θ⁻¹                                                              eq. 15
    K_g = diag(√diag(M Mᵀ)),   R_g = K_g⁻¹ M                                 eq. 12
    ω = R_g⁻¹ K_g⁻¹ (ω_raw − b_g − K_ga ā)

optcal's output is in g (``g = 1``): its ``K_a`` and ``K_ga`` are imucal's times imucal's ``grav``
(9.81 m/s² per g), its ``R_a``, ``b_a``, ``K_g``, ``R_g``, ``b_g`` are imucal's.  The accelerometer
is the full calibration ``ā = W a + V`` with ``W = R_a⁻¹ K_a⁻¹`` and ``V = −W b_a`` (the
``sixpos_full`` form of Yin 2014, eq. 3), the gyroscope :class:`optcal.core.gyro_model.GyroModel`
with ``T_g = R_g⁻¹ K_g⁻¹`` (rad/s per raw unit) and ``G_g = K_ga`` (raw units per g).

What the method assumes (and what the pose set cannot tell)
-----------------------------------------------------------
Each pair of opposite faces is taken as exactly opposite (the bias is the pair's mean: a tilt common
to the pair cancels) and the three pair directions as the output frame (orthogonal): a placement
that is not square is absorbed into ``R_a`` as non-orthogonality, which six faces cannot tell from
the sensor's own.  Only the diagonal of ``B`` is used, so the other six entries (each pair's
estimate of the other axes' biases) are a check, not a fit.  Each turn is taken as exactly
``Θ_i`` about its axis.  The standard errors come from the noise of the section means (the
turns: white rate noise integrated over the turn) by the delta method; they leave out these
assumptions, which the held-out rests test.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.fit_result import SolverInfo
from optcal.core.gyro_model import GyroModel
from optcal.core.identifiability import RankReport
from optcal.core.model import AXES
from optcal.core.norm_residual import norm_residuals
from optcal.core.rotations import exponential_map, rotation_angle_deg
from optcal.core.stats import rms
from optcal.data.recording import Recording
from optcal.data.sections import FACE_NAMES, TURN_NAMES
from optcal.data.static import Segmentation
from optcal.data.static_poses import sigma_of_mean
from optcal.data.units import RAD_PER_UNIT, decide_gyro_units
from optcal.errors import InputError
from optcal.families.accel.base import Stopwatch
from optcal.families.accel.result import CalibrationResult
from optcal.families.caltypes.base import FitPoses
from optcal.families.accel.sixpos import PARAM_NAMES as SIXPOS_PARAM_NAMES
from optcal.families.ferraris.regions import AXIS_OF, FerrarisRegions, sample_dt
from optcal.families.gyro.result import ImuCalibration

__all__ = ["FerrarisFit", "TurnReading", "ferraris_accelerometer", "ferraris_equations", "ferraris_fit"]

#: Batches of the batch-means standard error of a section mean (as the static detection's default).
SIGMA_BLOCKS: int = 10
#: Degrees in one full turn (imucal's ``expected_angle`` is −360 for one clockwise turn).
FULL_TURN_DEG: float = 360.0
#: Relative step of the central differences of the delta method, in standard errors of each input.
DELTA_STEP: float = 1e-3
#: Gyro parameter names: T_g row-major, b_g, G_g row-major.
GYRO_PARAM_NAMES: tuple[str, ...] = (
    tuple(f"Tg_{a}{b}" for a in AXES for b in AXES) + tuple(f"bg_{a}" for a in AXES)
    + tuple(f"Gg_{a}{b}" for a in AXES for b in AXES)
)


@dataclass(frozen=True)
class FerrarisInputs:
    """The section statistics the equations use (raw units; ``sums`` over the turns)."""

    acc_p: NDArray[np.float64]   # 3×3, columns: mean acc with +x, +y, +z up
    acc_n: NDArray[np.float64]   # 3×3, columns: −x, −y, −z up
    gyr_p: NDArray[np.float64]   # 3×3, the faces' gyro means
    gyr_n: NDArray[np.float64]
    face_counts: NDArray[np.float64]  # 6, samples of x_p, x_a, y_p, y_a, z_p, z_a
    turn_gyro_dt: NDArray[np.float64]  # 3×3, columns: Σ ω Δt over the x, y, z turns
    turn_acc_dt: NDArray[np.float64]   # 3×3, columns: Σ a Δt
    turn_time: NDArray[np.float64]     # 3, Σ Δt of each turn, s

    def vector(self) -> NDArray[np.float64]:
        return np.concatenate([self.acc_p.ravel(), self.acc_n.ravel(), self.gyr_p.ravel(), self.gyr_n.ravel(),
                               self.turn_gyro_dt.ravel(), self.turn_acc_dt.ravel()])

    def with_vector(self, z: NDArray[np.float64]) -> "FerrarisInputs":
        m = [z[9 * k: 9 * k + 9].reshape(3, 3) for k in range(6)]
        return FerrarisInputs(m[0], m[1], m[2], m[3], self.face_counts, m[4], m[5], self.turn_time)


@dataclass(frozen=True)
class FerrarisMatrices:
    """imucal's matrices in optcal's units (output g for the accelerometer, degrees for the turns)."""

    K_a: NDArray[np.float64]
    R_a: NDArray[np.float64]
    b_a: NDArray[np.float64]
    K_g: NDArray[np.float64]
    R_g: NDArray[np.float64]
    b_g: NDArray[np.float64]
    K_ga: NDArray[np.float64]

    @property
    def W(self) -> NDArray[np.float64]:
        """``R_a⁻¹ K_a⁻¹``, g per raw unit."""
        return np.linalg.inv(self.R_a) @ np.linalg.inv(self.K_a)

    @property
    def V(self) -> NDArray[np.float64]:
        return -self.W @ self.b_a

    @property
    def T_g_deg(self) -> NDArray[np.float64]:
        """``R_g⁻¹ K_g⁻¹``, the turn unit (degrees) per second per raw unit."""
        return np.linalg.inv(self.R_g) @ np.linalg.inv(self.K_g)

    def theta(self) -> NDArray[np.float64]:
        """W row-major, V, T_g (rad/s per raw unit) row-major, b_g, G_g row-major."""
        return np.concatenate([self.W.ravel(), self.V, np.radians(self.T_g_deg).ravel(), self.b_g, self.K_ga.ravel()])

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k).tolist() for k in ("K_a", "R_a", "b_a", "K_g", "R_g", "b_g", "K_ga")}


def ferraris_accelerometer(acc_p: NDArray[np.float64], acc_n: NDArray[np.float64], grav: float = 1.0
                           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``K_a``, ``R_a``, ``b_a`` from the faces' mean readings (columns: +x, +y, +z up; −x, −y, −z up)."""
    b_a = np.diag((acc_p + acc_n) / 2)                          # eq. 19, 20
    U_d = acc_p - acc_n                                          # eq. 21
    K_a = np.diag(np.sqrt(np.diag(U_d @ U_d.T) / (4 * grav**2)))  # eq. 23
    R_a = np.linalg.inv(K_a) @ U_d / (2 * grav)                  # eq. 22
    return K_a, R_a, b_a


def ferraris_equations(x: FerrarisInputs, turn_angles_deg: NDArray[np.float64], grav: float = 1.0) -> FerrarisMatrices:
    """imucal's ``FerrarisCalibration.compute`` on section statistics (module docstring)."""
    K_a, R_a, b_a = ferraris_accelerometer(x.acc_p, x.acc_n, grav)
    counts = x.face_counts
    means = [x.gyr_p[:, 0], x.gyr_n[:, 0], x.gyr_p[:, 1], x.gyr_n[:, 1], x.gyr_p[:, 2], x.gyr_n[:, 2]]
    b_g = np.sum([n * m for n, m in zip(counts, means)], axis=0) / counts.sum()  # mean of every face sample
    K_ga = (x.gyr_p - x.gyr_n) / (2 * grav)                      # eq. 9
    W_acc = np.linalg.inv(R_a) @ np.linalg.inv(K_a)
    # eq. 13/14: Σ (ω − b_g − K_ga ā) Δt, with Σ ā Δt = W (Σ a Δt − b_a Σ Δt)
    acc_dt = W_acc @ (x.turn_acc_dt - np.outer(b_a, x.turn_time))
    W_s = x.turn_gyro_dt - np.outer(b_g, x.turn_time) - K_ga @ acc_dt
    M = W_s @ np.linalg.inv(np.diag(turn_angles_deg))            # eq. 15
    K_g = np.diag(np.sqrt(np.diag(M @ M.T)))                     # eq. 12
    R_g = np.linalg.inv(K_g) @ M
    return FerrarisMatrices(K_a, R_a, b_a, K_g, R_g, b_g, K_ga)


@dataclass(frozen=True)
class TurnReading:
    """One turn as the calibrated gyroscope reads it.

    Attributes
    ----------
    name : str
    expected_deg : float
        The turn angle taken (signed: the sign of the raw reading).
    about_axis_deg : float
        ``Σ ω_axis Δt`` of the calibrated gyro (eq. 13/14 after calibration): the angle read about the turn's axis.
    net_rotation_deg : float
        Angle of the attitude integrated over the turn (0 when a full turn closes exactly).
    how : str
    """

    name: str
    expected_deg: float
    about_axis_deg: float
    net_rotation_deg: float
    how: str


@dataclass
class FerrarisFit:
    """A Ferraris calibration with its statistics (module docstring).

    Attributes
    ----------
    matrices : FerrarisMatrices
    accelerometer : CalibrationResult
        ``ā = W a + V`` (method ``ferraris``), parameters W, V with their covariance; residuals on the six faces.
    gyro : GyroModel
        ``ω = T_g (ω_raw − b_g − G_g ā)`` in rad/s.
    gyro_units, gyro_units_reason : str
    gyro_params : ndarray
        T_g (rad/s per raw unit), b_g, G_g: :data:`GYRO_PARAM_NAMES`.
    gyro_covariance : ndarray
    regions : FerrarisRegions
    turns : list of TurnReading
    held_out : list of dict
        For each rest not used as a face: its interval, samples and ``‖ā‖ − 1`` in g.
    bias_check : ndarray, shape (3, 3)
        ``B − diag(b_a)`` off the diagonal (raw units): what each pair says about the other axes' biases.
    notes : list of str
    """

    matrices: FerrarisMatrices
    accelerometer: CalibrationResult
    gyro: GyroModel
    gyro_units: str
    gyro_units_reason: str
    gyro_params: NDArray[np.float64]
    gyro_covariance: NDArray[np.float64]
    regions: FerrarisRegions
    turns: list[TurnReading]
    held_out: list[dict[str, Any]]
    bias_check: NDArray[np.float64]
    notes: list[str] = field(default_factory=list)

    @property
    def face_rms_mg(self) -> float:
        return 1e3 * self.accelerometer.rms_norm_residual_g

    @property
    def held_out_rms_mg(self) -> float | None:
        values = [h["norm_residual_g"] for h in self.held_out]
        return 1e3 * rms(values) if values else None

    def calibration(self, rec: Recording) -> ImuCalibration:
        """Both sensors as optcal's ``imu`` calibration (what ``-o`` saves; ``check`` and ``apply`` read it).

        The gravity-prediction angles of that type are here the net rotation over each full turn
        (0 for a perfect gyro): before, with the rest bias removed and the nominal scale of the gyro
        units (NaN for counts, which have none); after, calibrated.
        """
        assert rec.gyro is not None
        dt = sample_dt(rec)
        per_unit = RAD_PER_UNIT.get(self.gyro_units)
        before = []
        for name in TURN_NAMES:
            idx = self.regions.sections[name].samples
            before.append(float("nan") if per_unit is None else
                          _net_rotation_deg((rec.gyro[idx] - self.matrices.b_g) * per_unit, dt[idx]))
        return ImuCalibration(
            accelerometer=self.accelerometer, gyro=self.gyro, gyro_units=self.gyro_units,
            gyro_units_reason=self.gyro_units_reason,
            angles_before_deg=np.array(before), angles_after_deg=np.array([t.net_rotation_deg for t in self.turns]),
            before="net rotation over each Ferraris turn, rest bias removed, nominal scale of the gyro units",
            accelerometer_mode="ferraris", units=self.accelerometer.units, fitted_on=self.accelerometer.fitted_on,
            params=self.gyro_params, param_names=list(GYRO_PARAM_NAMES), covariance=self.gyro_covariance,
            solver=self.accelerometer.solver, exclusions=dict(self.accelerometer.exclusions),
            notes=list(self.accelerometer.notes) + list(self.notes),
        )

    @property
    def gyro_stderr(self) -> dict[str, float]:
        return dict(zip(GYRO_PARAM_NAMES, np.sqrt(np.clip(np.diag(self.gyro_covariance), 0.0, None)).tolist()))


def _section_stats(rec: Recording, regions: FerrarisRegions) -> tuple[FerrarisInputs, NDArray[np.float64]]:
    """The inputs, and the variance of each entry of :meth:`FerrarisInputs.vector` (independent sections)."""
    gyro = rec.gyro
    assert gyro is not None
    acc_cols: dict[str, NDArray[np.float64]] = {}
    gyr_cols: dict[str, NDArray[np.float64]] = {}
    acc_var: dict[str, float] = {}
    gyr_var: dict[str, float] = {}
    counts = []
    acc_noise, gyr_noise = [], []
    for name in FACE_NAMES:
        idx = regions.sections[name].samples
        a, g = rec.acc[idx], gyro[idx]
        acc_cols[name], gyr_cols[name] = a.mean(axis=0), g.mean(axis=0)
        acc_var[name] = sigma_of_mean(a, SIGMA_BLOCKS) ** 2
        gyr_var[name] = sigma_of_mean(g, SIGMA_BLOCKS) ** 2
        counts.append(idx.size)
        acc_noise.append(a.std(axis=0, ddof=1))
        gyr_noise.append(g.std(axis=0, ddof=1))
    dt = sample_dt(rec)
    turn_g = np.zeros((3, 3))
    turn_a = np.zeros((3, 3))
    turn_t = np.zeros(3)
    for i, name in enumerate(TURN_NAMES):
        idx = regions.sections[name].samples
        turn_g[:, i] = (gyro[idx] * dt[idx, None]).sum(axis=0)
        turn_a[:, i] = (rec.acc[idx] * dt[idx, None]).sum(axis=0)
        turn_t[i] = dt[idx].sum()
    p, n = ["x_p", "y_p", "z_p"], ["x_a", "y_a", "z_a"]
    x = FerrarisInputs(
        np.column_stack([acc_cols[k] for k in p]), np.column_stack([acc_cols[k] for k in n]),
        np.column_stack([gyr_cols[k] for k in p]), np.column_stack([gyr_cols[k] for k in n]),
        np.array(counts, dtype=float), turn_g, turn_a, turn_t,
    )
    # white rate (acc) noise of the rests, summed over a turn's samples: σ² Σ Δt² (row = axis, column = turn)
    sg2 = np.mean(np.square(gyr_noise), axis=0)
    sa2 = np.mean(np.square(acc_noise), axis=0)
    dt2 = np.array([np.sum(dt[regions.sections[k].samples] ** 2) for k in TURN_NAMES])
    var = np.concatenate([
        np.repeat([acc_var[k] for k in p], 3).reshape(3, 3).T.ravel(),  # column j is face j: entry (axis, face)
        np.repeat([acc_var[k] for k in n], 3).reshape(3, 3).T.ravel(),
        np.repeat([gyr_var[k] for k in p], 3).reshape(3, 3).T.ravel(),
        np.repeat([gyr_var[k] for k in n], 3).reshape(3, 3).T.ravel(),
        np.outer(sg2, dt2).ravel(),
        np.outer(sa2, dt2).ravel(),
    ])
    return x, var


def _turn_angles(rec: Recording, x: FerrarisInputs, turn_angle_deg: float | None, gyro_units: str | None
                 ) -> tuple[NDArray[np.float64], str, str, str]:
    """The signed angle of each turn (degrees), with the gyro units decision and why."""
    assert rec.gyro is not None
    bias = np.mean(np.column_stack([x.gyr_p, x.gyr_n]), axis=1)
    decision = decide_gyro_units(rec.gyro[rec.gyro_usable], bias, gyro_units, rec.gyro_units)
    raw = np.array([x.turn_gyro_dt[i, i] - bias[i] * x.turn_time[i] for i in range(3)])
    if np.any(raw == 0):
        raise InputError("a Ferraris turn integrates to exactly zero about its axis: no turn in that stretch")
    sign = np.sign(raw)
    per_unit = RAD_PER_UNIT.get(decision.units)
    if turn_angle_deg is not None:
        angles = sign * abs(turn_angle_deg)
        why = f"{abs(turn_angle_deg):g}° per turn (given with --turn-angle)"
    elif per_unit is None:
        angles = sign * FULL_TURN_DEG
        why = (f"one full turn each ({FULL_TURN_DEG:g}°, imucal's default): gyro units {decision.units}, so the "
               "reading cannot count the turns; --turn-angle DEG for another")
    else:
        read = np.degrees(np.abs(raw) * per_unit)
        turns = np.rint(read / FULL_TURN_DEG)
        if np.any(turns < 1):
            bad = TURN_NAMES[int(np.argmin(turns))]
            raise InputError(f"the {bad} stretch turns only {read[int(np.argmin(turns))]:.0f}° about its axis "
                             f"(gyro in {decision.units}): not a full turn; give the sections (--sections) or --turn-angle")
        angles = sign * turns * FULL_TURN_DEG
        why = ("whole turns nearest the reading in " + decision.units + " ("
               + ", ".join(f"{TURN_NAMES[i]} {sign[i] * read[i]:+.1f}°" for i in range(3)) + "); --turn-angle DEG to set it")
    why += "; the sign is the raw reading's (imucal: −360 for a clockwise turn)"
    return angles, why, decision.units, decision.reason


def _jacobian(x: FerrarisInputs, var: NDArray[np.float64], angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """dθ/dz by central differences (θ: :meth:`FerrarisMatrices.theta`, z: :meth:`FerrarisInputs.vector`)."""
    z = x.vector()
    steps = DELTA_STEP * np.maximum(np.sqrt(var), 1e-12 * np.maximum(np.abs(z), 1.0))
    cols = []
    for k, h in enumerate(steps):
        e = np.zeros(z.size)
        e[k] = h
        hi = ferraris_equations(x.with_vector(z + e), angles).theta()
        lo = ferraris_equations(x.with_vector(z - e), angles).theta()
        cols.append((hi - lo) / (2 * h))
    return np.column_stack(cols)


def _net_rotation_deg(omega_rad_s: NDArray[np.float64], dt: NDArray[np.float64]) -> float:
    """Angle of the attitude ``Π exp([ω Δt]×)`` integrated over the samples, degrees (the steps composed in order,
    pairwise)."""
    steps = exponential_map(np.asarray(omega_rad_s, dtype=float).reshape(-1, 3) * np.asarray(dt, dtype=float)[:, None])
    while steps.shape[0] > 1:
        if steps.shape[0] % 2:
            steps = np.concatenate([steps, np.eye(3)[None]])
        steps = steps[0::2] @ steps[1::2]
    return rotation_angle_deg(steps[0]) if steps.shape[0] else 0.0


def ferraris_fit(
    seg: Segmentation,
    regions: FerrarisRegions,
    *,
    turn_angle_deg: float | None = None,
    gyro_units: str | None = None,
) -> FerrarisFit:
    """Ferraris' calibration of a recording from its nine sections (module docstring).

    Parameters
    ----------
    seg : Segmentation
        The recording and its static intervals (the rests not used as faces are the held-out check).
    regions : FerrarisRegions
        The nine sections (:mod:`optcal.families.ferraris.regions`).
    turn_angle_deg : float, optional
        The angle of each turn; default: the whole turns nearest the reading (one, for counts).
    gyro_units : str, optional
        Units of the gyro columns (decided from the file and the data when omitted).

    Raises
    ------
    InputError
        No gyro columns; a section without samples; a turn that does not turn.
    """
    rec = seg.recording
    if rec.gyro is None:
        raise InputError("the Ferraris method needs the gyro columns (gx, gy, gz): its turns calibrate the gyroscope")
    with Stopwatch() as watch:
        x, var = _section_stats(rec, regions)
        angles, angle_why, g_units, g_why = _turn_angles(rec, x, turn_angle_deg, gyro_units)
        mats = ferraris_equations(x, angles)
        J = _jacobian(x, var, angles)
        cov = J @ (J * var).T
    W, V = mats.W, mats.V
    acc_cov = cov[:12, :12]
    face_means = np.column_stack([x.acc_p, x.acc_n]).T  # x_p, y_p, z_p, x_a, y_a, z_a
    nominal = np.vstack([np.eye(3), -np.eye(3)])
    vec_res = face_means @ W.T + V - nominal
    # σ of each face mean (x_p, y_p, z_p, x_a, y_a, z_a; pooled over the axes), raw units → g
    pose_sigma_g = np.sqrt(var[[0, 1, 2, 9, 10, 11]]) * float(np.mean(np.abs(np.diag(W))))
    weights = 1.0 / pose_sigma_g**2
    order = [0, 3, 1, 4, 2, 5]  # x_p, x_a, y_p, y_a, z_p, z_a: imucal's order
    U_d = x.acc_p - x.acc_n
    B = (x.acc_p + x.acc_n) / 2
    notes = [
        "Ferraris 1995 as imucal implements it (imucal/ferraris_calibration.py, eqs. 9, 12-15, 19-23): "
        "bias from the pairs of opposite faces (a tilt common to a pair cancels), scale and axes from their differences",
        "W = R_a^-1 K_a^-1 is the full 3x3 calibration in the frame of the three pairs of faces (taken as orthogonal)",
        "standard errors from the noise of the section means (batch means; turns: white rate noise), by the delta "
        "method; the placement (pairs exactly opposite, faces square, turns exactly about their axes) is assumed, "
        "and the held-out rests test it",
        f"turn angles: {angle_why}",
    ]
    accelerometer = CalibrationResult(
        method="ferraris",
        T=W,
        o=mats.b_a,
        units=rec.units,
        params=np.concatenate([W.ravel(), V]),
        param_names=list(SIXPOS_PARAM_NAMES),
        covariance=acc_cov,
        residuals=norm_residuals(W, mats.b_a, face_means[order]),
        weights=weights[order],
        chisqr=float(np.sum(weights[:, None] * vec_res**2)),
        n_observations=18,
        sigma_known=True,
        solver=SolverInfo(name="closed form", status="solved", success=True, iterations=0, solve_time_s=watch.seconds,
                          message="Ferraris 1995 (imucal's equations) on six faces and three turns"),
        rows=[regions.sections[n].interval or 0 for n in FACE_NAMES],
        exclusions=dict(seg.exclusions),
        identifiability=RankReport(rank=int(np.linalg.matrix_rank(U_d)) * 4, n_params=12,
                                   condition_number=float(np.linalg.cond(U_d))),
        notes=notes,
        extra={"ferraris": mats.to_dict(), "vector_residuals_g": vec_res[order], "faces": list(FACE_NAMES)},
        W=W,
        V=V,
    )
    accelerometer.fitted_on = FitPoses(face_means[order].copy(), None, None)
    gyro = GyroModel(np.radians(mats.T_g_deg), mats.b_g, mats.K_ga)
    # the turns as the calibrated gyroscope reads them
    dt = sample_dt(rec)
    turns = []
    assert rec.gyro is not None
    for i, name in enumerate(TURN_NAMES):
        idx = regions.sections[name].samples
        omega_deg = np.degrees(gyro.correct(rec.gyro[idx], accelerometer.correct(rec.acc[idx])))
        about = float((omega_deg[:, AXIS_OF[name]] * dt[idx]).sum())
        net = _net_rotation_deg(np.radians(omega_deg), dt[idx])
        turns.append(TurnReading(name, float(angles[i]), about, net, regions.sections[name].how))
    held = []
    for iv in seg.intervals:
        if iv.number in regions.held_out:
            r = float(np.linalg.norm(W @ iv.mean + V) - 1.0)
            held.append({"interval": iv.number, "n_samples": iv.n_samples, "rows": [iv.first_row, iv.last_row],
                         "norm_residual_g": r})
    if not held:
        notes.append("no rest outside the six faces: no held-out check (record a few rests in other orientations)")
    return FerrarisFit(
        matrices=mats, accelerometer=accelerometer, gyro=gyro, gyro_units=g_units, gyro_units_reason=g_why,
        gyro_params=mats.theta()[12:],  # T_g (rad/s per raw unit), b_g, G_g
        gyro_covariance=cov[12:, 12:], regions=regions, turns=turns, held_out=held,
        bias_check=B - mats.b_a[:, None], notes=list(regions.notes),
    )
