"""Issue 39 (gyro11): a gyro that does not see the moves is refused before the NLP, not after 180 IPOPT iterations.

The fit check's test 2 (:func:`optcal.families.gyro.consistency.signal_to_noise`) reads the bias-free raw rates and
the rests' noise only, so its refusal cannot depend on the fit.  Before, the NLP ran first: on the Xsens log with its
gyro replaced by noise it wandered a flat objective for 180 iterations (about 5 CPU s) to a fit test 2 then refused.
The accepted fits, and the fit kept with ``accept_gyro_fit``, still run the NLP and are unchanged.
"""

from __future__ import annotations

import numpy as np
import pytest

import optcal
from optcal.core.poses import PoseTable
from optcal.data.units import GyroUnitsDecision
from optcal.errors import InputError
from optcal.families.gyro import estimator
from optcal.families.gyro.estimator import GyroSettings, calibrate_gyro
from optcal.families.gyro.moves import moves_from_arrays
from optcal.families.simulate.gyro import ImuRecording, reference_gyro, simulate_imu

RAD_S = GyroUnitsDecision("rad/s", "test")


@pytest.fixture(scope="module")
def recording() -> ImuRecording:
    """24 poses, 23 moves of 1.5 s at 100 Hz, noisy accelerometer (2 mg) and gyro (0.005 rad/s per sample)."""
    return simulate_imu(optcal.lu2017_reference_model(), reference_gyro(1.0, rng=1), 24, rng=41,
                        dwell_s=2.0, move_s=1.5, acc_noise=0.002, gyro_noise=0.005)


class CountingProblems:
    """Stands in for :data:`estimator.GYRO_PROBLEMS`, counting the NLPs asked for."""

    def __init__(self) -> None:
        self.calls = 0
        self.real = estimator.GYRO_PROBLEMS

    def get(self, *args: object):
        self.calls += 1
        return self.real.get(*args)


def fit(rec: ImuRecording, gyro: np.ndarray, **settings: object):
    moves = moves_from_arrays(rec.t, rec.acc, gyro, rec.intervals)
    accelerometer = optcal.calibrate(PoseTable(acc=moves.acc_means, sigma=moves.acc_sigma))
    return calibrate_gyro(moves, accelerometer, RAD_S, GyroSettings(**settings))


def test_noise_gyro_refused_without_the_nlp(recording: ImuRecording, monkeypatch) -> None:
    problems = CountingProblems()
    monkeypatch.setattr(estimator, "GYRO_PROBLEMS", problems)
    noise = np.random.default_rng(0).normal(0.0, 0.005, recording.gyro.shape)
    with pytest.raises(InputError, match=r"^the gyro calibration cannot be right: the gyro does not see the moves "
                       r"\(their rotation is [01]\.\d+× .*refused before the fit.*accept_gyro_fit=True"):
        fit(recording, noise)
    assert problems.calls == 0
    kept = fit(recording, noise, accept_gyro_fit=True)  # the override still fits, and its check still runs
    assert problems.calls == 1
    assert kept.fit_check["refused"] and "the gyro does not see the moves" in kept.fit_check["findings"][0]


def test_a_gyro_that_sees_the_moves_is_fitted_as_before(recording: ImuRecording, monkeypatch) -> None:
    problems = CountingProblems()
    monkeypatch.setattr(estimator, "GYRO_PROBLEMS", problems)
    cal = fit(recording, recording.gyro)
    assert problems.calls == 1 and not cal.fit_check["refused"]
    kept = fit(recording, recording.gyro, accept_gyro_fit=True)  # the early test decides nothing here
    np.testing.assert_array_equal(kept.params, cal.params)
