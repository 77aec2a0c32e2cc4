"""χ² and the held-out error of a calibration against the simulation band of its own fitted model.

The χ² distribution is the band of χ² only when the model is linear and the noise Gaussian and
known; the norm residual (Lu 2017, eq. 13) is not linear in θ, the weights depend on the fit and
the held-out error has no closed-form distribution at all.  The band here is a parametric
bootstrap: the fitted model ``(T, o)`` is simulated at the recorded poses (the calibrated
direction of every pose, Lu 2017 eq. 5, with the per-pose noise σ given with the data)
``SIMULATIONS`` times, each simulated data set is refitted by maximum likelihood (all of them in
one IPOPT problem, :class:`optcal.families.accel.batched.BatchedMaximumLikelihood`), and for each
refit the same two statistics are computed as for the measured fit:

* χ² ``= Σ_k r_k² / σ_r,k²`` with ``σ_r,k`` the pose noise propagated to the norm residual
  (:func:`optcal.applications.quality.validation.norm_noise`; Lu 2017 eq. 13-14);
* the held-out rms: the leave-one-out norm residuals of the fit, first order
  (:func:`optcal.core.norm_residual.heldout_residuals`), so that every simulation costs no extra fit.

The measured values are placed among the simulated ones (percentile) and against the
``BAND_PERCENTILES`` band, as the diagnosis's simulation check places its statistics
(:func:`optcal.applications.diagnosis.simulation.place_among_simulations`).  Without a per-pose
σ the noise would have to be estimated from the same residuals, which matches χ² by
construction: no band is computed then.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.core.poses import PoseTable
from optcal.applications.diagnosis.simulation import place_among_simulations
from optcal.applications.quality.bands import BandCheck
from optcal.families.accel.result import CalibrationResult
from optcal.core.stats import rms

#: Simulated data sets behind the band.
SIMULATIONS: int = 200
#: Percentiles of the simulated distribution that bound the reported band.
BAND_PERCENTILES: tuple[float, float] = (5.0, 95.0)
#: The same as quantile levels in [0, 1].
BAND_LEVELS: tuple[float, float] = (BAND_PERCENTILES[0] / 100, BAND_PERCENTILES[1] / 100)
#: The band in words.
BAND_LABEL: str = f"{BAND_PERCENTILES[0]:g}-{BAND_PERCENTILES[1]:g} %"


@dataclass(frozen=True)
class FitStatistics:
    """The two statistics of one fit that are compared with the band.

    Attributes
    ----------
    chisqr : float
        ``Σ r_k² / σ_r,k²``.
    heldout_rms_g : float
        rms of the leave-one-out norm residuals, g.
    """

    chisqr: float
    heldout_rms_g: float


@dataclass(frozen=True)
class SimulationBand:
    """Where a calibration's χ² and held-out rms lie among fits of simulations of its own model.

    Attributes
    ----------
    checks : list of BandCheck
        χ² and the held-out rms (g), each with its percentile, median and ``BAND_PERCENTILES`` band
        (empty when not computed).
    simulations : int
        Simulated data sets refitted successfully.
    note : str
        Why no band was computed ("" when it was).
    """

    checks: list[BandCheck]
    simulations: int
    note: str = ""


def fit_statistics(T: NDArray[np.float64], o: NDArray[np.float64], acc: NDArray[np.float64],
                   sigma: NDArray[np.float64]) -> FitStatistics:
    """χ² and the leave-one-out held-out rms of the fit ``(T, o)`` to the poses ``acc`` with noise ``sigma``."""
    from optcal.applications.quality.validation import norm_noise
    from optcal.core.norm_residual import NormResidualKernel, heldout_residuals

    point = NormResidualKernel(acc).at(T, o)
    weights = 1.0 / norm_noise(T, o, acc, sigma) ** 2
    r = point.residuals
    heldout = heldout_residuals(r, point.jacobian().T, weights)
    return FitStatistics(float(np.sum(weights * r * r)), rms(heldout))


def band_text(check: BandCheck) -> str:
    """``statistic: value, at the Nth percentile of ... (median, band)``: a statistic among the simulated refits."""
    def show(x: float) -> str:
        return f"{x * 1e3:.3g} mg" if check.unit == "g" else f"{x:.4g}"

    return (f"{check.statistic}: {show(check.measured)}, at the {check.percentile:.0f}th percentile of {check.source} "
            f"(median {show(check.median)}, {BAND_LABEL} band {show(check.low)} .. {show(check.high)})")


def simulation_band(result: CalibrationResult, poses: PoseTable, simulations: int = SIMULATIONS,
                    seed: int = 0) -> SimulationBand:
    """Simulate the fitted model at the recorded poses, refit, and place the measured χ² and held-out rms.

    Parameters
    ----------
    result : CalibrationResult
        The calibration of ``poses``.
    poses : PoseTable
        Its poses, with their per-pose noise ``sigma`` (no band without it).
    simulations : int
        Simulated data sets.
    seed : int
        Seed of the simulated noise.

    Returns
    -------
    SimulationBand
    """
    from optcal.errors import ConvergenceWarning, InputError
    from optcal.families.accel.batched import BatchedMaximumLikelihood
    from optcal.core.model import unpack_theta
    from optcal.families.simulate.poses import simulate_poses

    if poses.sigma is None:
        return SimulationBand([], 0, "no per-pose noise given: a noise estimated from these residuals would "
                                     "match χ² by construction")
    idf = result.identifiability
    if idf is not None and idf.rank < idf.n_params:
        return SimulationBand([], 0, "the poses do not determine every parameter, so refits of simulations scatter "
                                     "along the undetermined combination")
    directions = result.correct(poses.acc)
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    rng = np.random.default_rng(seed)
    tables = [simulate_poses(result.model, directions, poses.sigma, rng=rng, units=poses.units) for _ in range(simulations)]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            fits = BatchedMaximumLikelihood().fit_many(tables)
    except InputError as exc:
        return SimulationBand([], 0, f"the simulations could not be refitted: {exc}")
    stats = [fit_statistics(*unpack_theta(theta), table.acc, poses.sigma)
             for theta, table, ok in zip(fits.theta, tables, fits.success) if ok]
    if len(stats) < simulations // 2:
        return SimulationBand([], len(stats), f"only {len(stats)} of {simulations} simulated refits converged")
    measured = fit_statistics(result.T, result.o, poses.acc, poses.sigma)
    source = f"{len(stats)} simulations of the fitted model, each refitted"
    checks = []
    for what, value, simulated, unit in (
        ("χ² of the fit", measured.chisqr, np.array([s.chisqr for s in stats]), ""),
        ("held-out rms of |a| − 1 g (leave-one-out)", measured.heldout_rms_g,
         np.array([s.heldout_rms_g for s in stats]), "g"),
    ):
        place = place_among_simulations(value, simulated, BAND_LEVELS)
        checks.append(BandCheck(what, value, place.low, place.high, source, percentile=place.percentile,
                                median=place.median, unit=unit))
    return SimulationBand(checks, len(stats))


__all__ = ["BAND_LABEL", "BAND_LEVELS", "BAND_PERCENTILES", "FitStatistics", "band_text", "SIMULATIONS", "SimulationBand", "fit_statistics", "simulation_band"]
