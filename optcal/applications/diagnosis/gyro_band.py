"""The gyroscope diagnosis's band: each move's bound of the gravity-prediction angle, from the fitted model simulated
along the recorded moves with the measured noise or from the linearised noise budget (step 1 of
:mod:`~optcal.applications.diagnosis.gyro_diagnosis`, whose module docstring states the Rayleigh law)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.gyro_problem import (GyroData, GyroParams, Noise, corrected_rates, move_budget,
                                                         predict)
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows


def band(angles_deg: NDArray[np.float64], noise: Noise, alpha: float) -> NDArray[np.float64]:
    """Each move's bound of the gravity-prediction angle at the family-wise level ``alpha`` (Rayleigh, module
    docstring), degrees."""
    m = angles_deg.size
    return np.degrees(np.sqrt(noise.move_rad2 * math.log(m / alpha)))


#: Simulation runs integrated together (memory: the longest move's steps x the moves x the runs, 3x3 each).
SIMULATION_CHUNK: int = 20


def simulated_move_rad2(data: GyroData, p: GyroParams, runs: int, seed: int) -> NDArray[np.float64]:
    """Each move's mean squared gravity-prediction angle (rad²) over ``runs`` simulations of the model ``p`` along
    the recorded moves with the measured noise.

    Each run takes the model's own prediction as the truth (``u₁ = Φ(ω)ᵀ u₀``, Tedaldi 2014, eq. 13-14) and
    integrates the corrected rates plus white rate noise of the rests' angle random walk (``N²/dt`` per step and
    raw axis, through ``T_g``) by the exponential map, from a start direction tilted by its pose's noise, to an end
    direction tilted by its pose's; the budget's sources a run does not simulate (the rests' bias offsets, the time
    base, the integration) tilt the prediction as Gaussian terms of their linearised variance.  The simulation
    follows each move's own axes against gravity (the linearised budget averages them: two thirds of an isotropic
    error) and the exponential map's nonlinearity.
    """
    moves = data.moves
    assert moves.noise is not None
    budget = move_budget(data, p)
    other = budget.bias + budget.time_base + budget.integration
    omega, _ = corrected_rates(data, p, data.raw, data.f_mid, data.t_mid, data.temp_mid, False)
    truth, _ = predict(data, omega)
    n, m = omega.shape[0], data.n_moves
    rate_sd = np.sqrt(moves.noise.arw2[None, :] / np.maximum(data.dt, 1e-12)[:, None])  # raw units, per step
    s0, s1 = data.pose_sigma[moves.move_from], data.pose_sigma[moves.move_to]
    rng = np.random.default_rng(seed)
    total = np.zeros(m)
    done = 0
    while done < runs:
        r = min(SIMULATION_CHUNK, runs - done)
        rates = omega[None] + (rng.standard_normal((r, n, 3)) * rate_sd) @ p.T.T
        theta = (rates * data.dt[None, :, None]).reshape(-1, 3)
        starts = (data.starts[None, :] + n * np.arange(r)[:, None]).ravel()
        u0 = unit_rows(np.tile(data.u0, (r, 1)) + rng.standard_normal((r * m, 3)) * np.tile(s0, r)[:, None])
        v = GravityPredictor.of_starts(starts, r * n).directions(theta, u0)
        v = unit_rows(v + rng.standard_normal((r * m, 3)) * np.sqrt(0.5 * np.tile(other, r))[:, None])
        u1 = unit_rows(np.tile(truth, (r, 1)) + rng.standard_normal((r * m, 3)) * np.tile(s1, r)[:, None])
        total += np.sum(np.radians(angles_deg(v, u1)).reshape(r, m) ** 2, axis=0)
        done += r
    return total / max(runs, 1)
