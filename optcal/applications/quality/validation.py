"""Validating a calibration on measured data.

* :func:`check_calibration`: the norm error ``‖ā_k‖ − 1`` of every pose before (nominal
  conversion, :func:`optcal.data.units.nominal_conversion`) and after calibration, with the
  spread expected from the pose noise alone (Lu 2017, section 3.2.1, the RMSE of the norm).
* :func:`held_out_validation`: calibrate on part of the poses and test on the others
  (Lu 2017, section 3.2.2 validates on 20 further attitudes); k-fold or a given split.
* :func:`displacement_integration`: the displacement obtained by integrating the specific
  force of a static log twice after removing gravity (Lu 2017, section 3.2.3, eq. 31);
  at rest it should be zero, and calibration should make it smaller.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.data.units import NominalConversion, nominal_conversion
from optcal.errors import InputError
from optcal.core.model import STANDARD_GRAVITY
from optcal.core.norm_residual import norm_residuals, normal_gain
from optcal.core.poses import MIN_POSES, PoseTable
from optcal.core.rotations import rotation_between
from optcal.core.stats import rms
from optcal.families.caltypes import Calibration
from optcal.core.jsonio import jsonable
from optcal.families.accel.result import CalibrationResult

G_TO_MS2 = {"g": 1.0, "m/s^2": STANDARD_GRAVITY}


def norm_noise(T: ArrayLike, o: ArrayLike, acc: ArrayLike, sigma: ArrayLike) -> NDArray[np.float64]:
    """Standard deviation of ``‖T(a_k − o)‖`` caused by isotropic noise ``σ_k`` on ``a_k``, g.

    First order: ``σ_k ‖Tᵀ v_k‖`` with ``v_k`` the unit calibrated vector.
    """
    return np.asarray(sigma, float) * normal_gain(T, o, acc)


@dataclass
class NormCheck:
    """Norm errors of a calibration on a set of poses.

    Attributes
    ----------
    rows : ndarray of int
    t, n_samples : ndarray or None
    before, after : ndarray
        ``‖a_k‖ − 1`` in g by the nominal conversion, and after calibration.
    noise : ndarray or None
        Expected standard deviation of ``after`` from the pose noise alone.
    nominal : NominalConversion
    """

    rows: NDArray[np.int64]
    t: NDArray[np.float64] | None
    n_samples: NDArray[np.float64] | None
    before: NDArray[np.float64]
    after: NDArray[np.float64]
    noise: NDArray[np.float64] | None
    nominal: NominalConversion

    @property
    def rms_before(self) -> float:
        return rms(self.before)

    @property
    def rms_after(self) -> float:
        return rms(self.after)

    @property
    def rms_noise(self) -> float:
        """rms of ``after`` expected from the pose noise alone (NaN without σ_k)."""
        return rms(self.noise) if self.noise is not None else float("nan")

    def summary(self) -> dict[str, Any]:
        """JSON-safe dictionary, figures in g."""
        poses = []
        for k in range(self.rows.size):
            d: dict[str, Any] = {"row": int(self.rows[k]), "before_g": self.before[k], "after_g": self.after[k]}
            if self.t is not None:
                d["t"] = self.t[k]
            if self.n_samples is not None:
                d["n_samples"] = self.n_samples[k]
            if self.noise is not None:
                d["noise_g"] = self.noise[k]
            poses.append(d)
        return jsonable(
            {
                "n_poses": int(self.rows.size),
                "rms_before_g": self.rms_before,
                "rms_after_g": self.rms_after,
                "max_abs_before_g": float(np.max(np.abs(self.before))) if self.before.size else None,
                "max_abs_after_g": float(np.max(np.abs(self.after))) if self.after.size else None,
                "rms_noise_g": self.rms_noise,
                "nominal": self.nominal.description,
                "poses": poses,
            }
        )


def convert_to_units(poses: PoseTable, units: str) -> PoseTable:
    """The same poses in ``units`` (g ↔ m/s² only; counts have no fixed scale)."""
    if poses.units == units:
        return poses
    if poses.units in G_TO_MS2 and units in G_TO_MS2:
        factor = G_TO_MS2[units] / G_TO_MS2[poses.units]
        out = poses.with_acc(poses.acc * factor)
        out.units = units
        if out.sigma is not None:
            out.sigma = out.sigma * factor
        return out
    raise InputError(
        f"the calibration is for data in {units} but DATA is in {poses.units}; "
        f"give DATA in {units} (or pass --units {units} if that is what it is)"
    )


def check_calibration(
    cal: Calibration | CalibrationResult, poses: PoseTable, nominal: NominalConversion | None = None
) -> NormCheck:
    """Evaluate a calibration on poses: norm errors before and after, per pose.

    Parameters
    ----------
    cal : Calibration or CalibrationResult
        Any ``cal_type`` (:mod:`optcal.families.caltypes`); an extended calibration uses the poses'
        temperature and time.
    poses : PoseTable
        In the calibration's units (g and m/s² are converted).
    nominal : NominalConversion, optional
        The "before" baseline (default: :func:`optcal.data.units.nominal_conversion`).
    """
    if isinstance(cal, CalibrationResult):
        cal = cal.calibration
    poses = convert_to_units(poses, cal.units)
    nominal = nominal or nominal_conversion(poses.units, poses.acc)
    before = np.linalg.norm(nominal.apply(poses.acc), axis=1) - 1.0
    after = cal.norm_errors(poses.acc, poses.temp, poses.t)
    lumped = cal.lumped()  # the noise gain of the linear part (first order)
    noise = norm_noise(lumped.T, lumped.o, poses.acc, poses.sigma) if poses.sigma is not None else None
    return NormCheck(poses.rows.copy(), poses.t, poses.n_samples, before, after, noise, nominal)


# ----------------------------------------------------------------------------- held-out
@dataclass
class HeldOutResult:
    """Held-out validation: each test pose judged by a calibration that did not see it.

    Attributes
    ----------
    residuals : ndarray
        Held-out ``‖ā_k‖ − 1`` per pose (NaN for poses never tested).
    in_sample : ndarray
        In-sample residuals of the calibration on all poses.
    folds : list of dict
        Per fold: training and test pose counts, rms of the test residuals.
    """

    residuals: NDArray[np.float64]
    in_sample: NDArray[np.float64]
    folds: list[dict[str, Any]] = field(default_factory=list)

    @property
    def rms_held_out(self) -> float:
        r = self.residuals[np.isfinite(self.residuals)]
        return rms(r)

    @property
    def rms_in_sample(self) -> float:
        return rms(self.in_sample)


def kfold_masks(n: int, folds: int, rng: np.random.Generator | int | None = 0) -> list[NDArray[np.bool_]]:
    """Test masks of a random ``folds``-fold partition of ``n`` poses."""
    if folds < 2 or folds > n:
        raise InputError(f"folds must lie between 2 and the number of poses ({n}), got {folds}")
    order = np.random.default_rng(rng).permutation(n)
    masks = []
    for part in np.array_split(order, folds):
        m = np.zeros(n, dtype=bool)
        m[part] = True
        masks.append(m)
    return masks


def held_out_validation(
    poses: PoseTable,
    test_masks: list[NDArray[np.bool_]] | None = None,
    folds: int = 5,
    method: str = "default",
    rng: np.random.Generator | int | None = 0,
    full: CalibrationResult | None = None,
    **settings: Any,
) -> HeldOutResult:
    """Calibrate on the training poses, evaluate the norm error on the test poses.

    Parameters
    ----------
    poses : PoseTable
    test_masks : list of bool arrays, optional
        One mask of test poses per fold (default: random ``folds``-fold partition).
    folds : int
    method : str
        Estimator (:func:`optcal.families.accel.calibration.calibrate`).
    rng : Generator or int, optional
        For the fold partition.
    full : CalibrationResult, optional
        The estimator's fit on all of ``poses`` with these settings, when the caller has it (not fitted again).
    **settings
        Passed to the estimator.
    """
    from optcal.families.accel.calibration import calibrate

    masks = test_masks if test_masks is not None else kfold_masks(poses.n, folds, rng)
    residuals = np.full(poses.n, np.nan)
    records = []
    for m in masks:
        train = np.flatnonzero(~m)
        if train.size < MIN_POSES:
            raise InputError(f"a fold leaves only {train.size} training poses; at least {MIN_POSES} are needed")
        cal = calibrate(poses.subset(train), method=method, **settings)
        test = np.flatnonzero(m)
        r = norm_residuals(cal.T, cal.o, poses.acc[test])
        residuals[test] = r
        records.append({"n_train": int(train.size), "n_test": int(test.size), "rms_test_g": rms(r),
                        "rms_train_g": cal.rms_norm_residual_g})
    if full is None:
        full = calibrate(poses, method=method, **settings)
    return HeldOutResult(residuals, norm_residuals(full.T, full.o, poses.acc), records)


# ----------------------------------------------------------------------------- Lu 2017 eq. 31
@dataclass
class DisplacementResult:
    """Displacement integrated from a static log (Lu 2017, eq. 31).

    Attributes
    ----------
    t : ndarray
        Time from the start, seconds.
    displacement : ndarray, shape (n, 3)
        ``∫₀ᵗ ∫₀^τ (R_bⁿ a + g) dτ' dτ`` in metres, navigation frame (z up).
    R : ndarray, shape (3, 3)
        The attitude ``R_bⁿ`` used (levelling from the accelerometer itself).
    """

    t: NDArray[np.float64]
    displacement: NDArray[np.float64]
    R: NDArray[np.float64]

    @property
    def final(self) -> NDArray[np.float64]:
        """``ε`` at the end of the log, metres, per navigation axis."""
        return self.displacement[-1]


def levelling_rotation(f: ArrayLike) -> NDArray[np.float64]:
    """Rotation ``R`` (body to navigation, z up) taking the direction of ``f`` to +z (yaw zero)."""
    return rotation_between(np.asarray(f, float) / np.linalg.norm(f), np.array([0.0, 0.0, 1.0]))


def displacement_integration(
    acc_g: ArrayLike,
    t: ArrayLike,
    align_s: float | None = None,
    gravity: float = STANDARD_GRAVITY,
) -> DisplacementResult:
    """Double integral of the specific force of a static log minus gravity (Lu 2017, eq. 31).

    ``ε(T) = ∫₀ᵀ ∫₀ᵗ (R_bⁿ a + g) dτ dt`` with ``a`` in m/s² (``acc_g`` times ``gravity``),
    ``g = (0, 0, −gravity)`` and ``R_bⁿ`` the attitude.  Without an external attitude,
    ``R_bⁿ`` is found by levelling: it turns the mean specific force of the first
    ``align_s`` seconds (the whole log when ``None``) to the vertical.  With levelling over
    the whole log the horizontal means vanish by construction, so the vertical channel
    carries the calibration error, ``ε_z ≈ ½ (‖ā‖ − 1) g T²``, and the horizontal channels
    the noise and drift that no calibration removes.

    Parameters
    ----------
    acc_g : array_like, shape (n, 3)
        Specific force in g (raw data by the nominal conversion, or calibrated).
    t : array_like, shape (n,)
        Seconds.
    align_s : float, optional
        Levelling window from the start, seconds.
    gravity : float
        m/s² per g (the paper takes 9.81).
    """
    a = np.asarray(acc_g, float).reshape(-1, 3) * gravity
    t = np.asarray(t, float).reshape(-1)
    if a.shape[0] != t.size or t.size < 2:
        raise InputError("displacement integration needs at least two samples with times")
    window = slice(None) if align_s is None else slice(0, max(2, int(np.searchsorted(t, t[0] + align_s))))
    R = levelling_rotation(a[window].mean(axis=0))
    an = a @ R.T + np.array([0.0, 0.0, -gravity])
    tt = t - t[0]
    dt = np.diff(tt)[:, None]
    v = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (an[1:] + an[:-1]) * dt, axis=0)])
    p = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (v[1:] + v[:-1]) * dt, axis=0)])
    return DisplacementResult(tt, p, R)
