"""Outlier poses that one systematic effect explains are that effect's evidence, not outliers (issue 39).

A scale nonlinearity on two axes moves the rests along those axes most (the norm residual sees ``β a_i² u_i``).  In
20 rests of IMU-TK's real Xsens log with 8 mg/g² planted on x and on z, each term alone is masked by the other, and
before the acceptance tried the step's terms as the outliers' explanation the robust fit named four of those rests
as outliers and nothing else (their ΔBIC beat every single term).  The two nonlinearities searched together at their
own level leave no outlier pose under their fit, with two coefficients for four poses
(:func:`~optcal.applications.diagnosis.acceptance.prefer_terms_to_outliers`), so they are named.  A knocked rest that
no candidate explains with fewer coefficients than its poses stays an outlier (tests/applications/
test_diagnosis_knock.py), and so does a quarter of a session off (test_diagnosis_outliers.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.core.extended_model import ExtendedModel
from optcal.core.poses import PoseTable

from tests.applications.test_diagnosis_knock import RESTS
from tests.applications.test_diagnosis_real import XSENS_COLUMNS, _xsens_and_its_calibration

#: Planted on x and on z (g per g²).  At 4 mg/g² the robust fit names two rests, which the two terms (two
#: coefficients) cannot be told from: they stay outliers; at 8 mg/g² it names four.
NONLINEARITY = -8e-3


def xsens_two_nonlinearities(shared_data: Path, tmp_path: Path, value: float) -> PoseTable:
    """20 rests of the Xsens log (as ``xsens_cut``) with a scale nonlinearity of ``value`` on x and on z, planted
    through the log's own lumped calibration (as ``planted_xsens`` plants one effect)."""
    from optcal.data import load
    from optcal.families.simulate.effects import distort_recording

    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    if not path.exists():
        pytest.skip("imutk-xsens recording absent")
    raw, base = _xsens_and_its_calibration(path)
    coefficients = np.zeros((3, 1))
    coefficients[[0, 2], 0] = value
    model = ExtendedModel(base, {"scale_nonlinearity": coefficients}, temp_ref=30.0, t_ref=256.0)
    out = tmp_path / "two_nonlinearities.csv"
    distort_recording(raw.copy(), model).rename(columns={v: k for k, v in XSENS_COLUMNS.items()}).to_csv(
        out, index=False, float_format="%.8g")
    full = load(out)
    return full.subset(np.unique(np.linspace(0, full.n - 1, RESTS).round().astype(int)))


def test_outliers_a_nonlinearity_on_two_axes_explains_are_named_as_it(shared_data: Path, tmp_path: Path) -> None:
    poses = xsens_two_nonlinearities(shared_data, tmp_path, NONLINEARITY)
    diag = Diagnoser(DiagnosisSettings(simulations=0)).run(poses)
    assert [(f.effect, f.axes) for f in diag.findings] == [("scale_nonlinearity", ["x", "z"])]
    for axis in "xz":
        assert diag.findings[0].estimate[axis] == pytest.approx(NONLINEARITY, rel=0.3)
    # the outlier set was found and set aside for the set of terms, which says so
    [outliers] = [c for c in diag.steps[0].candidates if c.effect == "outliers"]
    assert not outliers.significant
    assert outliers.rejected_because is not None and "scale_nonlinearity(x) + scale_nonlinearity(z)" in \
        outliers.rejected_because
