"""The noise model as a named explanation: correlated pose noise is named, never as a physical effect.

Raw 100 Hz recordings in counts from :func:`optcal.families.simulate.effects.recording_with_effect` with a
Gauss–Markov noise component (1 mg, 4 s correlation time: the time scale of a 4 s dwell); the
truth (no effect, or one effect) is hidden from the diagnosis.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from optcal.data import load
from optcal.applications.diagnosis import diagnose
from optcal.families.simulate.effects import recording_with_effect
from optcal.report.diagnosis_text import diagnosis_report


def poses_of(tmp_path: Path, effect: str | None, gauss_markov_g: float, seed: int):
    frame, truth = recording_with_effect(effect, gauss_markov_g=gauss_markov_g, correlation_s=4.0, seed=seed)
    path = tmp_path / "rec.csv"
    frame.to_csv(path, index=False, float_format="%.6f")
    return load(path), truth


def test_correlated_noise_is_named_and_the_extension_calibrates_chi2_and_standard_errors(tmp_path: Path) -> None:
    poses, _ = poses_of(tmp_path, None, 1e-3, seed=0)
    diag = diagnose(poses, simulations=60)
    check = diag.noise_model
    assert diag.findings == []  # never a physical effect
    assert check.named and check.reduced_chi2 > 3 and check.understated_by > 1.5
    assert 0.7 <= check.reduced_chi2_after <= 1.5
    assert abs(check.coverage_extended - 0.95) <= 0.05 < 0.95 - check.coverage_given_sigma
    report = diagnosis_report(diag)
    assert "the simulation's noise model is wrong" in report and "none named" in report and "not ruled out" in report
    assert diag.to_dict()["noise_model"]["named"] is True


@pytest.mark.parametrize("seed", [1, 2])
def test_white_noise_does_not_name_the_noise_model(tmp_path: Path, seed: int) -> None:
    poses, _ = poses_of(tmp_path, None, 0.0, seed)
    diag = diagnose(poses, simulations=0)
    assert not diag.noise_model.named and diag.findings == []


def test_correlated_noise_does_not_hide_a_real_effect(tmp_path: Path) -> None:
    poses, truth = poses_of(tmp_path, "temperature_bias", 1e-3, seed=1)
    diag = diagnose(poses, simulations=0)
    assert [f.effect for f in diag.findings] == ["temperature_bias"] and diag.findings[0].axes == [truth.axis]
    assert diag.findings[0].estimate[truth.axis] == pytest.approx(truth.value, rel=0.3)
    assert diag.noise_model.named
