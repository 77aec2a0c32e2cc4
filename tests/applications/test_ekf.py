"""The extended Kalman filter of Yin 2014 (eqs. 7-13)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from optcal.applications.papers.yin2014.ekf import YinEKF, sum_squared_errors
from optcal.errors import InputError
from optcal.core.model import lumped_matrix
from optcal.core.rotations import gravity_direction, roll_pitch
from optcal.families.noise.allan import simulate_noise
from optcal.families.noise.analysis import analyse_static_log

RATE = 100.0
C = lumped_matrix((1.02, 0.97, 1.03), *np.radians((0.5, 0.3, 0.4)))
O = np.array([0.03, -0.02, 0.05])
W = np.linalg.inv(C)
V = -W @ O
N, B, K = 200e-6, 100e-6, 10e-6


def still_log(roll: float, pitch: float, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    f = gravity_direction(roll, pitch)
    noise = np.column_stack([simulate_noise(n, RATE, N, B, K, rng) for _ in range(3)])
    return C @ f + O + noise, f


def make_filter(**settings: float) -> YinEKF:
    return YinEKF(W, V, RATE, [N] * 3, [B] * 3, [K] * 3, correlation_time_s=200.0, **settings)


@pytest.mark.parametrize("roll, pitch", [(0.3, -0.2), (math.pi, 0.1), (1.2, 0.4)])
def test_roll_pitch_inverts_the_gravity_direction(roll: float, pitch: float) -> None:
    r, p = roll_pitch(gravity_direction(roll, pitch))
    np.testing.assert_allclose(gravity_direction(r, p), gravity_direction(roll, pitch), atol=1e-15)


def test_measurement_jacobian_matches_finite_differences() -> None:
    ekf = make_filter()
    x = np.array([0.4, -0.3, 1e-3, -2e-3, 5e-4])
    _, H = ekf.measurement_model(x)
    step = 1e-7
    numeric = np.column_stack(
        [(ekf.measurement_model(x + step * e)[0] - ekf.measurement_model(x - step * e)[0]) / (2 * step) for e in np.eye(5)]
    )
    np.testing.assert_allclose(H, numeric, atol=1e-8)


def test_process_noise_follows_the_noise_parameters() -> None:
    A, Q = make_filter(attitude_random_walk=2e-4).transition()
    beta = math.exp(-1 / RATE / 200.0)
    np.testing.assert_allclose(np.diag(A), [1, 1, beta, beta, beta])
    np.testing.assert_allclose(np.diag(Q)[:2], (2e-4) ** 2 / RATE)
    np.testing.assert_allclose(np.diag(Q)[2:], B**2 * (1 - beta**2) + K**2 / RATE)
    np.testing.assert_allclose(np.diag(make_filter().measurement_noise()), N**2 * RATE)


def test_noise_free_input_converges_to_the_truth() -> None:
    f = gravity_direction(0.25, -0.15)
    raw = np.tile(C @ f + O, (3000, 1))
    out = make_filter().run(raw)
    np.testing.assert_allclose(out.compensated[-1], f, atol=1e-9)
    np.testing.assert_allclose(out.bias[-1], 0, atol=1e-9)


def test_filter_reduces_the_sum_of_squared_errors_on_every_axis() -> None:
    # Table 4 analogue: raw > calibrated (W, V) > EKF, per axis, on a still sensor with known truth
    rng = np.random.default_rng(44)
    raw, f = still_log(0.3, -0.2, 20_000, rng)
    out = make_filter().run(raw)
    sse_raw = sum_squared_errors(raw, f)
    sse_cal = sum_squared_errors(raw @ W.T + V, f)
    sse_ekf = sum_squared_errors(out.compensated, f)
    assert np.all(sse_raw > sse_cal) and np.all(sse_cal > 10 * sse_ekf)
    # attitude variance converges (Yin 2014, Fig. 3)
    assert np.all(out.attitude_variance[-1] < out.attitude_variance[0] / 100)
    assert np.all(np.abs(np.diff(out.attitude_variance[-100:], axis=0)) < 1e-3 * out.attitude_variance[-1])



def test_logs_filtered_side_by_side_equal_each_filtered_alone() -> None:
    # run_many (speed only: the reproduction's six poses in one pass) is run() on each log, in the logs' order,
    # logs of one length stacked, a log of another length alone; a NaN in a stacked log is refused as run() refuses it
    rng = np.random.default_rng(7)
    logs = [still_log(r, p, n, rng)[0] for r, p, n in ((0.3, -0.2, 800), (2.0, 0.4, 800), (-1.0, 0.1, 300),
                                                         (0.0, 1.2, 800))]
    ekf = make_filter()
    for log, out in zip(logs, ekf.run_many(logs), strict=True):
        alone = ekf.run(log)
        for field in ("compensated", "attitude", "bias", "attitude_variance"):
            np.testing.assert_allclose(getattr(out, field), getattr(alone, field), rtol=1e-12, atol=1e-15)
    bad = [logs[0], logs[1].copy()]
    bad[1][5, 2] = np.nan
    with pytest.raises(InputError, match="NaN"):
        ekf.run_many(bad)

def test_filter_built_from_an_allan_analysis() -> None:
    rng = np.random.default_rng(45)
    noise = np.column_stack([simulate_noise(200_000, RATE, N, B, K, rng) for _ in range(3)])
    analysis = analyse_static_log(noise, RATE, "g")
    ekf = YinEKF.from_noise(W, V, RATE, analysis.parameters)
    np.testing.assert_allclose(ekf.N, N, rtol=0.05)
    assert ekf.correlation_time_s == pytest.approx(np.median([p.correlation_time_s for p in analysis.parameters.values()]))
    raw, f = still_log(-0.4, 0.1, 5_000, rng)
    assert np.all(sum_squared_errors(ekf.run(raw).compensated, f) < sum_squared_errors(raw @ W.T + V, f))


def test_sum_of_squared_errors_broadcasts_a_static_truth() -> None:
    est = np.array([[1.0, 2.0, 3.0], [2.0, 2.0, 5.0]])
    np.testing.assert_allclose(sum_squared_errors(est, [1.0, 1.0, 3.0]), [1.0, 2.0, 4.0])


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: YinEKF(np.zeros((3, 3)), V, RATE, [N] * 3, [B] * 3), "invertible"),
        (lambda: YinEKF(W, V, RATE, [0.0, N, N], [B] * 3), "velocity random walk positive"),
        (lambda: YinEKF(W, V, -1.0, [N] * 3, [B] * 3), "positive"),
        (lambda: make_filter().run(np.zeros((10, 2))), "shape"),
        (lambda: make_filter().run(np.full((10, 3), np.nan)), "NaN"),
    ],
)
def test_bad_input_is_refused(build, message: str) -> None:
    with pytest.raises(InputError, match=message):
        build()
