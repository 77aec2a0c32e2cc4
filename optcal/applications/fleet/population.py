"""Population statistics of a fleet: robust location and spread, flags, figures.

Rule (stated once, used by ``optcal fleet``): for every parameter θ_i of
:data:`optcal.core.model.PARAM_NAMES`, the population's location is the **median** over the
units calibrated by their own data and its spread the **normalised median absolute
deviation** ``s_i = 1.4826 · median |θ_i − median θ_i|`` (equal to the standard deviation
for a normal population, and unmoved by up to half the units being odd).  A unit is
**flagged** when any parameter lies outside ``median ± k_n s_i`` or its rms norm residual
above ``median + k_n s`` (one-sided: a small residual is no fault).  ``k``
(:data:`DEFAULT_FLAG_THRESHOLD` unless given) is the threshold of a large population; for n
units, ``k_n`` (:func:`finite_sample_threshold`) keeps the same tail probability once the noise
of the median and of the MAD is accounted for (the robust z is then close to Student's t with
``0.37 (n − 1)`` degrees of freedom, 0.37 being the MAD's efficiency at the normal, times
``√(1 + π/(2n))`` for the median): 4.3 for 50 units, 3.6 for 300, 3.5 in the limit.  With
nine two-sided checks and one one-sided, the union bound puts the false-flag rate of a clean
fleet at ≤ 19 Φ(−k) ≈ 0.44 % for k = 3.5; the measured rate is in ``studies/fleet_scale.md``.
Units whose calibration leans on the population prior are checked on their residual only
(their parameters come partly from the population).  Units recorded in other units than most
of the fleet are flagged for that.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.applications.fleet.unit import UnitOutcome
from optcal.core.model import PARAM_NAMES

#: Robust z beyond which a unit is flagged.
DEFAULT_FLAG_THRESHOLD: float = 3.5
#: MAD → standard deviation of a normal distribution.
MAD_TO_SD: float = 1.4826
#: The statistics checked: the nine parameters and the rms norm residual.
STATISTICS: tuple[str, ...] = (*PARAM_NAMES, "rms_g")
#: Fewest units the statistics are computed from.
MIN_UNITS: int = 5


@dataclass(frozen=True)
class RobustBand:
    """Robust location and spread of one statistic over the population.

    Attributes
    ----------
    name : str
    median, spread : float
        Median and normalised MAD (:data:`MAD_TO_SD` · MAD).
    low, high : float
        The band ``median ± k·spread`` outside which a unit is flagged (``low`` is −inf for the
        one-sided residual check).
    n_units : int
        Units the band was computed from.
    """

    name: str
    median: float
    spread: float
    low: float
    high: float
    n_units: int

    def robust_z(self, value: float) -> float:
        """``(value − median) / spread``."""
        return (value - self.median) / self.spread if self.spread > 0 else (0.0 if value == self.median else np.inf)


@dataclass(frozen=True)
class PopulationStats:
    """The robust bands of every statistic and the rule that uses them.

    Attributes
    ----------
    bands : tuple of RobustBand
        One per :data:`STATISTICS`.
    threshold : float
        ``k`` of the flag rule.
    units : str
        Units of the raw data of the population.
    threshold_n : float
        ``k_n``, the threshold for this population's size (:func:`finite_sample_threshold`).
    """

    bands: tuple[RobustBand, ...]
    threshold: float
    units: str
    threshold_n: float

    def band(self, name: str) -> RobustBand:
        """The band of the statistic ``name``."""
        for b in self.bands:
            if b.name == name:
                return b
        raise InputError(f"unknown statistic {name!r}; use one of {', '.join(STATISTICS)}")

    def rule(self) -> str:
        """The flag rule in words."""
        n = self.bands[0].n_units
        return (f"flagged when a parameter lies outside median ± {self.threshold_n:.3g}·1.4826·MAD of the {n} units "
                f"calibrated by their own data, or the rms residual above median + {self.threshold_n:.3g}·1.4826·MAD "
                f"(k = {self.threshold:g} corrected for {n} units)")


def finite_sample_threshold(k: float, n_units: int) -> float:
    """The threshold for a robust z from ``n_units`` units with the tail probability of ``k`` (module docstring)."""
    from scipy.stats import norm, t

    dof = max(0.37 * (n_units - 1), 1.0)
    return float(t.ppf(norm.cdf(k), dof) * np.sqrt(1.0 + np.pi / (2.0 * n_units)))


def statistic_values(outcome: UnitOutcome) -> NDArray[np.float64]:
    """The values of :data:`STATISTICS` for one calibrated unit."""
    assert outcome.theta is not None
    return np.append(outcome.theta, outcome.rms_g)


def robust_location_spread(values: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Median and normalised MAD (:data:`MAD_TO_SD` · MAD) of each column of ``values`` (units × statistics)."""
    med = np.median(values, axis=0)
    return med, MAD_TO_SD * np.median(np.abs(values - med), axis=0)


def population_stats(outcomes: list[UnitOutcome], threshold: float = DEFAULT_FLAG_THRESHOLD) -> PopulationStats | None:
    """Robust bands from the units calibrated by their own data (``None`` when fewer than :data:`MIN_UNITS`)."""
    if not threshold > 0:
        raise InputError(f"flag_threshold must be positive, got {threshold}")
    own = [o for o in outcomes if o.status == "calibrated"]
    if not own:
        return None
    units = max({o.units for o in own}, key=lambda u: sum(o.units == u for o in own))
    own = [o for o in own if o.units == units]
    if len(own) < MIN_UNITS:
        return None
    med, spread = robust_location_spread(np.array([statistic_values(o) for o in own]))
    k_n = finite_sample_threshold(threshold, len(own))
    bands = []
    for i, name in enumerate(STATISTICS):
        low = -np.inf if name == "rms_g" else med[i] - k_n * spread[i]
        bands.append(RobustBand(name, float(med[i]), float(spread[i]), float(low), float(med[i] + k_n * spread[i]), len(own)))
    return PopulationStats(tuple(bands), float(threshold), units, k_n)


def flag_reason(outcome: UnitOutcome, stats: PopulationStats) -> str:
    """Why ``outcome`` lies outside the population's bands (empty when it does not)."""
    if not outcome.calibrated or outcome.theta is None:
        return ""
    if outcome.units != stats.units:
        return f"data in {outcome.units} while the population is in {stats.units}"
    values = statistic_values(outcome)
    checked = STATISTICS if outcome.status == "calibrated" else ("rms_g",)
    parts = []
    for i, band in enumerate(stats.bands):
        if band.name in checked and not band.low <= values[i] <= band.high:
            parts.append(f"{band.name} = {values[i]:.6g} is {band.robust_z(values[i]):+.1f} robust SD from the "
                         f"population median {band.median:.6g}")
    return "; ".join(parts)


def flag_units(outcomes: list[UnitOutcome], stats: PopulationStats) -> list[UnitOutcome]:
    """Set :attr:`UnitOutcome.flag` of every unit; return the flagged ones."""
    for o in outcomes:
        o.flag = flag_reason(o, stats)
    return [o for o in outcomes if o.flag]


def parameter_figure(outcomes: list[UnitOutcome], stats: PopulationStats, name: str, ax: Any | None = None) -> Any:
    """Histogram of one statistic over the calibrated units, its robust band, the flagged units.

    Returns the :class:`matplotlib.figure.Figure` (a new one unless ``ax`` is given).
    """
    from matplotlib.figure import Figure

    band = stats.band(name)
    i = STATISTICS.index(name)
    fig = None
    if ax is None:
        fig = Figure(figsize=(6, 3.5))
        ax = fig.add_subplot()
    own = [o for o in outcomes if o.calibrated and o.theta is not None and o.units == stats.units]
    values = np.array([statistic_values(o)[i] for o in own])
    flagged = np.array([bool(o.flag) for o in own], dtype=bool)
    if values.size:
        ax.hist(values[~flagged], bins=40, color="0.6", label=f"{int((~flagged).sum())} units")
        lo = band.low if np.isfinite(band.low) else values.min()
        ax.axvspan(lo, band.high, color="tab:blue", alpha=0.12, label=f"robust band (k = {stats.threshold_n:.3g})")
        ax.axvline(band.median, color="tab:blue", lw=1)
        for v, o in zip(values[flagged], [o for o, f in zip(own, flagged) if f]):
            ax.axvline(v, color="tab:red", lw=1)
            ax.annotate(o.unit, (v, 0), xytext=(2, 12), textcoords="offset points", rotation=90, fontsize=6, color="tab:red")
    ax.set_title(f"{name}: median {band.median:.5g}, robust SD {band.spread:.2g}", fontsize=8)
    ax.set_xlabel(f"{name} ({'g' if name == 'rms_g' else stats.units + ' based'})", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.legend(fontsize=6)
    return fig if fig is not None else ax.figure


def summary_figure(outcomes: list[UnitOutcome], stats: PopulationStats) -> Any:
    """Every statistic's :func:`parameter_figure` on one page (a 3 × 4 grid)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(14, 9), layout="constrained")
    axes = fig.subplots(3, 4).ravel()
    for ax, name in zip(axes, STATISTICS):
        parameter_figure(outcomes, stats, name, ax=ax)
    for ax in axes[len(STATISTICS):]:
        ax.axis("off")
    fig.suptitle(f"Fleet population, {stats.bands[0].n_units} units calibrated by their own data; {stats.rule()}", fontsize=9)
    return fig
