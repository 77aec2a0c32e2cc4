"""Units of a magnetometer's samples: every spelling, the factor to microtesla, and the decision from the data.

A magnetometer's file says its units by a word in the column names (``mag_x_uT``), by a
variable's ``units`` attribute, or not at all.  When nothing says, the units are decided from
the magnitude of the samples against the Earth's field, 25–65 µT at the surface (the World
Magnetic Model's total intensity ranges from about 22 µT over South America to 67 µT near
the magnetic poles), and the decision is printed with ``--mag-units`` to override it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.data.units import sphere_through
from optcal.errors import InputError

#: Accepted spellings of the magnetometer's units (lower case, spaces and underscores removed), mapped to the unit.
MAG_UNIT_ALIASES: dict[str, str] = {
    **dict.fromkeys(("ut", "µt", "μt", "microtesla", "utesla", "micro_tesla"), "uT"),
    **dict.fromkeys(("nt", "nanotesla", "ntesla"), "nT"),
    **dict.fromkeys(("t", "tesla"), "T"),
    **dict.fromkeys(("gauss", "gs", "ga", "g"), "gauss"),
    **dict.fromkeys(("mgauss", "milligauss", "mgs", "mga", "mg"), "mgauss"),
    **dict.fromkeys(("counts", "count", "lsb", "raw", "adc"), "counts"),
}
#: The units, in the order messages list them.
MAG_UNITS: tuple[str, ...] = ("uT", "nT", "T", "gauss", "mgauss", "counts")
#: Microtesla per unit for the units with a stated scale (1 gauss = 100 µT).
UT_PER_UNIT: dict[str, float] = {"uT": 1.0, "nT": 1e-3, "T": 1e6, "gauss": 100.0, "mgauss": 0.1}
#: Unit words recognised at the end of a magnetometer column's name (``mag_x_ut``, ``mx_mgauss``);
#: ``g`` and ``mg`` are not among them (an accelerometer's words).
MAG_UNIT_WORDS: tuple[str, ...] = ("microtesla", "milligauss", "nanotesla", "mgauss", "gauss", "ut", "nt", "counts", "lsb", "raw")
#: The Earth's field at the surface, µT (WMM total intensity, rounded outward): a stated unit
#: whose median field falls outside a factor 3 of this range is reported (a unit word or
#: attribute that contradicts the data), and the unit decided from the data when none is stated.
EARTH_FIELD_UT: tuple[float, float] = (25.0, 65.0)
#: How far outside the Earth's range a raw (hard- and soft-iron distorted) field's median magnitude
#: may be and still name a unit.  µT and mgauss are a factor 10 apart, so their widened ranges
#: [25/f, 65 f] and [250/f, 650 f] stay apart only for f < sqrt(250/65) = 1.96: at 1.9 a median
#: names at most one unit, and a hard iron up to about 1.9 times the field (more than most boards
#: show after mounting) still reads in its unit.  Beyond it the samples are read as counts, and
#: the decision says so with --mag-units.
UNIT_TOLERANCE: float = 1.9


def normalise_mag_units(units: str) -> str:
    """Map a spelling (``"µT"``, ``"milligauss"``, ``"LSB"``) to one of :data:`MAG_UNITS`."""
    key = re.sub(r"[\s_]+", "", units.strip().lower())
    if key in MAG_UNIT_ALIASES:
        return MAG_UNIT_ALIASES[key]
    if units in MAG_UNITS:
        return units
    raise InputError(f"unknown magnetometer units {units!r}; use --mag-units with one of {', '.join(MAG_UNITS)}")


@dataclass(frozen=True)
class UnitDecision:
    """The magnetometer's units and why.

    Attributes
    ----------
    units : str
        One of :data:`MAG_UNITS`.
    reason : str
        Where it came from (``--mag-units``, a column's unit word, an attribute, the magnitude).
    median_field : float
        Median ``|m|`` of the samples, in the units.
    """

    units: str
    reason: str
    median_field: float

    def line(self) -> str:
        """One line for the report."""
        return f"magnetometer units: {self.units} ({self.reason}; override with --mag-units)"


def units_from_magnitude(median: float) -> str | None:
    """The unit whose Earth's field range (widened by :data:`UNIT_TOLERANCE`) holds ``median``, else ``None``.

    Tesla is one of them (Android's and MATLAB Mobile's SI export writes 5e-5): its range, 1.3e-5 to 1.2e-4, lies
    10^6 below µT's, and no raw counts (integers) have a median field so small.
    """
    low, high = EARTH_FIELD_UT
    fits = [u for u, k in UT_PER_UNIT.items() if low / UNIT_TOLERANCE <= median * k <= high * UNIT_TOLERANCE]
    return fits[0] if len(fits) == 1 else None


#: Smallest ratio of the samples' least to greatest spread (eigenvalues of their covariance) at which the sphere
#: through them determines the field's magnitude: samples turned about one axis lie near a circle, whose sphere's
#: radius is not determined along its normal.  0.1: every axis spans at least a third of the widest.
SPHERE_MIN_SPREAD: float = 0.1
#: Largest rms of the samples' distances from that sphere, relative to its radius, at which the sphere is the
#: field's (a soft iron of 30 % or a noise of that size: beyond it the radius is no field strength).
SPHERE_MAX_RESIDUAL: float = 0.3


def sphere_radius(m: NDArray[np.float64]) -> float | None:
    """The radius of the sphere through the samples (:func:`optcal.data.units.sphere_through`, the least-squares
    ``|m|² = 2 m·c + d``, ``r² = d + |c|²``): the field's magnitude with the hard iron ``c`` removed; ``None`` where
    the samples do not determine it (their spread, :data:`SPHERE_MIN_SPREAD`) or do not lie on it
    (:data:`SPHERE_MAX_RESIDUAL`)."""
    m = m[np.all(np.isfinite(m), axis=1)]
    if m.shape[0] < 10:
        return None
    spread = np.linalg.eigvalsh(np.cov(m.T))
    if not spread[-1] > 0 or spread[0] / spread[-1] < SPHERE_MIN_SPREAD:
        return None
    centre, radius = sphere_through(m)
    if not radius > 0:  # NaN: no sphere (no positive r²)
        return None
    residual = float(np.sqrt(np.mean((np.linalg.norm(m - centre, axis=1) - radius) ** 2)))
    return radius if residual <= SPHERE_MAX_RESIDUAL * radius else None


def decide_mag_units(m: NDArray[np.float64], stated: str | None, where: str, override: str | None = None) -> UnitDecision:
    """Decide the magnetometer's units (module docstring): ``override``, else ``stated`` (by ``where``), else the magnitude.

    Parameters
    ----------
    m : ndarray, shape (n, 3)
        Raw samples (non-finite rows ignored).
    stated : str or None
        Units the file states.
    where : str
        What stated them (for the reason).
    override : str, optional
        ``--mag-units``.
    """
    norm = np.linalg.norm(m[np.all(np.isfinite(m), axis=1)], axis=1)
    median = float(np.median(norm)) if norm.size else float("nan")
    if override:
        return UnitDecision(normalise_mag_units(override), "given with --mag-units", median)
    if stated is not None:
        units = normalise_mag_units(stated)
        reason = f"stated by {where}"
        guess = units_from_magnitude(median)
        if units != "counts" and guess is not None and guess != units:
            reason += f"; note: the median |m| {median:.4g} is Earth's field in {guess}, not in {units}"
        return UnitDecision(units, reason, median)
    # the field's magnitude is the sphere's radius where the samples determine it: their median |m| holds the hard
    # iron too (a board's magnet, several times the field), which can put it in another unit's range
    radius = sphere_radius(m)
    by_sphere = units_from_magnitude(radius) if radius is not None else None
    if by_sphere is not None and by_sphere != units_from_magnitude(median):
        low, high = EARTH_FIELD_UT
        return UnitDecision(by_sphere, f"from the data: the field's magnitude {radius:.4g} (the radius of the sphere "
                                       f"through the samples; their median |m| {median:.4g} holds the hard iron) is "
                                       f"the Earth's {low:g}-{high:g} µT (within a factor {UNIT_TOLERANCE:g}) only in "
                                       f"{by_sphere}", median)
    guess = units_from_magnitude(median)
    if guess is not None:
        low, high = EARTH_FIELD_UT
        return UnitDecision(guess, f"from the data: median |m| {median:.4g} is the Earth's {low:g}-{high:g} µT "
                                   f"(within a factor {UNIT_TOLERANCE:g}) only in {guess}", median)
    return UnitDecision("counts", f"from the data: median |m| {median:.4g} is not the Earth's field in µT, nT, T, "
                                  f"gauss or mgauss, so the samples are read as counts (the field strength is then in counts)", median)



#: Half the width (as a factor) of the band about the World Magnetic Model's field at the session's place in which
#: the field's magnitude names its unit: √10, half a decade, so that units a decade or more apart (mgauss, µT, gauss)
#: never share it.  A gain error or a site's steel moves the field by far less than a decade; it is judged afterwards
#: by the comparison with the model, in the unit named here.
PLACE_UNIT_BAND: float = float(np.sqrt(10.0))


def units_at_place(decision: UnitDecision, m: NDArray[np.float64], field_ut: float) -> UnitDecision:
    """Check a unit decided from the data against the World Magnetic Model's field at the place (``--location``).

    Without a place the unit is the one in which the samples' magnitude is the Earth's 25-65 µT within a factor
    :data:`UNIT_TOLERANCE` (:func:`decide_mag_units`), a band centred on 40 µT; with one, the field expected there
    is known.  The unit in which the field's magnitude (:func:`sphere_radius`) is nearest the model's field (by
    ratio) replaces the decision where it differs and lies within :data:`PLACE_UNIT_BAND` of it.  A unit given or
    stated, samples that determine no sphere (a planar turn: their median holds the hard iron), and a magnitude
    no unit puts within the band keep the decision (the comparison with the model then says how far it is).

    Parameters
    ----------
    decision : UnitDecision
        The decision from the samples (:func:`decide_mag_units`).
    m : ndarray, shape (n, 3)
        The raw samples.
    field_ut : float
        The model's total intensity at the place and date, µT.
    """
    if not decision.reason.startswith("from the data"):
        return decision
    radius = sphere_radius(m)
    if radius is None or not field_ut > 0:
        return decision
    ratio = {u: abs(float(np.log(radius * k / field_ut))) for u, k in UT_PER_UNIT.items()}
    unit = min(ratio, key=ratio.__getitem__)
    if unit == decision.units or ratio[unit] > np.log(PLACE_UNIT_BAND):
        return decision
    k = UT_PER_UNIT.get(decision.units)
    was = f"; in {decision.units} it would be {radius * k:.4g} µT" if k else ""
    return UnitDecision(unit, f"from the data and the place: the field's magnitude {radius:.4g} (the radius of the "
                              f"sphere through the samples) is {radius * UT_PER_UNIT[unit]:.4g} µT in {unit}, nearest "
                              f"the World Magnetic Model's {field_ut:.4g} µT at --location of the units (within a "
                              f"factor {PLACE_UNIT_BAND:.3g}){was}", decision.median_field)


#: The field in a planar turn's plane, µT, whose magnitude names the unit of a planar recording (the planar fit's
#: ``H``, its hard iron removed).  It is a lower bound on the total field, the dip being unseen: at most the total
#: field (65 µT, :data:`EARTH_FIELD_UT`'s upper end: a plane that holds the field's direction), at least the
#: horizontal field of a level turn, the total times the cosine of the dip, 25-65 µT × cos 85° ≈ 5 µT for a dip up to
#: 85° (everywhere but a few hundred km about the dip poles).  Not widened by :data:`UNIT_TOLERANCE`: the band already
#: spans a factor 13, so µT and mgauss share 50-65 (there the magnitude |m| decides, as without a fit).
PLANE_FIELD_UT: tuple[float, float] = (5.0, 65.0)


def units_from_plane_field(decision: UnitDecision, field: float) -> UnitDecision:
    """The unit of a planar recording decided from the field in its plane (:data:`PLANE_FIELD_UT`).

    A unit given with ``--mag-units`` or stated by the file is kept.  Decided from the data, the unit is the only one
    in which ``field`` (the planar fit's horizontal field ``H``, data units) lies in :data:`PLANE_FIELD_UT`; where no
    unit or two do, the decision from the magnitude is kept and the reason says so.

    Parameters
    ----------
    decision : UnitDecision
        The decision from the samples (:func:`decide_mag_units`).
    field : float
        The planar fit's field in the plane, in the samples' units.
    """
    if not decision.reason.startswith("from the data"):
        return decision
    low, high = PLANE_FIELD_UT
    fits = [u for u, k in UT_PER_UNIT.items() if low <= field * k <= high]
    band = (f"{low:g}-{high:g} µT (the Earth's {EARTH_FIELD_UT[0]:g}-{EARTH_FIELD_UT[1]:g} µT total, times the cosine "
            f"of a dip up to 85°: the dip is not seen in one plane)")
    if len(fits) != 1:
        which = "no unit" if not fits else " and ".join(fits)
        return UnitDecision(decision.units, f"{decision.reason}; the planar fit's field in the plane {field:.4g} is "
                                            f"{which} in {band}, so the magnitude decides", decision.median_field)
    unit = fits[0]
    was = "" if unit == decision.units else f", which read {decision.units}"
    return UnitDecision(unit, f"from the data: the planar fit's field in the plane {field:.4g} (the hard iron removed) is "
                              f"{field * UT_PER_UNIT[unit]:.3g} µT in {unit}, the only unit in {band}; the median "
                              f"|m| {decision.median_field:.4g} holds the hard iron{was}", decision.median_field)
