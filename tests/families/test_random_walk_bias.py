"""The random-walk bias (issue 13, item 2): a bias wandering in time, fitted jointly with T and o by ML."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from optcal.errors import InputError
from optcal.families.accel.mle import MaximumLikelihood
from optcal.families.accel.random_walk_bias import RandomWalkBias, _brownian_covariance, brownian_states
from optcal.core.model import lu2017_reference_model, theta_from, unpack_theta
from optcal.core.norm_residual import norm_residuals
from optcal.core.poses import PoseTable
from optcal.families.simulate.poses import uniform_directions
from optcal.report.diagnosis_text import diagnosis_report

MODEL = lu2017_reference_model()
TRUE_THETA = theta_from(MODEL.T_canonical, MODEL.o)
SIGMA = 1e-3


def _session(K: float, seed: int, n: int = 60, dt: float = 10.0) -> tuple[PoseTable, np.ndarray]:
    """``n`` poses ``dt`` s apart whose bias walks with intensity ``K`` (raw units per √s), white noise ``SIGMA``."""
    rng = np.random.default_rng(seed)
    steps = rng.standard_normal((n, 3)) * K * np.sqrt(dt)
    steps[0] = 0.0
    walk = np.cumsum(steps, axis=0)
    acc = MODEL.measure(uniform_directions(n, rng)) + walk + SIGMA * rng.standard_normal((n, 3))
    return PoseTable(acc=acc, t=np.arange(n) * dt, sigma=np.full(n, SIGMA)), walk


def test_brownian_covariance_restarts_in_each_session():
    B = _brownian_covariance(np.array([0.0, 2.0, 5.0, 100.0, 103.0]), np.array([0, 0, 0, 1, 1]))
    assert B[1, 2] == 2.0 and B[2, 2] == 5.0 and B[0, 0] == 0.0
    assert B[3, 4] == 0.0 and B[4, 4] == 3.0 and B[0, 4] == 0.0


def test_poses_at_the_same_time_share_the_walk_and_the_session_start_sees_none():
    t = np.array([5.0, 0.0, 2.0, 2.0, 100.0, 100.0, 103.0])
    session = np.array([0, 0, 0, 0, 1, 1, 1])
    state, chain = brownian_states(t, session)
    assert state[1] == -1 and state[4] == -1 and state[5] == -1  # each session's start: the walk is 0 there
    assert state[2] == state[3] >= 0 and len({state[0], state[2], state[6]}) == 3
    assert chain.size == 3 and np.array_equal(chain.phi, [1.0, 0.0])  # restarts in the second session
    elapsed = t - np.where(session == 0, 0.0, 100.0)
    dense = np.where(session[:, None] == session[None, :], np.minimum(elapsed[:, None], elapsed[None, :]), 0.0)
    assert np.array_equal(_brownian_covariance(t, session), dense)


def _dense_profile(poses: PoseTable, theta: np.ndarray, lam: float, s2: float) -> tuple[float, np.ndarray]:
    """−2 log L (s² fixed) and the smoothed walk at ``(θ, λ)`` written densely from the model's definition."""
    from optcal.core.norm_residual import NormResidualKernel

    point = NormResidualKernel(poses.acc).at_theta(theta)
    H = point.bias_jacobian()
    B = _brownian_covariance(poses.t, np.zeros(poses.n, dtype=int))
    V = lam * (H.T @ H) * B + np.diag((poses.sigma * point.normal_gain()) ** 2)
    r = point.residuals
    alpha = np.linalg.solve(V, r)
    m2ll = float(r @ alpha) / s2 + poses.n * np.log(s2) + np.linalg.slogdet(V)[1]
    return m2ll, -(lam * B) @ (H.T * alpha[:, None])


def test_the_linear_time_likelihood_and_smoother_equal_the_dense_definition():
    """Reference: the O(n) Kalman-form likelihood and smoothed walk against V = W⁻¹ + λ(HHᵀ∘B) built densely."""
    for seed in range(3):
        poses, _ = _session(1e-3, seed, n=50)
        fit = RandomWalkBias(noise_scale=1.0).fit(poses, MaximumLikelihood().fit(poses).params[:9])
        m2ll, track = _dense_profile(poses, fit.theta, fit.q, 1.0)
        assert -0.5 * m2ll == pytest.approx(fit.log_likelihood, rel=1e-10, abs=1e-8)
        assert np.max(np.abs(track - fit.bias_track)) < 1e-8 * np.max(np.abs(track))


def test_a_walk_is_fitted_and_checked_on_thousands_of_poses():
    """No pose cap any more: 3,000 poses 2 s apart, a walk of 1e-4 raw/√s (the dense form was O(n³))."""
    from optcal.applications.diagnosis.random_walk import check_random_walk

    poses, _ = _session(1e-4, 11, n=3000, dt=2.0)
    ml = MaximumLikelihood().fit(poses)
    check = check_random_walk(poses, *unpack_theta(ml.params[:9]), None, 0.01, None)
    true_K_g = 1e-4 * np.mean(np.abs(np.diag(MODEL.T_canonical)))
    assert check.tested and check.named and check.heldout_rms_walk_g < check.heldout_rms_white_g
    assert check.K_interval_g[0] <= true_K_g <= check.K_interval_g[1]


def test_without_a_walk_the_fit_is_the_white_noise_ml_and_q_is_not_supported():
    """Cross-method: with q = 0 the generalised fit is the white-noise ML fit; the boundary LR test stays quiet."""
    quiet = 0
    for seed in range(10):
        poses, _ = _session(0.0, seed)
        ml = MaximumLikelihood().fit(poses)
        fit = RandomWalkBias(noise_scale=1.0).fit(poses, ml.params[:9])
        quiet += fit.p_value > 0.05
        if fit.q == 0.0:
            assert np.max(np.abs(fit.theta - ml.params[:9])) < 1e-6  # ML's IPOPT tolerance: measured ≤ 8.2e-8
    assert quiet >= 9  # 95 % nominal; 10 seeds


def test_a_planted_walk_is_recovered_within_its_interval_and_improves_the_calibration():
    covered, better, tracks = 0, 0, []
    K = 1e-3
    for seed in range(10):
        poses, walk = _session(K, seed)
        ml = MaximumLikelihood().fit(poses)
        fit = RandomWalkBias(noise_scale=1.0).fit(poses, ml.params[:9])
        assert fit.p_value < 1e-6
        covered += fit.K_interval[0] <= K <= fit.K_interval[1]
        better += np.max(np.abs(fit.theta - TRUE_THETA)) < np.max(np.abs(ml.params[:9] - TRUE_THETA))
        # the smoothed track follows the planted walk (its band is conditional on θ̂: see the field's docs)
        tracks.append(np.corrcoef(fit.bias_track.ravel(), walk.ravel())[0, 1])
    assert covered >= 8  # 95 % profile-likelihood interval, 10 seeds (20-seed run: 18/20)
    assert better >= 8
    assert np.median(tracks) > 0.8


def test_heldout_poses_are_predicted_better_with_the_walk():
    poses, _ = _session(1e-3, 3, n=80)
    keep = np.arange(80) % 5 != 2
    train = PoseTable(acc=poses.acc[keep], t=poses.t[keep], sigma=poses.sigma[keep])
    test = PoseTable(acc=poses.acc[~keep], t=poses.t[~keep], sigma=poses.sigma[~keep])
    ml = MaximumLikelihood().fit(train)
    rw = RandomWalkBias(noise_scale=1.0)
    fit = rw.fit(train, ml.params[:9])
    walk_rms = np.sqrt(np.mean(rw.predict_heldout(train, test, fit) ** 2))
    T, o = unpack_theta(ml.params[:9])
    white_rms = np.sqrt(np.mean(norm_residuals(T, o, test.acc) ** 2))
    assert fit.q > 0
    assert walk_rms < 0.5 * white_rms


def test_the_still_parts_allan_deviation_bounds_and_resolves_the_rate_random_walk():
    """The Allan side of the comparison: the bound ``K ≤ σ(τ)√(3/τ)`` on the analytic curve, and a rate
    random walk resolved on a long still stretch (white 0.05 mg·√s, K = 0.01 mg/√s, 20 min at 100 Hz)."""
    from optcal.applications.diagnosis.random_walk import compare_with_allan
    from optcal.applications.diagnosis.still_noise import MeasuredPoseNoise
    from optcal.families.noise.allan import NoiseParameters, allan_deviation, rate_random_walk_bound, simulate_noise

    taus = 2.0 ** np.arange(-6, 8)
    params = NoiseParameters(5e-5, 0.0, 1e-5, {}, True, 0.0, 1.0)
    bound, at = rate_random_walk_bound(taus, params.model_adev(taus))
    assert at == taus[-1] and bound == pytest.approx(np.sqrt(3 * 5e-5**2 / taus[-1] ** 2 + 1e-5**2), rel=1e-12)
    rng = np.random.default_rng(2)
    samples = np.column_stack([simulate_noise(120_000, 100.0, 5e-5, 0.0, 1e-5, rng) for _ in range(3)])
    curves = [allan_deviation(samples[:, axis], 100.0) for axis in range(3)]
    adev = np.sqrt(np.mean([c.adev**2 for c in curves], axis=0))
    still = MeasuredPoseNoise(None, "a long still stretch", 1200.0, curves[0].taus, adev, curves)
    agree = compare_with_allan(still, 1.1e-5, (0.7e-5, 1.6e-5), 1.0)
    assert agree.K_allan_g is not None and agree.consistent
    assert agree.K_allan_interval_g[0] <= 1e-5 <= agree.K_allan_interval_g[1]
    assert not compare_with_allan(still, 1e-4, (0.7e-4, 1.6e-4), 1.0).consistent
    bound_only = compare_with_allan(MeasuredPoseNoise(None, "pooled", 4.0, curves[0].taus[:6], adev[:6]),
                                    1e-5, (0.7e-5, 1.6e-5), 1.0)
    assert bound_only.K_allan_g is None and bound_only.consistent and bound_only.K_bound_g >= 1e-5


def test_refusals():
    poses, _ = _session(0.0, 0)
    with pytest.raises(InputError, match="times"):
        RandomWalkBias().fit(PoseTable(acc=poses.acc), TRUE_THETA)
    with pytest.raises(InputError, match="noise_scale"):
        RandomWalkBias(noise_scale=0.0)


@pytest.fixture(scope="module")
def walking_diagnosis() -> tuple[PoseTable, Any]:
    """40 poses whose bias walks at 1e-3 raw/√s and their diagnosis (no simulations), read by two tests (speed
    only: one diagnosis per test process instead of one per test)."""
    from optcal.applications.diagnosis import diagnose

    walking, _ = _session(1e-3, 7, n=40)
    return walking, diagnose(walking, simulations=0)


def test_diagnose_names_a_wandering_bias_as_noise_and_not_on_white_sessions(walking_diagnosis):
    """The diagnosis tests the walk in its noise section (never a finding) and names it only when it is there."""
    from optcal.applications.diagnosis import diagnose

    _, d = walking_diagnosis
    check = d.noise_model.random_walk
    assert check.tested and check.named and check.p_value < 1e-3
    assert check.heldout_rms_walk_g < check.heldout_rms_white_g
    true_K_g = 1e-3 * np.mean(np.abs(np.diag(MODEL.T_canonical)))  # raw units → g, as the check converts
    assert check.K_interval_g[0] <= true_K_g <= check.K_interval_g[1]
    assert "random-walk bias" in diagnosis_report(d) and "named cause: the bias wanders" in diagnosis_report(d)
    assert d.to_dict()["noise_model"]["random_walk"]["named"] is True
    quiet, _ = _session(0.0, 8, n=40)
    check = diagnose(quiet, simulations=0).noise_model.random_walk
    assert check.tested and not check.named


def test_a_walk_planted_in_the_xsens_recording_is_named_and_measured(shared_data):
    """../shared/data/imutk-xsens (38 hand-held poses over 477 s): a planted random walk of 0.05 mg/√s is named.

    Tested about the final model (the log's own rise-and-fall z bias taken out first).  Ten planted walks
    (seeds 0-9): named 10/10, K estimated 0.028-0.051 mg/√s (median 0.038: the selection's time terms take a
    share of a walk first), its 95 % interval covering 0.05 in 7/10, held-out rms cut by > 20 % in 8/10.
    """
    from optcal.data import load_with_segmentation
    from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings

    loaded = load_with_segmentation(shared_data / "imutk-xsens" / "xsens_imutk.csv")
    poses = loaded.poses
    settings = DiagnosisSettings(simulations=0)
    plain_diagnosis = Diagnoser(settings).run(poses, still_parts=loaded.segmentation)
    plain = plain_diagnosis.noise_model.random_walk
    assert plain.tested and plain.noise_scale_source == "measured on the still parts"
    K_g = 5e-5
    # the still parts set the noise's scale, not the fit: T equals the poses-only diagnosis's bit for bit on this log
    T = plain_diagnosis.model.base.T_canonical
    counts_per_g = 1.0 / np.mean(np.abs(np.diag(T)))
    rng = np.random.default_rng(13)
    dt = np.diff(poses.t, prepend=poses.t[0])
    walk = np.cumsum(rng.standard_normal((poses.n, 3)) * (K_g * counts_per_g) * np.sqrt(dt)[:, None], axis=0)
    planted = Diagnoser(settings).run(poses.with_acc(poses.acc + walk), still_parts=loaded.segmentation)
    check = planted.noise_model.random_walk
    assert check.named
    assert 0.5 * K_g <= check.K_g <= 2 * K_g
    assert check.heldout_rms_walk_g < 0.9 * check.heldout_rms_white_g
    # compared with the still parts' Allan deviation (38 intervals pooled, τ ≤ 20.5 s, no +½ slope): the log's
    # own small K (0.0049 mg/√s) is within the bound it sets (0.012 mg/√s); the walk planted between the poses
    # is not in the samples, so the still parts rule it out
    for walk_check, consistent in ((plain, True), (check, False)):
        allan = walk_check.allan
        assert allan is not None and allan.K_allan_g is None and allan.consistent is consistent
        assert 0.005e-3 < allan.K_bound_g < 0.05e-3
        # the log's own K would rise above the curve only beyond its longest τ; the planted one well within it
        assert (allan.tau_needed_s > allan.tau_max_s) is consistent
    assert "bounds it at K ≤" in plain.text() and "several times that long" in plain.text()
    assert "not the sensor's noise" in check.text() and "would show in it" in check.text()
    assert planted.to_dict()["noise_model"]["random_walk"]["allan"]["consistent"] is False


def test_the_saved_calibration_carries_the_walk_and_round_trips(tmp_path, walking_diagnosis):
    """diagnose -o: a named walk is not applicable to a later recording; it is saved as the bias's uncertainty (format 2.2)."""
    from optcal.families.calibration_files import load as load_calibration
    from optcal.families.caltypes.extended import ExtendedCalibration

    walking, d = walking_diagnosis
    cal = d.calibration()
    assert isinstance(cal, ExtendedCalibration) and cal.format_version == "2.2"
    assert cal.bias_random_walk.K_g_per_sqrt_s == pytest.approx(d.noise_model.random_walk.K_g)
    assert "random walk" in cal.describe()
    path = tmp_path / "cal.json"
    cal.save(path)
    again = load_calibration(path)
    assert again.bias_random_walk == cal.bias_random_walk
    assert np.allclose(again.correct(walking.acc, t=walking.t), cal.correct(walking.acc, t=walking.t), atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.integers(0, 6)), min_size=1, max_size=25))
def test_the_walk_s_states_give_the_brownian_covariance_for_any_times_sessions_and_ties(rows):
    """Property: whatever the order, ties and sessions, the chain's covariance is ``min(t_k, t_j) − t_0`` per session."""
    session = np.array([s for s, _ in rows])
    t = np.array([float(v) * 1.5 for _, v in rows])
    start = np.array([t[session == s].min() for s in session])
    elapsed = t - start
    dense = np.where(session[:, None] == session[None, :], np.minimum(elapsed[:, None], elapsed[None, :]), 0.0)
    assert np.allclose(_brownian_covariance(t, session), dense, rtol=0, atol=1e-9)


def test_heldout_prediction_equals_the_dense_conditional_mean_also_before_the_first_training_pose():
    """E[h·b(t_h) | r_train] from the chain (held-out states seen by no residual) against the dense Gaussian
    conditional; the first pose in time is held out, so the walk starts at a held-out pose."""
    from optcal.core.norm_residual import NormResidualKernel

    poses, _ = _session(1e-3, 5, n=40)
    held = np.arange(40) % 4 == 0  # pose 0 (the session's start) is held out
    train, test = poses.subset(np.flatnonzero(~held)), poses.subset(np.flatnonzero(held))
    rw = RandomWalkBias(noise_scale=1.0)
    fit = rw.fit(train, MaximumLikelihood().fit(train).params[:9], interval=False)
    assert fit.q > 0 and np.isnan(fit.K_interval[0])
    predicted = rw.predict_heldout(train, test, fit)
    p_tr = NormResidualKernel(train.acc).at_theta(fit.theta)
    p_te = NormResidualKernel(test.acc).at_theta(fit.theta)
    n = train.n
    B = _brownian_covariance(np.concatenate([train.t, test.t]), np.zeros(40, dtype=int))
    H_tr, H_te = p_tr.bias_jacobian(), p_te.bias_jacobian()
    lam = fit.q / fit.noise_scale**2
    V = lam * (H_tr.T @ H_tr) * B[:n, :n] + np.diag((train.sigma * p_tr.normal_gain()) ** 2)
    dense = p_te.residuals - (lam * (H_te.T @ H_tr) * B[n:, :n]) @ np.linalg.solve(V, p_tr.residuals)
    assert np.allclose(predicted, dense, rtol=0, atol=1e-12)  # g
    assert predicted[0] == pytest.approx(p_te.residuals[0], abs=1e-15)  # the walk is 0 at the start


def test_a_fold_s_search_from_the_session_s_lowest_lambda_finds_what_the_whole_grid_finds(shared_data):
    """The held-out folds walk the λ grid downhill from the whole session's lowest point (``near``) instead of
    evaluating all 25 points: on ../shared/data/imutk-xsens (38 poses), as recorded and with a walk of
    0.05 mg/√s planted, every fold's estimate equals the whole grid's (the reference) to the bounded
    minimisation's tolerance (1e-4 in log10 λ, so ≤ 2.3e-4 relative in q; measured ≤ 5e-8)."""
    from optcal.data import load_with_segmentation

    poses = load_with_segmentation(shared_data / "imutk-xsens" / "xsens_imutk.csv").poses
    T, _ = unpack_theta(MaximumLikelihood().fit(poses).params[:9])
    dt = np.diff(poses.t, prepend=poses.t[0])
    walk = np.cumsum(np.random.default_rng(13).standard_normal((poses.n, 3)) * np.sqrt(dt)[:, None], axis=0)
    fold_of = np.empty(poses.n, dtype=int)
    fold_of[np.argsort(poses.t, kind="stable")] = np.arange(poses.n) % 5  # check_random_walk's folds
    rw = RandomWalkBias(noise_scale=1.0)
    walks = 0
    for planted in (0.0, 5e-5 / np.mean(np.abs(np.diag(T)))):  # K in raw units per √s
        session = poses.with_acc(poses.acc + planted * walk)
        theta0 = MaximumLikelihood().fit(session).params[:9]
        whole = rw.fit(session, theta0, interval=False)
        for k in range(5):
            train = session.subset(np.flatnonzero(fold_of != k))
            reference = rw.fit(train, theta0, interval=False)
            fast = rw.fit(train, theta0, interval=False, near=whole.lam_lowest)
            walks += reference.q > 0
            assert (fast.q > 0) == (reference.q > 0)
            assert fast.q == pytest.approx(reference.q, rel=2.3e-4)
            assert fast.log_likelihood == pytest.approx(reference.log_likelihood, rel=0, abs=1e-6)
            assert np.max(np.abs(fast.theta - reference.theta)) < 1e-6 * np.max(np.abs(reference.theta))
            assert np.array_equal(fast.theta_white, rw.white_fit(train, theta0))
    assert walks >= 5  # the planted walk is fitted in every fold: the bounded minimisation's bracket is compared
