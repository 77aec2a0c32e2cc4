"""Outliers tested against the final model with its effects (issue 39): a rest set aside beside a drift.

IMU-TK's real Xsens log with a bias drift planted on x: the rest the drift moves most is an outlier of the paper's
model (its deleted residual significant at the family-wise level), and not one of the model with the drift.
Selection started with that rest set aside (as a step taken before the drift entered leaves it) names the drift
and returns the rest to the fit: the backward check after the drift's entry tests it by its deleted residual at the
outliers' level and lists it in ``dropped``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.applications.diagnosis.outliers import deleted_residual_p
from optcal.applications.diagnosis.selection import ForwardSelection

from tests.applications.test_diagnosis_real import planted_xsens

ALPHA = 0.01  # the outlier test's share of the default family-wise level 0.02


def drift_and_its_outlier(shared_data: Path, tmp_path: Path):
    """The Xsens log with an x drift planted: its poses, fitter, the paper's model's fit and that fit's largest
    weighted residual (the rest the drift moves most)."""
    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    if not path.exists():
        pytest.skip("imutk-xsens recording absent")
    poses = planted_xsens(tmp_path, path, "bias_drift", 0, 1.2e-5, "drift")
    fitter, _ = Diagnoser(DiagnosisSettings(simulations=0)).prepare(poses)
    plain = fitter.fit({})
    return poses, fitter, plain, int(np.argmax(np.sqrt(fitter.w) * np.abs(plain.residuals)))


def test_a_rest_set_aside_before_the_drift_entered_is_returned(shared_data: Path, tmp_path: Path) -> None:
    poses, fitter, plain, k = drift_and_its_outlier(shared_data, tmp_path)
    assert deleted_residual_p(fitter, plain, frozenset({k}), plain.x)[k] < ALPHA  # an outlier of the paper's model
    notes: list[str] = []
    start = fitter.fit({}, frozenset({k}), plain.x)
    result = ForwardSelection(fitter, [("bias_drift", a) for a in range(3)], True, 2 * ALPHA, notes.append).run(start)
    assert ("bias_drift", 0) in result.final.terms
    assert k not in result.final.outliers
    # returned by the backward check once the drift entered: listed with its test, level and held-out check
    returned = [d for d in result.dropped if d.effect == "outliers"]
    assert [d.rows for d in returned] == [(int(poses.rows[k]),)] and "bias_drift(x" in returned[0].after
    assert returned[0].p_value >= returned[0].level == ALPHA or returned[0].delta_bic >= 0
    assert returned[0].heldout_rms_g_without <= returned[0].heldout_rms_g_with
