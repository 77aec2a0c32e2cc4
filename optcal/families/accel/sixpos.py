"""Six-position least squares with known orientations (Yin 2014, eqs. 2-4).

Reconstruction of the lost equations
------------------------------------
The measurement error model (eq. 1, after Farrell 2008, the paper's [8], higher-order terms
dropped) relates the sensor output ``a^b`` to the platform's true specific force ``a^p``::

    a^b = (I + S + M) a^p + b + w                                                       (1)

with S the diagonal scale-factor errors, M the misalignment and cross-coupling (off-diagonal),
b the bias — a constant plus a slow drift (bias instability, rate random walk) — and w white
noise (velocity random walk).  Eq. 3 below is its deterministic part, inverted; the random
part is what :mod:`optcal.families.noise.allan` and :mod:`optcal.applications.papers.yin2014.ekf` deal with.

The platform's roll φ (about x) and pitch θ (about y) are known (a levelled cube placed on
each of its six faces, Yin 2014, Table 2).  The true specific force in the sensor frame is
(eq. 2, ``a^p = C_n^p a^n`` with ``a^n = −g^n``)::

    f(φ, θ) = G [−sin θ,  cos θ sin φ,  cos θ cos φ]ᵀ                                  (2)

optcal writes eq. 2 in the usual tilt-sensing convention of the paper's reference [2]
(Pedley, AN4399): a sensor at rest reads +1 g along the axis that points *up*, so a level
sensor (φ = θ = 0) reads ``(0, 0, +1)`` g.  (The paper's navigation frame has its z axis
down, which flips the sign of the whole vector; with a full 3×3 W that is only a choice of
convention, and this one matches what accelerometers report.)  G = 1: the reference is in g.

The deterministic calibration model (eq. 3) maps the measurement ``a`` of a pose to the true
specific force through a full calibration matrix W (scale, misalignment, cross-coupling)
and a bias vector V (``W = (I + S + M)⁻¹``, ``V = −W b`` for the constant part of b)::

    f_k = W a_k + V,         k = 1 … n                                                  (3)

Stacking the poses as ``X = [a_1 … a_n]`` (3×n), ``Y = [f_1 … f_n]`` and
``X̃ = [X; 1ᵀ]`` (4×n), eq. 3 reads ``Y = [W V] X̃`` and its least-squares solution is
(eq. 4, with optional pose weights ``D = diag(w_k)``)::

    [W V] = Y D X̃ᵀ (X̃ D X̃ᵀ)⁻¹                                                         (4)

Uncertainty
-----------
Each output row of eq. 4 is a linear regression on the same design ``X̃``, so (multivariate
regression) ``Cov([W V]_i, [W V]_j) = S_ij (X̃ D X̃ᵀ)⁻¹`` with ``S`` the 3×3 covariance of the
residuals ``W a_k + V − f_k``.  When the pose table gives the noise of each pose mean
(``sigma``, raw units), ``w_k = 1/σ_k²`` and the residual is ``−W e_k`` with
``e_k ~ N(0, σ_k² I)``, so ``S = W Wᵀ`` (absolute covariance); otherwise ``w_k = 1`` and
``S = R Rᵀ / (n − 4)`` from the residuals R (scaled by the fit; only n − 4 = 2 degrees of
freedom per axis for six poses, so those standard errors are themselves uncertain).  The
regression is on pose means, so the errors-in-variables bias of noisy regressors is of
order σ_mean² and negligible.

Relation to optcal's calibration result
---------------------------------------
``ā = W a + V = T (a − o)`` with ``T = W`` and ``o = −W⁻¹ V``.  With known orientations the
rotation of T *is* identifiable, so T is the full 3×3 W, not the canonical lower-triangular
form of the self-calibrating estimators.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.families.accel.base import Stopwatch
from optcal.core.model import AXES, STANDARD_GRAVITY
from optcal.core.rotations import gravity_direction
from optcal.core.norm_residual import norm_residuals
from optcal.core.poses import PoseTable
from optcal.core.fit_result import SolverInfo
from optcal.core.identifiability import RankReport
from optcal.families.accel.result import CalibrationResult

#: Columns with the known orientation, degrees (Yin 2014, Table 2).
ANGLE_COLUMNS: tuple[str, str] = ("roll_deg", "pitch_deg")
#: Columns with the reference specific force in the sensor frame, g.
REFERENCE_COLUMNS: tuple[str, str, str] = ("gx_ref", "gy_ref", "gz_ref")
#: Six positions are the paper's design (eq. 4 alone would need 4, and 5 for a residual variance).
MIN_POSES: int = 6
#: Parameter names: W row-major, then V.
PARAM_NAMES: tuple[str, ...] = tuple(f"W_{r}{c}" for r in AXES for c in AXES) + tuple(f"V_{r}" for r in AXES)
#: A reference whose mean norm lies in this range is taken to be in m/s² and converted to g.
_MS2_REFERENCE_NORM: tuple[float, float] = (5.0, 20.0)


def reference_from_angles(roll_deg: NDArray, pitch_deg: NDArray) -> NDArray[np.float64]:
    """Unit specific force ``f(φ, θ)`` in the sensor frame for roll/pitch in degrees (Yin 2014, eq. 2)."""
    return gravity_direction(np.radians(np.asarray(roll_deg, dtype=float)), np.radians(np.asarray(pitch_deg, dtype=float)))


def reference_specific_force(poses: PoseTable) -> tuple[NDArray[np.float64], str, list[str]]:
    """The known specific force of each pose, g, from ``poses.extra``.

    Returns
    -------
    reference : ndarray, shape (n, 3)
    source : str
        Which columns were used.
    notes : list of str
    """
    extra = poses.extra
    notes: list[str] = []
    if all(c in extra for c in REFERENCE_COLUMNS):
        ref = np.column_stack([extra[c] for c in REFERENCE_COLUMNS]).astype(float)
        source = ", ".join(REFERENCE_COLUMNS)
        norm = float(np.mean(np.linalg.norm(ref, axis=1)))
        if _MS2_REFERENCE_NORM[0] <= norm <= _MS2_REFERENCE_NORM[1]:
            ref = ref / STANDARD_GRAVITY
            notes.append(
                f"reference columns have mean norm {norm:.4g}, read as m/s^2 and divided by {STANDARD_GRAVITY}"
            )
    elif all(c in extra for c in ANGLE_COLUMNS):
        ref = reference_from_angles(extra["roll_deg"], extra["pitch_deg"])
        source = "roll_deg, pitch_deg (f = [−sin θ, cos θ sin φ, cos θ cos φ] g)"
    else:
        present = sorted(extra) or ["none"]
        raise InputError(
            "the six-position method needs the known orientation of every pose: columns roll_deg and "
            "pitch_deg (degrees; level with z up is 0, 0) or the reference specific force gx_ref, gy_ref, "
            f"gz_ref (g, +1 g on the axis pointing up); extra columns found: {', '.join(present)}"
        )
    if not np.all(np.isfinite(ref)):
        bad = np.flatnonzero(~np.all(np.isfinite(ref), axis=1))
        raise InputError(
            f"the known orientation is missing or not finite for {bad.size} pose(s) "
            f"(rows {', '.join(str(r) for r in poses.rows[bad][:5])}); fill in every pose"
        )
    return ref, source, notes


class SixPositionLeastSquares:
    """Calibration matrix W and bias V from poses of known orientation (Yin 2014, eq. 4).

    Parameters
    ----------
    scale_covariance : bool, optional
        Take the residual covariance from the fit residuals (True) or from the per-pose noise
        ``sigma`` (False).  Default: from ``sigma`` when the pose table has it, else from the
        residuals.
    allow_degenerate : bool
        Accepted for the uniform interface of ``optcal calibrate`` (which passes it to every
        method) and ignored: with known orientations, every pose set that passes
        :meth:`~optcal.core.poses.PoseTable.validate` (measurements not in one plane) determines W
        and V, and any other is refused.
    """

    def __init__(self, scale_covariance: bool | None = None, allow_degenerate: bool = False) -> None:
        self.scale_covariance = scale_covariance

    def fit(self, poses: PoseTable) -> CalibrationResult:
        """Solve eq. 4 and return W, V as a :class:`~optcal.families.accel.result.CalibrationResult`.

        ``T = W``, ``o = −W⁻¹ V`` (so that ``ā = T (a − o) = W a + V``); ``params`` are the
        entries of W (row-major) and V with their covariance; ``W`` and ``V`` are fields of the
        result (its calibration is ``sixpos_full``); ``extra`` holds their standard errors, the
        reference and the vector residuals ``W a_k + V − f_k`` (g).
        """
        if not isinstance(poses, PoseTable):
            raise InputError("fit() takes a PoseTable")
        poses.validate(min_poses=MIN_POSES)
        reference, source, notes = reference_specific_force(poses)
        known = poses.sigma is not None
        scale = (not known) if self.scale_covariance is None else bool(self.scale_covariance)
        if not scale and not known:
            raise InputError("scale_covariance=False needs the per-pose noise column sigma")

        with Stopwatch() as watch:
            weights = np.ones(poses.n) if poses.sigma is None else 1.0 / poses.sigma**2
            X1 = np.vstack([poses.acc.T, np.ones(poses.n)])  # X̃, 4×n
            # eq. 4, with the rows of X̃ scaled to unit rms for conditioning (X̃ has rank 4: validated)
            col_scale = np.sqrt(np.mean(X1**2, axis=1))
            Xs = X1 / col_scale[:, None]
            sw = np.sqrt(weights)
            design = (Xs * sw).T  # n×4
            beta_s, *_ = np.linalg.lstsq(design, (reference * sw[:, None]), rcond=None)  # 4×3
            beta = beta_s / col_scale[:, None]  # rows: coefficients of a_x, a_y, a_z, 1
            W = beta[:3].T
            V = beta[3]
            residual = poses.acc @ W.T + V - reference  # n×3, g
            normal_inv_s = np.linalg.inv(design.T @ design)
            normal_inv = normal_inv_s / np.outer(col_scale, col_scale)  # (X̃ D X̃ᵀ)⁻¹
            dof = poses.n - 4
            chi2_matrix = residual.T @ (residual * weights[:, None])
            S = chi2_matrix / dof if scale else W @ W.T
            cov = _parameter_covariance(S, normal_inv)

        if scale and dof < 4:
            notes.append(
                f"standard errors from the residuals with only {dof} degree(s) of freedom per axis; "
                "give per-pose sigma (noise of each pose mean) for absolute standard errors"
            )
        notes.append("T = W is the full 3x3 calibration matrix (orientation known), not optcal's canonical lower-triangular T")
        o = -np.linalg.solve(W, V)
        params = np.concatenate([W.ravel(), V])
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        redchi = float(np.trace(np.linalg.solve(W @ W.T, chi2_matrix)) / (3 * dof)) if known and dof > 0 else None
        extra: dict[str, Any] = {
            "W_stderr": se[:9].reshape(3, 3),
            "V_stderr": se[9:],
            "reference": reference,
            "reference_source": source,
            "vector_residuals_g": residual,
            "residual_covariance_g2": S,
            "reduced_chi_square_from_sigma": redchi,
        }
        condition = float(np.linalg.cond(design.T @ design))
        return CalibrationResult(
            method="sixpos",
            T=W,
            o=o,
            units=poses.units,
            params=params,
            param_names=list(PARAM_NAMES),
            covariance=cov,
            residuals=norm_residuals(W, o, poses.acc),
            weights=weights,
            # the cost is that of the vector residuals, three scalar observations per pose (eq. 4 is a vector equation)
            chisqr=float(np.sum(weights[:, None] * residual**2)),
            n_observations=3 * poses.n,
            sigma_known=not scale,
            solver=SolverInfo(
                name="numpy.linalg.lstsq",
                status="solved",
                success=True,
                iterations=0,
                solve_time_s=watch.seconds,
                message=f"Yin 2014 eq. 4 on {poses.n} poses, reference from {source}",
            ),
            rows=[int(r) for r in poses.rows],
            exclusions=dict(poses.exclusions),
            identifiability=RankReport(rank=12, n_params=12, condition_number=condition),
            notes=notes,
            extra=extra,
            W=W,
            V=V,
        )


def _parameter_covariance(S: NDArray[np.float64], normal_inv: NDArray[np.float64]) -> NDArray[np.float64]:
    """Covariance of ``[W row-major, V]`` from ``Cov(β_i, β_j) = S_ij (X̃ D X̃ᵀ)⁻¹``.

    ``β_i = [W_i0, W_i1, W_i2, V_i]`` is output row i of eq. 4.
    """
    index = np.array([[3 * i + j for j in range(3)] + [9 + i] for i in range(3)])  # β_i entry → θ slot
    cov = np.zeros((12, 12))
    for i in range(3):
        for j in range(3):
            cov[np.ix_(index[i], index[j])] = S[i, j] * normal_inv
    return cov
