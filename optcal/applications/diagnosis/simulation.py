"""The simulation check: the fitted model simulated on the same poses (parametric bootstrap).

The fitted model is simulated on the same poses (fitted directions, temperatures and times;
the noise the model claims: the given per-pose σ, or the residual scale when none was given)
and refitted many times.  For each statistic of the residuals — rms, whiteness along pose
order and time (lag-1 autocorrelation, Ljung–Box), partial correlation with the regressor of
every candidate effect, tails (excess kurtosis, largest standardised residual) — the measured
value is compared with the simulated band; what falls outside is what the simulation gets wrong.

:func:`place_among_simulations` places a measured statistic among its simulated values (band,
median, percentile, Monte Carlo p value); the simulation band of a calibration's report
(:mod:`optcal.applications.quality.simulation_band`) places its statistics with it too.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats as sps

from optcal.applications.diagnosis.effects import REGRESSOR_WORDS
from optcal.applications.diagnosis.fitting import Fit, Fitter, orthogonal_part
from optcal.applications.diagnosis.problem import BETA_INDEX, PoseData
from optcal.applications.diagnosis.progress import Loop, plain_loop
from optcal.core.model import AXES
from optcal.core.stats import rms

#: Plain-words meaning of each residual statistic (the correlations are named per candidate).
STAT_MEANING: dict[str, str] = {
    "rms_g": "rms of the norm residuals (g)",
    "lag1_pose_order": "lag-1 autocorrelation along pose order",
    "ljung_box_pose_order": "Ljung-Box whiteness statistic along pose order",
    "lag1_time": "lag-1 autocorrelation along time",
    "ljung_box_time": "Ljung-Box whiteness statistic along time",
    "excess_kurtosis": "excess kurtosis of the standardised residuals (tails)",
    "max_abs_z": "largest standardised residual (tails)",
}


def autocorrelation(e: NDArray, lag: int) -> float:
    """Sample autocorrelation of ``e`` at ``lag``."""
    e = e - e.mean()
    den = float(np.sum(e * e))
    return float(np.sum(e[lag:] * e[:-lag]) / den) if den > 0 and len(e) > lag else 0.0


def ljung_box(e: NDArray, lags: int) -> float:
    """Ljung–Box statistic ``n(n+2) Σ ρ_k²/(n−k)`` over ``lags`` lags."""
    n = len(e)
    return float(n * (n + 2) * sum(autocorrelation(e, k) ** 2 / (n - k) for k in range(1, lags + 1)))


def correlation_name(effect: str, axis: int) -> str:
    """Key of the partial correlation of the residuals with a candidate's regressor."""
    return f"corr_{effect}_{AXES[axis]}"


def statistic_meaning(name: str, time_is_pose_order: bool = False) -> str:
    """Plain words for a statistic key (no internal names)."""
    if name.startswith("corr_"):
        effect, axis = name[len("corr_"):].rsplit("_", 1)
        return f"correlation with {REGRESSOR_WORDS[effect]} on axis {axis} (a {effect.replace('_', ' ')} would show here)"
    meaning = STAT_MEANING[name]
    if name.endswith("pose_order") and time_is_pose_order:
        meaning += " (= time order)"
    return meaning


@dataclass(frozen=True)
class Placement:
    """Where a measured statistic lies among its values in fits of simulations of the fitted model.

    Attributes
    ----------
    measured : float
    low, high : float
        The band: the simulated values' quantiles at the two levels asked for (NaN without simulations).
    median : float
        The simulated values' median (NaN without simulations).
    percentile : float
        Share of the simulated values below ``measured``, ties counted half, % (NaN without simulations).
    p_value : float
        Two-sided Monte Carlo p value ``min(1, 2 min((#{s ≥ m} + 1)/(N + 1), (#{s ≤ m} + 1)/(N + 1)))``
        of ``N`` simulated values ``s`` and the measured ``m`` (1 without simulations).
    """

    measured: float
    low: float
    high: float
    median: float
    percentile: float
    p_value: float

    @property
    def outside(self) -> bool:
        """Whether ``measured`` lies outside ``[low, high]`` (never without simulations)."""
        return bool(self.measured < self.low or self.measured > self.high)


def place_among_simulations(measured: float, simulated: ArrayLike, levels: tuple[float, float]) -> Placement:
    """Place ``measured`` among the values of the same statistic in refits of simulated data sets.

    Parameters
    ----------
    measured : float
        The statistic of the fit to the data.
    simulated : array_like, shape (N,)
        The statistic of each fit to a simulation of the fitted model.
    levels : tuple of float
        Quantile levels in [0, 1] of the band's bounds (``(0.05, 0.95)`` for a 5-95 % band).

    Returns
    -------
    Placement
    """
    s = np.asarray(simulated, dtype=float)
    if not s.size:
        return Placement(measured, float("nan"), float("nan"), float("nan"), float("nan"), 1.0)
    low, high = (float(np.quantile(s, q)) for q in levels)
    percentile = float(100.0 * (np.sum(s < measured) + 0.5 * np.sum(s == measured)) / s.size)
    p = min(1.0, 2 * min((np.sum(s >= measured) + 1) / (s.size + 1), (np.sum(s <= measured) + 1) / (s.size + 1)))
    return Placement(measured, low, high, float(np.median(s)), percentile, float(p))


@dataclass
class StatisticBand:
    """One residual statistic: measured value against its simulated band.

    Attributes
    ----------
    measured, simulated_median : float
    band : list of float
        ``[low, high]`` quantiles of the simulations (coverage :attr:`SimulationCheck.band`).
    p_value : float
        Two-sided Monte Carlo p value of the measured value.
    outside : bool
    meaning : str
        Plain words.
    """

    measured: float
    simulated_median: float
    band: list[float]
    p_value: float
    outside: bool
    meaning: str


@dataclass
class SimulationCheck:
    """The result of a simulation check (JSON ``simulation_check``).

    Attributes
    ----------
    model : str
        The model simulated.
    simulations : int
    noise : str
        Which noise was simulated, in words.
    noise_scale : float or None
        rms of the standardised residuals when σ was given (1 when it describes the scatter).
    band : float
        Coverage of the bands.
    statistics : dict of str to StatisticBand
    outside_band : list of str
        Keys of the statistics outside their band.
    """

    model: str
    simulations: int
    noise: str
    noise_scale: float | None
    band: float
    statistics: dict[str, StatisticBand] = field(default_factory=dict)
    outside_band: list[str] = field(default_factory=list)

    @property
    def multiplicity_note(self) -> str | None:
        """How many statistics fall outside by chance."""
        if not self.simulations or len(self.statistics) <= 1:
            return None
        return (
            f"({len(self.statistics)} statistics at {self.band * 100:g} % each: about "
            f"{len(self.statistics) * (1 - self.band):.2g} would fall outside by chance: a band alone names no effect; the forward selection tests them)"
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "model": self.model,
            "simulations": self.simulations,
            "noise": self.noise,
            "noise_scale": self.noise_scale,
            "band": self.band,
            "statistics": {k: asdict(v) for k, v in self.statistics.items()},
            "outside_band": list(self.outside_band),
        }
        if self.noise_scale is not None:
            out["noise_scale_meaning"] = (
                "rms of the standardised residuals: 1 when the given per-pose σ describes the pose-to-pose error"
            )
        if self.multiplicity_note:
            out["multiplicity_note"] = self.multiplicity_note
        return out


def residual_statistics(
    fitter: Fitter, fit: Fit, r: NDArray, J_full: NDArray, G: NDArray, candidates: list[tuple[str, int]]
) -> dict[str, float]:
    """The statistics compared in the simulation check (module docstring)."""
    n = fitter.n
    kept = fit.kept(n)
    e = np.sqrt(fitter.w) * r
    scale = np.sqrt(np.sum(e[kept] ** 2) / max(kept.sum() - fit.n_params + len(fit.outliers), 1))
    out = {"rms_g": rms(r[kept])}
    ek = e[kept]
    lags = max(1, min(5, int(kept.sum()) // 8))
    out["lag1_pose_order"] = autocorrelation(ek, 1)
    out["ljung_box_pose_order"] = ljung_box(ek, lags)
    if fitter.reg.has_time and not np.array_equal(fitter.time_order, np.arange(n)):
        et = e[fitter.time_order][kept[fitter.time_order]]
        out["lag1_time"] = autocorrelation(et, 1)
        out["ljung_box_time"] = ljung_box(et, lags)
    z = ek / max(scale, 1e-300)
    out["excess_kurtosis"] = float(sps.kurtosis(z, fisher=True, bias=False)) if len(z) > 3 else 0.0
    out["max_abs_z"] = float(np.max(np.abs(z)))
    open_candidates = [(e, a) for e, a in candidates if (e, a) not in fit.terms]
    if open_candidates:
        columns = [9 + BETA_INDEX[(e, a, 1)] for e, a in open_candidates]
        g_perp = orthogonal_part(J_full[kept][:, columns], G[kept])
        norms = np.linalg.norm(g_perp, axis=0) * np.linalg.norm(ek)
        for (effect, axis), gp, den in zip(open_candidates, g_perp.T, norms):
            out[correlation_name(effect, axis)] = float(ek @ gp / den) if den > 0 else 0.0
    return out


def pose_noise(fitter: Fitter, rng: np.random.Generator) -> NDArray[np.float64]:
    """Unit-variance noise of every pose's axes (n, 3) as the diagnosis's noise model claims it: independent
    poses, or correlated in time when the fitter tests under the pose-noise correlation
    (:meth:`optcal.applications.diagnosis.correlation.CorrelationOperator.sample`)."""
    if fitter.correlation is None:
        return rng.standard_normal((fitter.n, 3))
    return fitter.correlation.sample(rng)[0]


def simulation_check(
    fitter: Fitter, fit: Fit, candidates: list[tuple[str, int]], simulations: int, band: float, seed: int,
    loop: Loop = plain_loop,
) -> SimulationCheck:
    """Parametric bootstrap of ``fit``: measured residual statistics against simulated bands."""
    n = fitter.n
    rng = np.random.default_rng(seed)
    clean = fitter.noise_free(fit)
    kept = fit.kept(n)
    lam = float(np.sqrt(fit.rss * fitter.w_mean / max(kept.sum() - (fit.n_params - len(fit.outliers)), 1)))
    known = fitter.poses.sigma is not None
    sigma = np.full(n, lam) if fitter.poses.sigma is None else fitter.poses.sigma * np.ones(n)
    noise = (
        "noise: the per-pose σ given with the data" if known
        else "noise: estimated from these residuals (no per-pose σ given), so the rms is matched by construction"
    )
    w = fitter.weights(fit)
    G, J = fitter.jacobians(fit, w)
    measured = residual_statistics(fitter, fit, fit.residuals, J, G, candidates)
    sims: dict[str, list[float]] = {k: [] for k in measured}
    if fitter.correlation is not None:
        noise += "; correlated between neighbouring poses as estimated (the pose-noise correlation in use)"
    for _ in loop(range(simulations), "simulation check", simulations):
        acc = clean + pose_noise(fitter, rng) * sigma[:, None]
        data = PoseData.of(fitter.norm.forward(acc), fitter.reg, fitter.data.step)
        sim_fit = fitter.fit(fit.terms, fit.outliers, fit.x, data)
        G_s, J_s = fitter.jacobians(sim_fit, w, data)
        st = residual_statistics(fitter, sim_fit, sim_fit.residuals, J_s, G_s, candidates)
        for k in sims:
            sims[k].append(st[k])
    lo_q, hi_q = (1 - band) / 2, 1 - (1 - band) / 2
    time_is_order = fitter.reg.has_time and np.array_equal(fitter.time_order, np.arange(n))
    check = SimulationCheck(fit.describe(), simulations, noise, lam if known else None, band)
    for name, value in measured.items():
        place = place_among_simulations(value, sims[name], (lo_q, hi_q))
        outside = place.outside and not (name == "rms_g" and not known)
        check.statistics[name] = StatisticBand(value, place.median, [place.low, place.high], place.p_value, outside,
                                               statistic_meaning(name, time_is_order))
        if outside:
            check.outside_band.append(name)
    return check
