"""The one-page report of a fleet (``optcal fleet --report FILE.html``), built from its public result types.

A verdict on the fleet as a whole (:func:`optcal.applications.quality.verdict.judge_fleet`), then the
population in the units engineers use: for every unit calibrated by its own data its θ is
stated as scale factors, non-orthogonality angles and biases in mg
(:func:`optcal.report.parameters.physical_vector`, Lu 2017 eq. 1 and 5) and the rms residual in
mg; the population's location and spread of each are the median and the normalised MAD
(:func:`optcal.applications.fleet.population.robust_location_spread`), its band ``median ± k_n·spread`` with
the fleet's own ``k_n``.  The units are flagged by the fleet's rule on θ
(:mod:`optcal.applications.fleet.population`); the report says which of the engineers' quantities put each
flagged unit outside.  Then one figure per quantity, the units without a calibration, the
population prior and what it did, and how the fleet was run.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from optcal.applications.fleet.results import FleetResult
from optcal.applications.fleet.unit import STATUSES, UnitOutcome
from optcal.core.model import PARAM_NAMES, LumpedModel
from optcal.report.document import ReportDocument, Section, Table, now_utc, significant, versions
from optcal.report.figures import embed
from optcal.report.parameters import Quantity, engineering_parameters, physical_vector
from optcal.applications.quality.verdict import DEFAULT_TOLERANCE_MG, judge_fleet

#: Units above which the per-quantity figures are embedded as PNG (an SVG grows with every mark).
SVG_MAX_UNITS: int = 2000
#: Rows of a unit table shown on the page (the rest are in the results table).
MAX_ROWS: int = 200
#: What each status means.
STATUS_WORDS: dict[str, str] = {
    "calibrated": "calibrated by its own poses, exactly as optcal calibrate",
    "calibrated_with_prior": "its poses do not determine every parameter; the population prior completes them",
    "refused": "data read, but no calibration (the poses cannot determine one)",
    "failed": "unreadable file or an error",
}


@dataclass(frozen=True)
class QuantityBand:
    """One engineers' quantity over the population.

    Attributes
    ----------
    name, symbol, unit : str
    median, spread, low, high : float
        Median, normalised MAD and the band ``median ± k_n·spread`` (``low`` −inf for the residual).
    """

    name: str
    symbol: str
    unit: str
    median: float
    spread: float
    low: float
    high: float

    def z(self, value: float) -> float:
        """Robust z of ``value``."""
        return (value - self.median) / self.spread if self.spread > 0 else 0.0

    def outside(self, value: float) -> bool:
        return not self.low <= value <= self.high


@dataclass(frozen=True)
class FleetPopulation:
    """The fleet in engineers' units.

    Attributes
    ----------
    units : str
        Raw units of the population.
    zero : ndarray, shape (3,)
        Raw reading the biases in mg are measured from.
    bands : list of QuantityBand
        Scale factors, angles, biases (mg) and the rms residual (mg).
    members : list of UnitOutcome
        The calibrated units in the population's units, in input order.
    values : ndarray, shape (len(members), len(bands))
    """

    units: str
    zero: NDArray[np.float64]
    bands: list[QuantityBand]
    members: list[UnitOutcome]
    values: NDArray[np.float64]

    def deviations(self, k: int) -> list[str]:
        """The quantities of member ``k`` outside their band, in words."""
        out = []
        for b, v in zip(self.bands, self.values[k]):
            if b.outside(v):
                out.append(f"{b.name} {significant(v, 6)} {b.unit} is {abs(b.z(v)):.1f} robust SD "
                           f"{'above' if v > b.median else 'below'} the fleet's median {significant(b.median, 6)}")
        return out


def _quantities(units: str, zero: NDArray[np.float64]) -> list[Quantity]:
    """Names, symbols and units of the quantities of :func:`physical_vector` (from the nominal sensor)."""
    return engineering_parameters(LumpedModel(np.eye(3), np.zeros(3)), units, None, zero).physical


def fleet_population(result: FleetResult) -> FleetPopulation | None:
    """Every calibrated unit's quantities and the population's robust bands (``None`` without population statistics)."""
    from optcal.data.units import nominal_conversion
    from optcal.applications.fleet.population import robust_location_spread

    stats = result.stats
    if stats is None:
        return None
    calibrated = [(o, o.theta) for o in result.outcomes
                  if o.calibrated and o.theta is not None and o.units == stats.units]
    members = [o for o, _ in calibrated]
    own = np.array([o.status == "calibrated" for o in members])
    zero = nominal_conversion(stats.units, np.array([theta[6:9] for _, theta in calibrated])).offset
    values = np.array([np.append(physical_vector(theta, zero), 1e3 * o.rms_g) for o, theta in calibrated])
    med, spread = robust_location_spread(values[own])
    k = stats.threshold_n
    names = [(q.name, q.symbol, q.unit) for q in _quantities(stats.units, zero)] + [("rms residual", "rms", "mg")]
    bands = [QuantityBand(name, symbol, unit, float(m), float(s), -np.inf if symbol == "rms" else float(m - k * s),
                          float(m + k * s))
             for (name, symbol, unit), m, s in zip(names, med, spread)]
    return FleetPopulation(stats.units, zero, bands, members, values)


def flag_words(result: FleetResult, population: FleetPopulation | None) -> dict[str, str]:
    """Why each flagged unit is flagged, in engineers' quantities (the fleet's own reason when none is outside)."""
    index = {o.unit: k for k, o in enumerate(population.members)} if population else {}
    out = {}
    for o in result.flagged:
        words = population.deviations(index[o.unit]) if population and o.unit in index else []
        out[o.unit] = "; ".join(words) if words else o.flag
    return out


def quantity_figure(population: FleetPopulation, j: int) -> Any:
    """Every unit's value of quantity ``j`` in input order, the robust band and the flagged units marked."""
    from matplotlib.figure import Figure

    band = population.bands[j]
    values = population.values[:, j]
    flagged = np.array([bool(o.flag) for o in population.members])
    prior = np.array([o.status == "calibrated_with_prior" for o in population.members])
    x = np.arange(values.size)
    fig = Figure(figsize=(7.0, 2.6), layout="constrained")
    ax = fig.add_subplot()
    low = band.low if np.isfinite(band.low) else min(float(values.min()), band.median)
    ax.axhspan(low, band.high, color="tab:blue", alpha=0.12, lw=0, label="robust band")
    ax.axhline(band.median, color="tab:blue", lw=0.8)
    plain = ~flagged & ~prior
    ax.plot(x[plain], values[plain], ".", ms=3 if values.size > 300 else 5, color="0.35", label="unit")
    if prior.any():
        ax.plot(x[prior & ~flagged], values[prior & ~flagged], "^", ms=5, color="tab:orange", label="with the prior")
    if flagged.any():
        ax.plot(x[flagged], values[flagged], "o", ms=6, mfc="none", mew=1.5, color="tab:red", label="flagged")
        for k in np.flatnonzero(flagged)[:12]:
            right = x[k] > 0.7 * values.size
            ax.annotate(population.members[k].unit, (x[k], values[k]), xytext=(-4 if right else 4, 4),
                        textcoords="offset points", ha="right" if right else "left", fontsize=7, color="tab:red")
    ax.set_xlabel("unit (input order)", fontsize=8)
    ax.set_ylabel(f"{band.symbol} ({band.unit})", fontsize=8)
    ax.set_title(f"{band.name}: median {significant(band.median, 6)} {band.unit}, robust SD {significant(band.spread, 2)}",
                 fontsize=9)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="best", ncols=4)
    return fig


def _population_section(result: FleetResult, population: FleetPopulation | None) -> Section:
    if population is None or result.stats is None:
        return Section("Population", ["No population statistics: fewer than five units were calibrated by their own "
                                      "data in the same units."])
    own = sum(o.status == "calibrated" for o in population.members)
    outside = [int(sum(b.outside(v) for v in population.values[:, j])) for j, b in enumerate(population.bands)]
    rows = [[b.name, b.symbol, significant(b.median, 7), significant(b.spread, 3),
             ("−∞" if not np.isfinite(b.low) else significant(b.low, 7)) + " .. " + significant(b.high, 7), b.unit, str(n)]
            for b, n in zip(population.bands, outside)]
    zero = "0" if not np.any(population.zero) else ", ".join(significant(z, 6) for z in population.zero)
    paragraphs = [
        f"{own} units calibrated by their own data in {population.units} make the population. Location: the median; "
        f"spread: the robust standard deviation 1.4826·MAD (equal to the standard deviation for a normal population, "
        f"unmoved by up to half the units being odd); band: median ± {result.stats.threshold_n:.3g} robust SD "
        f"(k = {result.stats.threshold:g} corrected for {own} units, so that a clean fleet has about 0.4 % of its "
        f"units flagged).",
        f"Units are flagged by the rule on the nine calibration parameters: {result.stats.rule()}. Scale factors are "
        f"the output per g, the angles the non-orthogonality of the sensing axes (Lu 2017, eq. 1), the biases are "
        f"referred to the calibrated output from the raw reading {zero}.",
    ]
    table = Table(["quantity", "symbol", "median", "robust SD", "band", "unit", "units outside"], rows,
                  "The population in engineers' units")
    fmt: Literal["png", "svg"] = "png" if len(population.members) > SVG_MAX_UNITS else "svg"
    figures = [embed(quantity_figure(population, j), f"{b.name} of every calibrated unit, the population's robust band "
                     "(shaded) and its median (line); flagged units circled in red", fmt)
               for j, b in enumerate(population.bands)]
    return Section("Population", paragraphs, [table], figures)


def _flagged_section(result: FleetResult, words: dict[str, str]) -> Section:
    flagged = result.flagged
    if not flagged:
        return Section("Flagged units", ["None: every calibrated unit lies inside the population's bands."])
    rows = [[o.unit, o.status, words[o.unit], o.flag] for o in flagged[:MAX_ROWS]]
    more = [f"{len(flagged) - MAX_ROWS} more in the results table."] if len(flagged) > MAX_ROWS else []
    return Section("Flagged units", more,
                   [Table(["unit", "status", "why, in engineers' units", "the fleet's rule"], rows)])


def _not_calibrated_section(result: FleetResult) -> Section:
    bad = result.not_calibrated
    if not bad:
        return Section("Units without a calibration", ["None: every unit was calibrated."])
    rows = [[o.unit, o.status, o.path, o.reason] for o in bad[:MAX_ROWS]]
    more = [f"{len(bad) - MAX_ROWS} more in the results table."] if len(bad) > MAX_ROWS else []
    return Section("Units without a calibration", more, [Table(["unit", "status", "file", "reason"], rows)])


def _prior_section(result: FleetResult, population: FleetPopulation | None) -> Section:
    prior = result.prior
    if prior is None:
        return Section("Population prior", [f"No population prior: {result.prior_note}."])
    zero = population.zero if population is not None else np.zeros(3)
    quantities = engineering_parameters(LumpedModel.from_theta(prior.mean), prior.units, prior.covariance, zero).physical
    rows = [[q.name, q.symbol, significant(q.value, 6), significant(q.stderr, 3), q.unit] for q in quantities]
    weak = [o for o in result.outcomes if o.status == "calibrated_with_prior"]
    weak_rows = []
    for o in weak[:MAX_ROWS]:
        share = [f"{n} {w:.2f}" for n, w in zip(PARAM_NAMES, o.prior_weight)] if o.prior_weight is not None else []
        strong = [s for s, w in zip(share, o.prior_weight if o.prior_weight is not None else []) if w >= 0.1]
        weak_rows.append([o.unit, str(o.n_poses), ", ".join(strong) or "all below 0.1",
                          significant(1e3 * o.rms_g, 3)])
    moved = [np.abs(o.theta_with_prior - o.theta) / o.stderr for o in result.outcomes
             if o.status == "calibrated" and o.theta is not None and o.theta_with_prior is not None
             and o.stderr is not None and np.all(o.stderr > 0)]
    paragraphs = [
        f"The population prior is the mean and covariance of θ over {prior.n_units} well-determined units "
        "(empirical Bayes). Every unit with data was refitted with it as a penalty; a unit whose own poses do not "
        "determine the calibration is calibrated with it (status calibrated_with_prior), and the share of each "
        "parameter that comes from the prior (0: the unit's data alone, 1: the prior alone) says how much.",
    ]
    if moved:
        shift = np.concatenate(moved)
        paragraphs.append(
            f"On the {len(moved)} units calibrated by their own data, the prior moves the parameters by a median of "
            f"{np.median(shift):.2g} and at most {shift.max():.2g} of their own standard errors: it does not bias them."
        )
    tables = [Table(["quantity", "symbol", "prior mean", "prior SD", "unit"], rows, "The prior in engineers' units")]
    if weak_rows:
        tables.append(Table(["unit", "poses", "share from the prior (≥ 0.1)", "rms residual (mg)"], weak_rows,
                            "Units calibrated with the prior"))
    else:
        paragraphs.append("No unit needed the prior: every unit's poses determine its calibration.")
    return Section("Population prior", paragraphs, tables)


def _units_section(result: FleetResult) -> Section:
    rows = [[s, str(result.count(s)), STATUS_WORDS[s]] for s in STATUSES]
    excluded: dict[str, int] = {}
    for o in result.outcomes:
        for key, n in o.exclusions.items():
            excluded[key] = excluded.get(key, 0) + int(n)
    rows_ex = [[k, str(v)] for k, v in sorted(excluded.items())] or [["nothing", "0"]]
    return Section("Units", [f"{len(result.outcomes)} units."],
                   [Table(["status", "units", "meaning"], rows),
                    Table(["excluded while reading, over all units", "samples or rows"], rows_ex)])


def _run_section(result: FleetResult, results_path: str) -> Section:
    rows = [["engine", result.engine], ["units per task", str(result.chunk)],
            ["wall time", f"{result.seconds:.3g} s (cluster start not included)"], ["results table", results_path]]
    return Section("Run", [], [Table(["", ""], rows)])


def fleet_document(result: FleetResult, results_path: str, command: str,
                   tolerance_mg: float = DEFAULT_TOLERANCE_MG) -> ReportDocument:
    """Report of ``optcal fleet``: the fleet's verdict, the population, the flagged and failed units, the prior, the run.

    Parameters
    ----------
    result : FleetResult
        From :func:`optcal.applications.fleet.engine.run_fleet`.
    results_path : str
        The Parquet table written beside it.
    command : str
        The exact command line.
    tolerance_mg : float
        Accuracy asked of each unit's calibrated norm, mg.
    """
    population = fleet_population(result)
    words = flag_words(result, population)
    verdict = judge_fleet(result, tolerance_mg, words)
    sections = [_units_section(result), _flagged_section(result, words), _population_section(result, population),
                _not_calibrated_section(result), _prior_section(result, population), _run_section(result, results_path)]
    title = f"Fleet of {len(result.outcomes)} units"
    return ReportDocument(title, results_path, verdict, sections, command, versions(), now_utc())


__all__ = ["FleetPopulation", "QuantityBand", "fleet_document", "fleet_population", "flag_words", "quantity_figure"]
