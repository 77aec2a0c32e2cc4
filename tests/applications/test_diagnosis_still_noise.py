"""The noise model's measured route: the noise of a pose mean from the recording's own still parts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers.diagnosis_cases import make_case

from optcal.data import load_with_segmentation
from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.applications.diagnosis.still_noise import mean_noise_at, pose_noise_from_still_parts
from optcal.families.simulate.effects import recording_with_effect
from optcal.report.diagnosis_text import diagnosis_report

SETTINGS = DiagnosisSettings(simulations=10)
#: No simulation check where only the selection and the noise test matter.
NO_SIMULATION = DiagnosisSettings(simulations=0)


def raw(tmp_path: Path, effect: str | None, gauss_markov_g: float, seed: int, axis: str | None = None):
    frame, truth = recording_with_effect(effect, axis, n_poses=30, dwell_s=10.0, gauss_markov_g=gauss_markov_g,
                                         correlation_s=4.0, seed=seed)
    path = tmp_path / "rec.csv"
    frame.to_csv(path, index=False)
    return load_with_segmentation(path), truth


def test_white_noise_is_measured_as_sigma_over_root_n() -> None:
    taus = np.array([0.01, 0.02, 0.04, 0.08])
    adev = 1e-3 / np.sqrt(taus / 0.01)
    # inside the curve: interpolated; beyond it: the white-noise slope continued
    np.testing.assert_allclose(mean_noise_at(taus, adev, np.array([0.03, 0.64])), 1e-3 / np.sqrt([3.0, 64.0]),
                               rtol=1e-12)
    # a rising curve (noise correlated beyond the curve) is held at its last value, never raised
    assert mean_noise_at(taus, adev[::-1].copy(), np.array([1.0]))[0] == pytest.approx(adev[0])


def test_correlated_noise_is_measured_and_named_never_as_a_physical_effect(tmp_path: Path) -> None:
    loaded, _ = raw(tmp_path, None, 1.5e-3, seed=5)
    diag = Diagnoser(SETTINGS).run(loaded.poses, still_parts=loaded.segmentation)
    check = diag.noise_model
    assert diag.findings == [] and check.named  # the noise model is the cause, not an effect
    assert "still intervals" in check.measured_route or "still stretch" in check.measured_route
    # measured and residual-estimated understatement agree within 30 %; the refit with the measured σ fits
    assert check.measured_understated_by == pytest.approx(check.understated_by, rel=0.3)
    assert check.measured_understated_by > 1.8
    assert 0.7 <= check.reduced_chi2_measured <= 1.5
    assert check.coverage_measured is not None and check.coverage_measured > check.coverage_given_sigma
    text = diagnosis_report(diag)
    assert "measured route" in text and "residual-estimated" in text
    assert diag.to_dict()["noise_model"]["measured_understated_by"] == pytest.approx(check.measured_understated_by)


def test_white_noise_recording_measures_no_understatement(tmp_path: Path) -> None:
    loaded, _ = raw(tmp_path, None, 0.0, seed=6)
    measured = pose_noise_from_still_parts(loaded.poses, loaded.segmentation)
    assert measured.sigma is not None
    assert np.median(measured.sigma / loaded.poses.sigma) == pytest.approx(1.0, abs=0.2)


def test_the_noise_model_does_not_hide_a_real_effect(tmp_path: Path) -> None:
    loaded, truth = raw(tmp_path, "temperature_bias", 1.5e-3, seed=7, axis="y")
    diag = Diagnoser(NO_SIMULATION).run(loaded.poses, still_parts=loaded.segmentation)
    found = diag.finding("temperature_bias")
    assert found is not None and found.axes == ["y"]
    assert found.estimate["y"] == pytest.approx(truth.value, rel=0.3)
    assert diag.noise_model.named and diag.noise_model.measured_understated_by > 1.5


def test_a_pose_table_has_only_the_residual_route() -> None:
    diag = Diagnoser(DiagnosisSettings(simulations=0)).run(make_case(None, 9, n_range=(30, 30)).poses)
    assert "only estimated from the residuals" in diag.noise_model.measured_route
    assert diag.noise_model.measured_understated_by is None
