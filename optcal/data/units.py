"""The units of a data set, decided from the evidence: the accelerometer's and the gyro's.

The unit names and their spellings are :mod:`optcal.core.units`; this module decides which
units a data set is in, and says why.

Accelerometer (raw counts, g or m/s²): optcal calibrates in the raw units of the data (``T``
in g per raw unit, ``o`` in raw units) and always outputs g.  The units are the user's
``--units``, a unit word in the column names, the file format, or, when none of these says,
the typical norm of the data (:func:`decide_units`), checked against that norm
(:func:`check_units`) and against the pose means (:func:`check_sensitivity`); the *nominal*
conversion to g (:func:`nominal_conversion`) serves as the "before calibration" baseline.

Gyro (raw counts, rad/s or °/s): the calibration ``T_g`` absorbs the units (rad/s per raw
unit), so the units decide only the nominal conversion: the "before calibration" baseline
and the starting point of the fit.  The decision (:func:`decide_gyro_units`) follows the
accelerometer's: the user's ``gyro_units`` wins, then a unit word in the file's column names
or the file format (ROS ``sensor_msgs/Imu`` and PX4 ULog state rad/s), then the data:
integer-valued samples are counts; otherwise the fastest rates reached in the moves (99th
percentile of ``|g − b|``) tell rad/s (a hand-turned sensor peaks at 1-20 rad/s) from °/s
(60-1200 °/s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.model import STANDARD_GRAVITY
from optcal.core.units import RAD_PER_UNIT, normalise_units, to_g_factor
from optcal.data.quantiles import column_medians, median, np_quantile
from optcal.errors import InputError

#: Norm ranges (median ‖a‖ over the data) in which the units are unambiguous.
G_NORM_RANGE: tuple[float, float] = (0.5, 2.0)
MS2_NORM_RANGE: tuple[float, float] = (5.0, 20.0)
COUNTS_MIN_NORM: float = 50.0


@dataclass(frozen=True)
class UnitsDecision:
    """The units of a data set and how they were decided.

    Attributes
    ----------
    units : str
        ``"g"``, ``"m/s^2"`` or ``"counts"``.
    reason : str
        Where the decision came from (reported by ``optcal segment`` and in ``PoseTable.meta``).
    """

    units: str
    reason: str


def median_norm(acc: ArrayLike) -> float:
    """Median of ‖a‖ over the finite rows of ``acc`` (NaN when there is none)."""
    a = np.asarray(acc, dtype=float).reshape(-1, 3)
    a = a[np.all(np.isfinite(a), axis=1)]
    with np.errstate(over="ignore", invalid="ignore"):  # values near the float limit: an infinite norm
        return median(np.linalg.norm(a, axis=1)) if a.size else float("nan")


def decide_units(
    acc: ArrayLike | None,
    requested: str | None = None,
    hint: str | None = None,
    hint_reason: str = "",
    norm: float | None = None,
) -> UnitsDecision:
    """Decide the units of ``acc``.

    Parameters
    ----------
    acc : array_like, shape (n, 3), or None
        Measurements (raw samples or pose means); not read when ``norm`` is given.
    requested : str, optional
        The user's ``--units``; always wins.
    hint : str, optional
        Units stated by the file (a unit word in the column names, a ``units`` attribute, or the
        file format, e.g. ``m/s^2`` for ROS ``sensor_msgs/Imu``): evidence, checked against the
        norm.  When the norm contradicts it and tells the units on its own (a netCDF attribute
        ``m/s2`` on data whose median |a| is 0.996), the data are trusted and the reason says
        so; when the norm contradicts it without telling, the file is refused naming ``--units``.
    hint_reason : str
        Where ``hint`` came from, for the report.
    norm : float, optional
        The median ‖a‖ of ``acc`` when already known (saves a pass over the data).

    Raises
    ------
    InputError
        When nothing states the units and the norm is ambiguous, or when ``requested`` (or a
        ``hint`` that the norm does not replace) contradicts the norm.
    """
    if norm is None:
        if acc is None:
            raise InputError("decide_units needs the samples (acc) or their median norm (norm)")
        norm = median_norm(acc)
    if requested is not None:
        return check_units(UnitsDecision(normalise_units(requested), "given with --units"), norm)
    if hint is not None:
        stated = UnitsDecision(normalise_units(hint), hint_reason or "stated by the file")
        try:
            return check_units(stated, norm)
        except InputError:  # what the file states is evidence: the data, when they tell, outweigh it
            by_data = units_from_norm(norm)
            if by_data is None:
                raise
            return UnitsDecision(by_data.units, f"{by_data.reason}; the file states {stated.units} ({stated.reason}), "
                                                "which the data contradict: the data are trusted")
    if not np.isfinite(norm):
        raise InputError("no finite acceleration values; cannot tell the units")
    found = units_from_norm(norm)
    if found is not None:
        return found
    raise InputError(
        f"cannot tell the units from the data (median |a| = {norm:.4g} is neither ≈ 1 g, "
        f"≈ 9.8 m/s^2 nor a raw count scale); pass --units g, m/s^2 or counts"
    )


def units_from_norm(norm: float) -> UnitsDecision | None:
    """The units the median ‖a‖ alone tells (g, m/s² or counts), or ``None`` when it does not."""
    if G_NORM_RANGE[0] <= norm <= G_NORM_RANGE[1]:
        return UnitsDecision("g", f"median |a| = {norm:.4g} ≈ 1 (g)")
    if MS2_NORM_RANGE[0] <= norm <= MS2_NORM_RANGE[1]:
        return UnitsDecision("m/s^2", f"median |a| = {norm:.4g} ≈ 9.8 (m/s^2)")
    if norm >= COUNTS_MIN_NORM:
        return UnitsDecision("counts", f"median |a| = {norm:.4g} ≫ 9.8 (raw counts)")
    return None


#: Median norms that each unit allows (a wide margin for calibration errors and motion).
PLAUSIBLE_NORM: dict[str, tuple[float, float]] = {
    "g": G_NORM_RANGE,
    "m/s^2": MS2_NORM_RANGE,
    "counts": (MS2_NORM_RANGE[1], float("inf")),
}


def check_units(decision: UnitsDecision, norm: float) -> UnitsDecision:
    """Refuse a declared or stated unit that the measured norm contradicts, with both numbers.

    A calibration corrects the scale by a few percent; data whose median ‖a‖ lies outside
    :data:`PLAUSIBLE_NORM` of the declared unit are in another unit.
    """
    if not np.isfinite(norm):
        return decision
    lo, hi = PLAUSIBLE_NORM[decision.units]
    if lo <= norm <= hi:
        return decision
    likely = next((u for u, (a, b) in PLAUSIBLE_NORM.items() if a <= norm <= b), None)
    expect = {"g": "≈ 1", "m/s^2": "≈ 9.8", "counts": f"> {MS2_NORM_RANGE[1]:g}"}[decision.units]
    hint = f"; the data look like {likely}: pass --units {likely}" if likely else "; pass the right --units"
    raise InputError(
        f"units {decision.units} ({decision.reason}) contradict the data: the median |a| is {norm:.4g}, "
        f"while data at rest in {decision.units} have |a| {expect} ({lo:g}–{hi:g}){hint}"
    )


#: Smallest plausible ratio of the implied sensitivity (the radius of the sphere through the
#: pose means, raw units per g) to the median |a|: an accelerometer's poses lie on a sphere
#: around its zero (a 16-bit unsigned converter at ±16 g: 2048/57000 ≈ 0.036); a resting
#: gyroscope's outputs mapped as an accelerometer cluster within a few hundred counts of
#: each other (the Xsens MTi's gyro: radius ≈ 150 counts next to |a| ≈ 57000, 0.0026).
MIN_SENSITIVITY_TO_NORM: float = 0.01
#: Poses needed before the sensitivity is checked (a calibration needs 9).
MIN_POSES_FOR_SCALE_CHECK: int = 9
#: Largest per-sample noise of a resting accelerometer, in g of the nominal conversion: tens of
#: mg at most (phone-grade sensors ≈ 15 mg; the recordings in ../shared/data 0.9-7.7 mg).  A
#: resting gyroscope's outputs mapped as an accelerometer have the noise of the gyro next to an
#: "implied 1 g" that is only its bias (the Xsens MTi's gyro in unsigned counts: ≈ 0.3).
MAX_REST_NOISE_G: float = 0.05
#: Pose means of a sensor turned between its poses spread by a good part of their |a| (an accelerometer's
#: by up to 2 g: 0.035 for a 2° turn); pose means that stay within this fraction of their median |a| are
#: one constant offset, as a gyroscope's at rest reads in every orientation (or a sensor never turned).
MIN_SPREAD_TO_NORM: float = 0.035
#: Pose means in g or m/s² whose median |a| lies within this fraction of 1 g are an accelerometer's at rest,
#: turned or not (the spread rule then does not apply).
ONE_G_TOLERANCE: float = 0.2


def sphere_through(points: ArrayLike) -> tuple[NDArray[np.float64], float]:
    """Centre and radius of the least-squares sphere through points (pose means, or rest readings).

    The algebraic sphere fit ``‖a‖² = 2 a·c + (r² − ‖c‖²)`` (linear in ``c`` and the
    constant), solved on points centred and scaled by their spread so that a tight cluster
    far from zero is as well conditioned as a sphere around it.  The radius is NaN when the
    points do not determine a sphere (fewer than four, or all in one plane), 0 when they are
    all one point.
    """
    a = np.asarray(points, dtype=float).reshape(-1, 3)
    a = a[np.all(np.isfinite(a), axis=1)]
    nowhere = np.full(3, np.nan)
    if a.shape[0] < 4:
        return nowhere, float("nan")
    centre0 = a.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum((a - centre0) ** 2, axis=1))))
    if not scale > 0:
        return centre0, 0.0
    u = (a - centre0) / scale
    design = np.column_stack([2.0 * u, np.ones(len(u))])
    sol, _, rank, _ = np.linalg.lstsq(design, np.sum(u * u, axis=1), rcond=None)
    if rank < 4:
        return nowhere, float("nan")
    r2 = float(sol[3] + sol[:3] @ sol[:3])
    if not r2 > 0:
        return nowhere, float("nan")
    return centre0 + scale * sol[:3], float(np.sqrt(r2)) * scale


def implied_sensitivity(means: ArrayLike) -> float:
    """Radius of the least-squares sphere through pose means (:func:`sphere_through`): the raw units of 1 g they imply.

    NaN when the means do not determine a sphere.
    """
    return sphere_through(means)[1]


def check_sensitivity(means: ArrayLike, units: str, noise: ArrayLike | None = None, *, stated: bool = False) -> None:
    """Refuse pose means that are not an accelerometer's (gyroscope columns mapped as ``ax, ay, az``).

    Two pieces of evidence, each with the fix in the message:

    * from :data:`MIN_POSES_FOR_SCALE_CHECK` poses on, the implied sensitivity: an
      accelerometer's pose means lie on a sphere of radius 1 g (in its units) around its zero;
      a radius that is a tiny fraction of the measured |a| means the columns are not an
      accelerometer's, or the sensor was never turned;
    * from two poses on, their spread: an accelerometer turned between its poses moves their
      means by a good part of 1 g, while a gyroscope at rest reads its constant offset in every
      orientation; means within :data:`MIN_SPREAD_TO_NORM` of their median |a| are refused,
      unless they are in g or m/s² and their |a| is 1 g (an accelerometer that was not turned), or
      ``stated`` (an acceleration unit given with ``--units`` or written in the file: the columns are
      then declared an accelerometer's, and poses of one orientation cannot tell its offset, even
      0.2 g, from a wrong unit). This holds however small the gyroscope's noise is next to its offset;
    * with any number of poses, when ``noise`` (each pose's per-sample standard deviation,
      pooled over the axes, raw units) is given: a resting accelerometer's noise is at most
      :data:`MAX_REST_NOISE_G` of 1 g by the nominal conversion; a gyroscope's noise next to
      its bias (the "1 g" its outputs imply) is far more.

    Raises
    ------
    InputError
        With the measured figures, and the fix.
    """
    a = np.asarray(means, dtype=float).reshape(-1, 3)
    fix = ("if these are gyroscope columns, map the accelerometer's with columns= (ax=NAME,ay=NAME,az=NAME), "
           "otherwise turn the sensor through several orientations")
    if a.shape[0] >= MIN_POSES_FOR_SCALE_CHECK:
        norm = median_norm(a)
        radius = implied_sensitivity(a)
        if np.isfinite(norm) and norm > 0 and not np.isnan(radius) and radius < MIN_SENSITIVITY_TO_NORM * norm:
            factor = to_g_factor(units)
            if factor is not None and abs(norm * factor - 1.0) <= ONE_G_TOLERANCE:
                # |a| of 1 g in g or m/s²: what an accelerometer never turned reads (ssong47's yaw trial: 187 rests
                # of one tilt), which the lead below would call no accelerometer's; a gyroscope's offset of 1 in
                # these units is the other reading, and the fix names both
                raise InputError(
                    f"the {a.shape[0]} pose means are of one orientation: they lie within a sphere of radius "
                    f"{radius:.4g} {units} around their centre (the implied 1 g) while their median |a| is {norm:.4g} "
                    f"{units}{'' if units == 'g' else ' (1 g)'}, as an accelerometer never turned reads; turn the sensor through several "
                    f"orientations (if these are gyroscope columns, map the accelerometer's with columns= "
                    f"(ax=NAME,ay=NAME,az=NAME))"
                )
            raise InputError(
                f"the {a.shape[0]} pose means do not look like an accelerometer's: they lie within a sphere of radius "
                f"{radius:.4g} {units} around their centre (the implied 1 g), while their median |a| is {norm:.4g} "
                f"{units} (ratio {radius / norm:.2g}, an accelerometer's is at least {MIN_SENSITIVITY_TO_NORM:g}); {fix}"
            )
    if a.shape[0] >= 2:
        norm = median_norm(a)
        spread = float(np.linalg.norm(np.ptp(a[np.all(np.isfinite(a), axis=1)], axis=0)))
        factor = to_g_factor(units)
        one_g_at_rest = factor is not None and abs(norm * factor - 1.0) <= ONE_G_TOLERANCE
        # an acceleration unit stated by the user or the file declares the columns an accelerometer's: the spread
        # rule's question (a gyroscope's constant reading?) is then answered, and one orientation's offset is the
        # calibration's to measure (it refuses a single orientation itself)
        declared = stated and factor is not None
        if np.isfinite(norm) and norm > 0 and spread < MIN_SPREAD_TO_NORM * norm and not (one_g_at_rest or declared):
            declare = ("" if factor is None else
                       f" (from one orientation an accelerometer's offset of {abs(norm * factor - 1.0):.2g} g and a "
                       "wrong unit look the same: --units g or --units m/s^2 states they are an accelerometer's and "
                       "proceeds)")
            raise InputError(
                f"the {a.shape[0]} pose means do not look like an accelerometer's: they stay within {spread:.4g} "
                f"{units} of each other, {spread / norm:.2g} of their median |a| {norm:.4g} {units} (a sensor turned "
                f"between its poses moves them by more than {MIN_SPREAD_TO_NORM:g} of it): one constant offset, as a "
                f"gyroscope at rest reads in every orientation{declare}; {fix}"
            )
    if noise is not None and a.shape[0] >= 1:
        one_g = nominal_conversion(units, a).sensitivity
        typical = median(np.asarray(noise, dtype=float))
        if one_g > 0 and typical > MAX_REST_NOISE_G * one_g:
            raise InputError(
                f"the {a.shape[0]} static pose(s) do not look like an accelerometer's: their per-sample noise "
                f"({typical:.4g} {units}, median over the poses) is {typical / one_g:.3g} of the 1 g their means imply "
                f"({one_g:.4g} {units} by the nominal conversion), while a resting accelerometer's is at most "
                f"{MAX_REST_NOISE_G:g}; {fix}"
            )


@dataclass(frozen=True)
class NominalConversion:
    """The uncalibrated conversion ``a_g = (a − offset) / sensitivity`` used as the baseline.

    Attributes
    ----------
    offset : ndarray, shape (3,)
        Raw units.
    sensitivity : float
        Raw units per g.
    description : str
        How it was chosen (reported next to every "before calibration" figure).
    """

    offset: NDArray[np.float64]
    sensitivity: float
    description: str

    def apply(self, raw: ArrayLike) -> NDArray[np.float64]:
        """Raw samples (..., 3) in g by the nominal conversion."""
        return (np.asarray(raw, dtype=float) - self.offset) / self.sensitivity


#: Mid-scale of unsigned 16-bit converters (e.g. the Xsens MTi raw counts of IMU-TK).
UNSIGNED_16_MIDSCALE: float = 32768.0
#: The largest value of an unsigned 16-bit converter.
UNSIGNED_16_MAX: float = 65535.0
#: Counts whose every axis has its median within this of mid-scale sit around it (a quarter of the
#: converter's range: an accelerometer's 1 g is a few thousand counts of it).
MIDSCALE_SPAN: float = 16384.0


def in_unsigned_16_range(minimum: float, maximum: float) -> bool:
    """Samples that an unsigned 16-bit converter can give: all in 0..65535."""
    return bool(minimum >= 0 and maximum <= UNSIGNED_16_MAX)


def around_midscale(medians: ArrayLike) -> bool:
    """Each axis's median within :data:`MIDSCALE_SPAN` of mid-scale (with :func:`in_unsigned_16_range`:
    unsigned 16-bit counts around their mid-scale zero)."""
    return bool(np.all(np.abs(np.asarray(medians, dtype=float) - UNSIGNED_16_MIDSCALE) < MIDSCALE_SPAN))


def nominal_conversion(
    units: str,
    acc: ArrayLike | None,
    *,
    median_norm: float | None = None,
    extremes: tuple[float, float] | None = None,
    medians: ArrayLike | None = None,
    midscale_norm: float | None = None,
) -> NominalConversion:
    """The "before calibration" conversion to g for data in ``units``.

    ``g`` and ``m/s^2`` use their exact unit factors with no offset.  Counts have no
    stated sensitivity: optcal takes no offset (or mid-scale 32768 for unsigned 16-bit
    data, whose values all lie in 0..65535 around it) and the sensitivity that makes the
    median norm of ``acc`` equal to 1 g, so that the baseline shows bias, scale-factor
    mismatch and non-orthogonality, not an arbitrary overall scale.

    Parameters
    ----------
    units : str
    acc : array_like, shape (n, 3), or None
        Pose means (or samples) used to choose the counts baseline (required for counts only).
    median_norm : float, optional
        The median of ``‖acc‖`` over its finite rows when already computed (the evidence's,
        :func:`optcal.data.evidence.gather_evidence`): used as the sensitivity when no mid-scale
        offset is taken, instead of a second pass over the samples.
    extremes, medians, midscale_norm : optional
        The smallest and largest sample, each axis's median and the median of ``‖acc − 32768‖``
        (NaN when the samples are not all in 0..65535), when the evidence has them
        (:class:`optcal.data.evidence.Evidence`): with ``median_norm`` the conversion then reads no
        sample (``acc`` may be ``None``).
    """
    units = normalise_units(units)
    factor = to_g_factor(units)
    if factor is not None:
        name = "1 g = 1" if units == "g" else f"1 g = {STANDARD_GRAVITY} m/s^2"
        return NominalConversion(np.zeros(3), 1.0 / factor, f"nominal: {name}, no bias")
    if extremes is not None and median_norm is not None:  # the evidence's statistics: no pass over the samples
        if in_unsigned_16_range(*extremes) and medians is not None and around_midscale(medians):
            if midscale_norm is not None and np.isfinite(midscale_norm):
                what = "offset 32768 (unsigned 16-bit mid-scale)"
                return NominalConversion(np.full(3, UNSIGNED_16_MIDSCALE), float(midscale_norm),
                                         _counts_description(what, midscale_norm))
        else:
            return NominalConversion(np.zeros(3), float(median_norm), _counts_description("no offset", median_norm))
    if acc is None:
        raise InputError("the nominal conversion of counts needs the samples (acc)")
    a = np.asarray(acc, dtype=float).reshape(-1, 3)
    finite = np.isfinite(a).all(axis=1)
    if not finite.all():  # no copy of a recording whose samples are all finite
        a = a[finite]
    offset = np.zeros(3)
    what = "no offset"
    if a.size and in_unsigned_16_range(a.min(), a.max()) and around_midscale(column_medians(a)):
        offset = np.full(3, UNSIGNED_16_MIDSCALE)
        what = "offset 32768 (unsigned 16-bit mid-scale)"
    if median_norm is not None and not offset.any():
        sens = float(median_norm)
    else:  # column by column: temporaries of one column, not of three
        sens = median(np.sqrt(sum((a[:, j] - offset[j]) ** 2 for j in range(3))), overwrite_input=True) if a.size else 1.0
    return NominalConversion(offset, sens, _counts_description(what, sens))


def units_and_nominal(
    requested: str | None,
    hint: str | None,
    hint_reason: str,
    *,
    norm: float,
    extremes: tuple[float, float] | None = None,
    medians: ArrayLike | None = None,
    midscale_norm: float | None = None,
) -> tuple[UnitsDecision, NominalConversion]:
    """The units decision (:func:`decide_units`) and its nominal conversion (:func:`nominal_conversion`),
    both from the evidence's statistics (:class:`optcal.data.evidence.Evidence`): no pass over the samples.

    Raises
    ------
    InputError
        As :func:`decide_units`.
    """
    found = decide_units(None, requested, hint, hint_reason, norm=norm)
    nominal = nominal_conversion(found.units, None, median_norm=norm, extremes=extremes, medians=medians,
                                 midscale_norm=midscale_norm)
    return found, nominal


def _counts_description(what: str, sensitivity: float) -> str:
    return f"nominal for counts: {what}, one sensitivity {sensitivity:.6g} counts/g (median norm)"


#: Peak rate (99th percentile of the bias-free rate norm) above which float gyro data are °/s.
DEG_S_MIN_PEAK: float = 40.0
#: A MEMS gyro's white rate noise density, °/s/√Hz: from about 0.003 (ICM-42688-P 0.0028, BMI270 0.007, MPU-6050
#: 0.005) to about 0.05 (L3GD20 0.03, consumer parts' worst); the same sensors in rad/s read 5e-5 to 9e-4.  The
#: number measured on a still log's samples says the unit where the two ranges do not meet: above their geometric
#: gap's middle (9e-4 · 0.003)^½ ≈ 1.6e-3 it is °/s.  (A tactical or fibre-optic gyro, 100 times quieter, is not
#: a MEMS part: its unit must be stated, --gyro-units.)
DEG_S_MIN_NOISE_DENSITY: float = float(np.sqrt(9e-4 * 0.003))


@dataclass(frozen=True)
class GyroUnitsDecision:
    """The gyro units and how they were decided."""

    units: str
    reason: str

    @property
    def rad_per_unit(self) -> float | None:
        """rad/s per raw unit (``None`` for counts, whose scale is what calibration finds)."""
        return RAD_PER_UNIT.get(self.units)


def decide_gyro_units(
    gyro: NDArray, bias: NDArray, requested: str | None = None, hint: str | None = None, rate_hz: float | None = None
) -> GyroUnitsDecision:
    """Decide the units of raw gyro samples (module docstring).

    Parameters
    ----------
    gyro : ndarray, shape (n, 3)
        Raw samples, moves included.
    bias : ndarray, shape (3,)
        Rest reading (mean of the still intervals), raw units.
    requested : str, optional
        The caller's ``gyro_units``; always wins.
    hint : str, optional
        Units stated by the file (column names, file format).
    rate_hz : float, optional
        Given for a still log, which has no moves for the peak-rate rule to measure: float samples are then judged
        by their white noise density (the first differences' spread over √2, in which a bias and its slow drift
        cancel, over √f_s; the median over the axes) against :data:`DEG_S_MIN_NOISE_DENSITY`.
    """
    if requested is not None:
        return GyroUnitsDecision(normalise_units(requested, "gyro"), "given with --gyro-units")
    if hint is not None:
        return GyroUnitsDecision(normalise_units(hint, "gyro"), "stated by the file")
    g = np.asarray(gyro, float)
    g = g[np.all(np.isfinite(g), axis=1)]
    if g.size == 0:
        raise InputError("no finite gyro samples; cannot tell the gyro units")
    if np.all(g == np.round(g)):
        return GyroUnitsDecision("counts", "integer-valued samples (raw counts)")
    if rate_hz is not None:
        density = float(np.median(np.std(np.diff(g, axis=0), axis=0))) / np.sqrt(2.0) / np.sqrt(rate_hz)
        unit = "deg/s" if density > DEG_S_MIN_NOISE_DENSITY else "rad/s"
        return GyroUnitsDecision(unit, f"{unit} from the still log's noise density {density:.2g} per √Hz (a MEMS "
                                       f"gyro's is 0.003-0.05 in °/s, 5e-5-9e-4 in rad/s; {DEG_S_MIN_NOISE_DENSITY:.2g} "
                                       "between): --gyro-units to override")
    peak = np_quantile(np.linalg.norm(g - bias, axis=1), 0.99)
    if peak >= DEG_S_MIN_PEAK:
        return GyroUnitsDecision("deg/s", f"peak rate {peak:.3g} ≥ {DEG_S_MIN_PEAK:g} (°/s)")
    return GyroUnitsDecision("rad/s", f"peak rate {peak:.3g} < {DEG_S_MIN_PEAK:g} (rad/s)")
