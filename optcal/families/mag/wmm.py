"""The World Magnetic Model at the session's place and date, and a calibration's field and dip against it.

A calibrated magnetometer says the local field's strength (in the data's units, when they are physical) and, with an
accelerometer, its inclination (dip).  The World Magnetic Model (NOAA/BGS, WMM2025 for 2025.0–2030.0) predicts both
at a place and date from its spherical-harmonic coefficients; the model itself comes from pygeomag (pure Python, the
``mag`` extra: ``pip install 'optcal[mag]'``), whose output these functions only read.

The model describes the core field: a building's steel, a vehicle's frame or a local anomaly shifts the field by a
few hundred nT to several µT (the WMM's own stated uncertainty is about 150 nT in total intensity and 0.2° in
inclination), so a difference is a finding about the site or the calibration, never a correction applied to it.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from typing import Any

import numpy as np

from optcal.errors import InputError
from optcal.families.mag.units import UT_PER_UNIT

#: The WMM2025 error model (NOAA/BGS, "The US/UK World Magnetic Model for 2025-2030", table of global
#: uncertainties): one standard deviation of the model against the observed field, total intensity in nT and
#: inclination in degrees.  A site's crustal field is part of it.
WMM_SIGMA_F_NT: float = 145.0
WMM_SIGMA_I_DEG: float = 0.21


@dataclass(frozen=True)
class Location:
    """Where the session was recorded: WGS-84 latitude and longitude, degrees, and height above the ellipsoid, m."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    @classmethod
    def parse(cls, text: str) -> Location:
        """``LAT,LON[,ALT]`` (degrees, degrees, metres) as ``--location`` takes it.

        Raises
        ------
        InputError
            Not two or three numbers, or out of range; the message names ``--location``.
        """
        parts = [p.strip() for p in str(text).split(",")]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = []
        if len(values) not in (2, 3) or not all(np.isfinite(values)):
            raise InputError(f"--location {text!r}: give LAT,LON[,ALT] in degrees and metres, e.g. --location 52.2,0.12,30")
        lat, lon = values[0], values[1]
        if not -90.0 <= lat <= 90.0 or not -180.0 <= lon <= 360.0:
            raise InputError(f"--location {text!r}: latitude must lie in -90..90 and longitude in -180..360 degrees")
        alt = values[2] if len(values) == 3 else 0.0
        if not -1000.0 <= alt <= 850_000.0:
            raise InputError(f"--location {text!r}: the height {alt:g} m is outside the model's -1 km..850 km")
        return cls(lat, lon if lon <= 180.0 else lon - 360.0, alt)


def parse_date(text: str | None) -> tuple[_dt.date, str]:
    """The session's date from ``--date YYYY-MM-DD`` (today when not given, and said so).

    Returns
    -------
    (date, reason)
    """
    if text is None:
        today = _dt.date.today()
        return today, f"today, {today.isoformat()} (--date YYYY-MM-DD gives the session's)"
    try:
        return _dt.date.fromisoformat(str(text).strip()), "--date"
    except ValueError:
        raise InputError(f"--date {text!r}: give the session's date as YYYY-MM-DD, e.g. --date 2026-11-28") from None


def decimal_year(date: _dt.date) -> float:
    """``date`` as a decimal year (its day of the year over the year's days), as the WMM takes time."""
    start = _dt.date(date.year, 1, 1)
    days = (_dt.date(date.year + 1, 1, 1) - start).days
    return date.year + (date - start).days / days


@dataclass(frozen=True)
class WmmReference:
    """The World Magnetic Model's field at a place and date.

    Attributes
    ----------
    total_nT : float
        Total intensity F, nT.
    inclination_deg : float
        Inclination I (dip), degrees, positive when the field points below the horizontal.
    declination_deg : float
        Declination D, degrees east of true north.
    model : str
        The coefficients' name and epoch (e.g. ``WMM 2025.0``).
    location : Location
    date : datetime.date
    outside_lifespan : bool
        The date lies outside the model's five years: the prediction is extrapolated (and said so).
    """

    total_nT: float
    inclination_deg: float
    declination_deg: float
    model: str
    location: Location
    date: _dt.date
    outside_lifespan: bool


def _geomag() -> Any:
    try:
        from pygeomag import GeoMag
    except ImportError:
        raise InputError("--location needs the World Magnetic Model: pip install 'optcal[mag]' (pygeomag)") from None
    return GeoMag


def wmm_reference(location: Location, date: _dt.date) -> WmmReference:
    """The World Magnetic Model's total intensity, inclination and declination at ``location`` on ``date``.

    Raises
    ------
    InputError
        pygeomag is not installed (the message gives the pip command).
    """
    geomag = _geomag()(base_year=_dt.datetime(date.year, date.month, date.day))
    year = decimal_year(date)
    result = geomag.calculate(glat=location.lat_deg, glon=location.lon_deg, alt=location.alt_m / 1000.0, time=year,
                              allow_date_outside_lifespan=True)
    epoch = float(getattr(geomag, "_epoch", np.nan))
    life = 5.0  # every WMM release covers five years from its epoch
    name = str(getattr(geomag, "_model", "WMM")).strip() or "WMM"
    model = f"{name} (epoch {epoch:.1f})" if np.isfinite(epoch) else name
    outside = bool(np.isfinite(epoch) and not epoch <= year < epoch + life)
    return WmmReference(float(result.f), float(result.i), float(result.d), model, location, date, outside)


def compare_with_wmm(ref: WmmReference, field_strength: float, units: str, dip_deg: float | None = None,
                     dip_se_deg: float | None = None) -> dict[str, Any]:
    """A calibration's field strength and dip against the model (the ``"wmm"`` entry of the JSON).

    The field strength is compared when the data's units are physical (µT, nT, T, gauss, mgauss: counts have no
    scale to the field); the dip when an accelerometer gave it.  Each difference is said in the model's own
    uncertainty (:data:`WMM_SIGMA_F_NT`, :data:`WMM_SIGMA_I_DEG`; the dip's with its standard error added): beyond
    three of them the site's field is not the core field the model predicts (steel, a vehicle, an anomaly) or the
    units or the calibration are wrong.
    """
    out: dict[str, Any] = {
        "model": ref.model, "date": ref.date.isoformat(),
        "location": {"lat_deg": ref.location.lat_deg, "lon_deg": ref.location.lon_deg, "alt_m": ref.location.alt_m},
        "field_strength_nT": ref.total_nT, "dip_deg": ref.inclination_deg, "declination_deg": ref.declination_deg,
        "field_sigma_nT": WMM_SIGMA_F_NT, "dip_sigma_deg": WMM_SIGMA_I_DEG, "outside_lifespan": ref.outside_lifespan,
    }
    if units in UT_PER_UNIT:
        measured = field_strength * UT_PER_UNIT[units] * 1000.0
        out["measured_field_nT"] = measured
        out["field_difference_nT"] = measured - ref.total_nT
        out["field_difference_relative"] = (measured - ref.total_nT) / ref.total_nT
        out["field_difference_sigmas"] = (measured - ref.total_nT) / WMM_SIGMA_F_NT
    if dip_deg is not None and np.isfinite(dip_deg):
        sigma = float(np.hypot(WMM_SIGMA_I_DEG, dip_se_deg or 0.0))
        out["measured_dip_deg"] = dip_deg
        out["dip_difference_deg"] = dip_deg - ref.inclination_deg
        out["dip_difference_sigmas"] = (dip_deg - ref.inclination_deg) / sigma
    return out


def wmm_lines(comparison: dict[str, Any]) -> list[str]:
    """The comparison in words, for the text report (one line per quantity)."""
    c = comparison
    loc = c["location"]
    head = (f"World Magnetic Model ({c['model']}, {c['date']}, {loc['lat_deg']:.4g}°, {loc['lon_deg']:.4g}°, "
            f"{loc['alt_m']:g} m): field {c['field_strength_nT']:.0f} nT, dip {c['dip_deg']:.2f}°, declination "
            f"{c['declination_deg']:.2f}°" + (" (date outside the model's five years: extrapolated)"
                                              if c["outside_lifespan"] else ""))
    lines = [head]
    if "measured_field_nT" in c:
        lines.append(f"  field measured {c['measured_field_nT']:.0f} nT: {c['field_difference_nT']:+.0f} nT "
                     f"({100 * c['field_difference_relative']:+.1f} %, {c['field_difference_sigmas']:+.1f} σ of the model)")
    else:
        lines.append("  field strength not compared: the magnetometer's units are counts (--mag-units gives a physical unit)")
    if "measured_dip_deg" in c:
        lines.append(f"  dip measured {c['measured_dip_deg']:.2f}°: {c['dip_difference_deg']:+.2f}° "
                     f"({c['dip_difference_sigmas']:+.1f} σ of the model and the estimate)")
    return lines
