"""Bad solver options are bad input on every path that takes them: mle (both forms), exact, gyro, plan, fleet prior.

Each path builds its NLP through optcal.solvers.nlp, so an option IPOPT refuses is an ``InputError``
naming the option and the argument that carried it, before any solve.
"""

from __future__ import annotations

import numpy as np
import pytest

from optcal import calibrate
from optcal.errors import InputError
from optcal.families.simulate.poses import simulate_poses, uniform_directions

from helpers.common import rngs

#: A tolerance IPOPT refuses (it must be positive): IPOPT itself says only "Invalid options were detected".
BAD = {"ipopt.tol": -1.0}
REFUSED = r"IPOPT refused the options \{'ipopt.tol': -1.0\}.*check ipopt_options"


@pytest.fixture
def poses(lu_model):
    rd, rn = rngs(31)
    return simulate_poses(lu_model, uniform_directions(30, rd), 0.003, rng=rn)


@pytest.mark.parametrize("method", ["mle", "exact"])
def test_estimators(poses, method):
    with pytest.raises(InputError, match=REFUSED):
        calibrate(poses, method=method, ipopt_options=BAD)


def test_mle_vectorised_form(lu_model):
    from optcal.families.accel.mle import MLProblem

    rd, rn = rngs(32)
    many = simulate_poses(lu_model, uniform_directions(MLProblem.SX_LIMIT + 20, rd), 0.003, rng=rn)
    with pytest.raises(InputError, match=REFUSED):
        calibrate(many, method="mle", ipopt_options=BAD)


def test_gyro(lu_model):
    from optcal.core.poses import PoseTable
    from optcal.data.units import GyroUnitsDecision
    from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro
    from optcal.families.gyro.moves import moves_from_arrays
    from optcal.families.simulate.gyro import reference_gyro, simulate_imu

    rec = simulate_imu(lu_model, reference_gyro(1.0, rng=1), 14, rng=3, dwell_s=1.0, move_s=1.0)
    moves = moves_from_arrays(rec.t, rec.acc, rec.gyro, rec.intervals)
    acc = calibrate(PoseTable(acc=moves.acc_means))
    with pytest.raises(InputError, match=REFUSED):
        calibrate_gyro(moves, acc, GyroUnitsDecision("rad/s", "test"), GyroSettings(ipopt_options=BAD))


def test_plan_refinement():
    from optcal.applications.plan import Prior
    from optcal.applications.plan.information import Criterion
    from optcal.applications.plan.rounding import refine

    prior = Prior.nominal("g")
    directions = uniform_directions(12, np.random.default_rng(5))
    refined, status = refine(prior.information_vectors, directions, Criterion.D)
    assert refined.shape == directions.shape and status
    with pytest.raises(InputError, match=REFUSED):
        refine(prior.information_vectors, directions, Criterion.D, ipopt_options=BAD)


def test_fleet_prior(lu_model):
    from optcal.applications.fleet.prior import PopulationPrior, fit_with_prior

    rd, rn = rngs(33)
    unit = simulate_poses(lu_model, uniform_directions(12, rd), 0.002, rng=rn)
    prior = PopulationPrior(lu_model.theta, np.diag([1e-4, 1e-5, 1e-4, 1e-5, 1e-5, 1e-4, 4e-4, 4e-4, 4e-4]), 50, "g", 0.002)
    assert fit_with_prior(unit, prior, ipopt_options={"ipopt.max_iter": 100}).result.solver.success
    with pytest.raises(InputError, match=REFUSED):
        fit_with_prior(unit, prior, ipopt_options=BAD)
