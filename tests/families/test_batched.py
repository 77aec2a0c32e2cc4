"""Batched ML solving: identical to one-at-a-time mle, noise-free exact, degenerate units marked."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.errors import IdentifiabilityError, InputError
from optcal.families.accel.batched import BatchedMaximumLikelihood, validate_many
from optcal.core.identifiability import parameter_full_scale
from optcal.families.accel.mle import MaximumLikelihood, NormResidualCost
from optcal.core.model import LumpedModel, lu2017_reference_model
from optcal.core.poses import PoseTable
from optcal.families.simulate.poses import simulate_poses, six_position, tilted_sweeps, uniform_directions


def _tables(seed: int) -> list[PoseTable]:
    """Mixed pose counts, with and without per-pose noise, Lu 2017's sensor and perturbed ones."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(24):
        model = lu2017_reference_model() if k % 3 else LumpedModel.from_physical(
            1 + 0.05 * rng.standard_normal(3), *np.deg2rad(rng.standard_normal(3)), bias=0.1 * rng.standard_normal(3))
        d = tilted_sweeps(40) if k % 2 else uniform_directions(30 + 10 * (k % 4), rng)
        p = simulate_poses(model, d, 0.005, rng=rng)
        out.append(p if k % 5 else PoseTable(acc=p.acc))  # every fifth without noise column
    return out


def test_batched_identical_to_one_at_a_time():
    tables = _tables(1)
    batched = BatchedMaximumLikelihood(batch=7).fit_many(tables)  # several problems per pose count
    ml = MaximumLikelihood()
    for k, t in enumerate(tables):
        single = ml.fit(t)
        se = np.sqrt(np.diag(single.covariance))
        assert np.max(np.abs(batched.theta[k] - single.params[:9]) / se) < 1e-6  # the solver tolerance (ipopt.tol 1e-10 on the scaled cost)
        assert np.max(np.abs(batched.theta[k] - single.params[:9]) / parameter_full_scale(single.params[:9])) < 5e-10
        assert np.allclose(batched.stderr[k], se, rtol=1e-6, atol=0)
        assert batched.rms_g[k] == pytest.approx(single.rms_norm_residual_g, rel=1e-6)
        assert batched.passes[k] == single.extra["passes"]
    assert batched.identifiable.all() and batched.success.all()


def test_batched_noise_free_reference():
    models = [lu2017_reference_model(), LumpedModel.from_physical([1.02, 0.97, 1.01], 0.01, -0.02, 0.005, [0.1, 0, -0.2])]
    tables = [simulate_poses(m, uniform_directions(60, k), 0.0) for k, m in enumerate(models)]
    fit = BatchedMaximumLikelihood().fit_many(tables)
    for k, m in enumerate(models):
        assert np.allclose(fit.theta[k], m.theta, atol=1e-8, rtol=0)


def test_batched_marks_the_unit_mle_refuses():
    model = lu2017_reference_model()
    good = simulate_poses(model, uniform_directions(24, 3), 0.002, rng=4)
    six = simulate_poses(model, np.repeat(six_position(), 4, axis=0), 0.002, rng=5)
    with pytest.raises(IdentifiabilityError):
        MaximumLikelihood().fit(six)
    fit = BatchedMaximumLikelihood().fit_many([good, six])
    assert fit.identifiable.tolist() == [True, False]


def test_the_cost_of_a_stack_is_the_sum_of_the_single_costs():
    """NormResidualCost with a leading axis of units: the separable sum, gradient stacked, Hessian blocks."""
    rng = np.random.default_rng(2)
    u = rng.standard_normal((3, 50, 3))
    w = rng.uniform(0.5, 2, (3, 50))
    scales = np.array([1.0, 2.0, 0.5])
    theta = np.tile(np.array([1.0, 0.01, 0.9, -0.02, 0.03, 1.1, 0.05, -0.1, 0.02]), 3) + 0.01 * rng.standard_normal(27)
    cost = NormResidualCost(u, w, scale=scales)
    _, g = cost.gradient(theta)
    H = cost.gauss_newton_hessian(theta)
    assert g.shape == (27,) and H.shape == (3, 9, 9)
    for k, c in enumerate(scales):
        one = NormResidualCost(u[k], w[k], scale=c)
        f1, g1 = one.gradient(theta[9 * k:9 * k + 9])
        assert np.allclose(g[9 * k:9 * k + 9], g1, rtol=1e-12, atol=1e-14)
        assert np.allclose(H[k], one.gauss_newton_hessian(theta[9 * k:9 * k + 9]), rtol=1e-12, atol=1e-14)
        assert np.allclose(cost.residuals(theta)[k], one.residuals(theta[9 * k:9 * k + 9]), rtol=0, atol=1e-15)
    assert cost.value(theta) == pytest.approx(sum(NormResidualCost(u[k], w[k], scale=c).value(theta[9 * k:9 * k + 9])
                                                  for k, c in enumerate(scales)), rel=1e-12)


def test_the_stacked_start_and_scale_are_the_single_ones():
    """convex_start and scaled_cost on a stack give each unit what they give it alone (the rules are written once)."""
    from optcal.families.accel.base import Normaliser
    from optcal.families.accel.mle import convex_start, scaled_cost

    tables = [t for t in _tables(4) if t.n == 120][:4]
    acc = np.stack([t.acc for t in tables])
    norm = Normaliser.of(acc)
    u = norm.forward(acc)
    theta = convex_start(u, 1e-3)
    w = np.random.default_rng(3).uniform(0.5, 2, (len(tables), 120))
    stacked = scaled_cost(u, w, theta)
    for k, t in enumerate(tables):
        single_norm = Normaliser.of(t.acc)
        np.testing.assert_array_equal(u[k], single_norm.forward(t.acc))
        np.testing.assert_allclose(theta[k], convex_start(u[k], 1e-3), rtol=1e-13, atol=1e-15)
        assert stacked.scale[k] == pytest.approx(scaled_cost(u[k], w[k], theta[k]).scale, rel=1e-13)


def test_validate_many_names_the_bad_table():
    tables = [t for t in _tables(3) if t.n == 120][:3]
    bad = tables[2].with_acc(tables[2].acc.copy())
    bad.acc[5] = np.nan
    with pytest.raises(InputError, match=r"tables\[2\].*NaN"):
        validate_many([tables[0], tables[1], bad])
    flat = PoseTable(acc=np.column_stack([np.cos(np.arange(12.0)), np.sin(np.arange(12.0)), np.zeros(12)]))
    with pytest.raises(InputError, match="one plane"):
        BatchedMaximumLikelihood().fit_many([flat])
