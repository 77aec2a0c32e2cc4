"""The angle between the field and gravity (dip) and the rotation between the two sensors' frames.

Where the sensor is still, the accelerometer reads the upward specific force ``â`` and the
calibrated magnetometer the field direction ``m̂``; the field dips by the inclination ``δ``
below the horizontal, so ``â · m̂ = −sin δ`` at every orientation (Kok & Schön 2016, sec. 3;
Vasconcelos 2011, eq. 24).  The ellipsoid fit determines the magnetometer's ``T`` only up to
a rotation, and the two sensors are mounted with a small misalignment: the rotation ``R`` of
the magnetometer's calibrated frame into the accelerometer's is estimated jointly with δ
from ``â_k · R m̂_k + sin δ = 0`` by Gauss–Newton (Papafotis 2019, eq. 20; Kok & Schön 2016,
eq. 17 with the dip constraint), with standard errors by batch means of correlated samples
(:func:`optcal.families.mag.fit.batch_means_stderr`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.core.rotations import exponential_map
from optcal.data.rest_tests import unit_rows

#: A sample is still when ``|a|`` is within this share of the session's median ``|a|`` (its
#: gravity): a linear acceleration of 2 % of g tilts the measured vertical by at most 1.1°, the
#: size of the dip spread a consumer magnetometer's noise gives.
STILL_SHARE: float = 0.02
#: Fewer still samples than this leave the dip unestimated (the rotation and δ are 4 unknowns,
#: and the inflation for correlated samples needs a sequence to measure its correlation).
MIN_STILL: int = 20
#: The dip is estimated on at most this many still samples, evenly spaced in time: the standard
#: error of 10⁵ correlated samples (inflated for their correlation) is already far below the
#: spread a magnetometer's noise gives, and the fit of 4 unknowns costs linear time per step.
MAX_DIP_SAMPLES: int = 100_000


#: "Near rest" with a gyroscope: a turn bends gravity's estimate in two ways the ``|a|`` test cannot see (an
#: acceleration across gravity changes ``|a|`` only in second order: 7 % of g across it tilts the vertical 4° and
#: changes ``|a|`` by 0.25 %). The centripetal acceleration ``ω² r`` of a sensor ``r`` from the turn's axis tilts it
#: by ``ω² r / g`` rad, and a lag ``τ`` between the accelerometer's and the magnetometer's samples (a filter's group
#: delay, the two sensors' sampling instants) by ``ω τ`` rad. A sample is near rest when the two together stay
#: within this angle: half of a consumer magnetometer's per-sample dip noise (about 1°: ckexplorer's white σ 1.15°),
#: so the turn adds at most 12 % to the dip's noise in quadrature.
GRAVITY_ANGLE_DEG: float = 0.5
#: The lever arm ``r`` the bound allows for: a sensor held in the hand or on a tag turned at arm's length, 0.3 m
#: from the turn's axis (a sensor on the axis only loosens the bound's centripetal part).
TURN_LEVER_M: float = 0.3
#: The lag ``τ`` when the file has no time column: the period of the slowest common magnetometer output rate
#: (50 Hz, QMC5883L); with a time column, the median sample period.
DEFAULT_LAG_S: float = 0.02
#: Standard gravity, m/s² (the centripetal tilt's denominator).
G0: float = 9.80665


def turning_rate_bound(lag_s: float | None) -> float:
    """The rate (rad/s) below which a turn bends gravity's direction by at most :data:`GRAVITY_ANGLE_DEG`.

    The positive root of ``ω τ + ω² r / g = ε`` (:data:`TURN_LEVER_M`, ``τ`` the lag: ``lag_s`` or
    :data:`DEFAULT_LAG_S`).

    Parameters
    ----------
    lag_s : float or None
        The accelerometer's lag behind the magnetometer, seconds (the sample period).

    Returns
    -------
    float
    """
    tau = DEFAULT_LAG_S if lag_s is None or not np.isfinite(lag_s) or lag_s <= 0 else float(lag_s)
    k, eps = TURN_LEVER_M / G0, np.radians(GRAVITY_ANGLE_DEG)
    return float((-tau + np.sqrt(tau * tau + 4.0 * k * eps)) / (2.0 * k))


@dataclass(frozen=True)
class RestGate:
    """Which samples are near rest for the dip: ``|a|`` near g and, with a gyroscope, the rate below a bound.

    Attributes
    ----------
    still : ndarray of bool, shape (n,)
        Near rest.
    rate_bound : float or None
        The rate bound, rad/s (:func:`turning_rate_bound`); ``None`` without a usable gyroscope.
    n_turning : int
        Samples with ``|a|`` near g left out for the rate.
    reason : str
        How the gate was decided (printed).
    """

    still: NDArray[np.bool_]
    rate_bound: float | None
    n_turning: int
    reason: str


def rest_gate(acc: NDArray[np.float64], gyro: NDArray[np.float64] | None = None,
              t: NDArray[np.float64] | None = None, gyro_units: str | None = None) -> RestGate:
    """The dip's near-rest samples (:func:`still_mask`, then the gyroscope's rate below :func:`turning_rate_bound`).

    Parameters
    ----------
    acc : ndarray, shape (n, 3)
    gyro : ndarray, shape (n, 3), optional
        Raw gyroscope samples; their units decided by :func:`optcal.data.units.decide_gyro_units` (counts: no
        rate gate, said in the reason).
    t : ndarray, shape (n,), optional
        Time, seconds (the lag: the median period).
    gyro_units : str, optional
        The user's gyro units (``--gyro-units``).

    Returns
    -------
    RestGate
    """
    from optcal.data.units import decide_gyro_units

    still = still_mask(acc)
    base = f"|a| within {100 * STILL_SHARE:g} % of its median"
    if gyro is None or gyro.shape != acc.shape or not np.all(np.isfinite(gyro[still])) or not still.any():
        return RestGate(still, None, 0, base + " (no gyroscope)")
    bias = np.median(gyro[still], axis=0)
    units = decide_gyro_units(gyro[np.all(np.isfinite(gyro), axis=1)], bias, gyro_units)
    if units.rad_per_unit is None:
        return RestGate(still, None, 0, base + f" (the gyroscope in {units.units}: its rate not used; "
                        "give --gyro-units)")
    lag = float(np.median(np.diff(t))) if t is not None and t.size == len(acc) and t.size > 1 else None
    bound = turning_rate_bound(lag)
    rate = np.linalg.norm(np.nan_to_num(gyro - bias, nan=np.inf), axis=1) * units.rad_per_unit
    slow = rate <= bound
    n_turning = int(np.count_nonzero(still & ~slow))
    lag_text = f"the sample period {lag:.3g} s" if lag is not None else f"{DEFAULT_LAG_S:g} s assumed (no time column)"
    return RestGate(still & slow, bound, n_turning,
                    f"{base} and the gyroscope's rate ≤ {bound:.3g} rad/s (gravity's direction within "
                    f"{GRAVITY_ANGLE_DEG:g}° for a lever arm of {TURN_LEVER_M:g} m and a lag of {lag_text}; gyro in "
                    f"{units.units}, {units.reason}): {n_turning} turning samples left out")


@dataclass(frozen=True)
class DipResult:
    """The dip over the still samples, before and after the two frames are aligned.

    Attributes
    ----------
    dip_deg, dip_se_deg : float
        The inclination (positive: the field points below the horizontal) and its standard error.
    dip_std_deg : float
        The spread (standard deviation) of the per-sample dip with the frames aligned.
    dip_std_unaligned_deg : float
        The same with ``R = I`` (the independent ML fit's frame).
    R : ndarray, shape (3, 3)
        Rotation of the calibrated magnetometer's frame into the accelerometer's.
    rotation_deg, rotation_se_deg : float
        Its angle and the standard error of that angle.
    n_still, n_samples : int
        Samples used (still) and offered.
    near_rest : str
        How near rest was decided (:func:`rest_gate`).
    """

    dip_deg: float
    dip_se_deg: float
    dip_std_deg: float
    dip_std_unaligned_deg: float
    R: NDArray[np.float64]
    rotation_deg: float
    rotation_se_deg: float
    n_still: int
    n_samples: int
    near_rest: str = ""

    def lines(self) -> list[str]:
        """The report's lines."""
        return [
            f"dip (inclination): {self.dip_deg:.2f} ± {self.dip_se_deg:.2f} deg over {self.n_still} still samples of "
            f"{self.n_samples} ({self.near_rest or f'|a| within {100 * STILL_SHARE:g} % of its median'})",
            f"dip spread: {self.dip_std_deg:.3f} deg with the frames aligned, {self.dip_std_unaligned_deg:.3f} deg without",
            f"magnetometer-to-accelerometer rotation: {self.rotation_deg:.2f} ± {self.rotation_se_deg:.2f} deg",
        ]


def still_mask(acc: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Samples whose ``|a|`` is within :data:`STILL_SHARE` of the median ``|a|`` (finite rows only)."""
    norm = np.linalg.norm(acc, axis=1)
    ok = np.isfinite(norm)
    g = float(np.median(norm[ok])) if ok.any() else np.nan
    return ok & (np.abs(norm - g) <= STILL_SHARE * g)


def per_sample_dip(acc_unit: NDArray, field_unit: NDArray) -> NDArray[np.float64]:
    """``δ_k = asin(−â_k · m̂_k)`` in degrees (module docstring)."""
    return np.degrees(np.arcsin(np.clip(-np.sum(acc_unit * field_unit, axis=1), -1.0, 1.0)))


def fit_dip(a: NDArray[np.float64], m: NDArray[np.float64], max_iter: int = 50,
            R0: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """``R`` and ``sin δ`` of ``â_k · R m̂_k + sin δ = 0`` by Gauss–Newton (module docstring), with the residuals.

    Parameters
    ----------
    a, m : ndarray, shape (n, 3)
        Unit vectors: the still accelerometer's direction and the calibrated field's.
    max_iter : int
    R0 : ndarray, shape (3, 3), optional
        The rotation to start from (the identity by default).

    Returns
    -------
    R : ndarray, shape (3, 3)
    s : float
        ``sin δ``.
    residuals : ndarray, shape (n,)
        ``â_k · R m̂_k + sin δ``.
    """
    R = np.eye(3) if R0 is None else np.array(R0, dtype=float)
    s = float(np.sin(np.radians(np.mean(per_sample_dip(a, m @ R.T)))))
    for _ in range(max_iter):  # Gauss-Newton on r_k = â_k·R m̂_k + sin δ, R perturbed on the left: exp([φ]×) R
        v = m @ R.T
        r = np.sum(a * v, axis=1) + s
        J = np.column_stack([np.cross(v, a), np.ones(len(a))])
        step = np.linalg.solve(J.T @ J, -(J.T @ r))  # normal equations: 4×4, linear in the samples
        R = exponential_map(step[:3]) @ R
        s = float(np.clip(s + step[3], -1.0, 1.0))
        if np.linalg.norm(step) < 1e-10:  # radians: far below any standard error of the angles
            break
    return R, s, np.sum(a * (m @ R.T), axis=1) + s


def estimate_dip(acc: NDArray[np.float64], calibrated: NDArray[np.float64], max_iter: int = 50,
                 gyro: NDArray[np.float64] | None = None, t: NDArray[np.float64] | None = None,
                 gyro_units: str | None = None) -> DipResult | None:
    """The dip and the frames' rotation (module docstring); ``None`` with fewer than :data:`MIN_STILL` still samples.

    Parameters
    ----------
    acc : ndarray, shape (n, 3)
        Accelerometer samples (any units: only the direction is used).
    calibrated : ndarray, shape (n, 3)
        The calibrated magnetometer samples ``T(m − o)``.
    max_iter : int
        Most Gauss–Newton steps.
    gyro, t, gyro_units
        The gyroscope's samples, the time and the user's gyro units, for near rest (:func:`rest_gate`).
    """
    from optcal.families.mag.fit import batch_means_stderr

    gate = rest_gate(acc, gyro, t, gyro_units)
    still = gate.still & np.all(np.isfinite(calibrated), axis=1)
    if np.count_nonzero(still) < MIN_STILL:
        return None
    index = np.flatnonzero(still)
    index = index[:: max(1, len(index) // MAX_DIP_SAMPLES)]
    a = unit_rows(acc[index])
    m = unit_rows(calibrated[index])
    unaligned = per_sample_dip(a, m)
    R, s, r = fit_dip(a, m, max_iter)
    v = m @ R.T
    J = np.column_stack([np.cross(v, a), np.ones(len(a))])
    se = batch_means_stderr(J, r)  # correlated samples: batch means (the rotation's three angles, then sin δ)
    aligned = per_sample_dip(a, v)
    dip = float(np.degrees(np.arcsin(s)))
    dip_se = float(np.degrees(se[3] / max(np.sqrt(1 - s * s), 1e-12)))
    angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))
    rot_se = float(np.degrees(np.sqrt(float(np.sum(se[:3] ** 2)))))
    return DipResult(dip, dip_se, float(np.std(aligned)), float(np.std(unaligned)), R, angle, rot_se,
                     int(np.count_nonzero(still)), int(len(acc)), gate.reason)
