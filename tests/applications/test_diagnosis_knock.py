"""A knocked rest and a rest a little off, in 20 rests of IMU-TK's real Xsens log (issue 39, item 2).

* A knock: one rest's mean moved by 1.7 mg on one axis, the rest of the recording untouched (the log's own noise,
  its pose-to-pose scatter and its own slow z bias stay in).  Planted on the pose mean, which is what adding the
  same offset to every sample of that rest does to it.  The diagnosis names that rest as an outlier and nothing
  else, and the random-walk bias (a noise explanation, reported beside the findings) is fitted without it: the knock
  does not inflate the allowance for a wandering bias.
* A rest 2.6 σ of the pose scatter off beside a real drift: a 20-pose session is tested at a family-wise level over
  its poses (Bonferroni: 2.6 σ is p ≈ 0.02 for one pose, 0.4 over 20), so the drift is named and the rest is not.

These pass on the branch's base too: they guard the outlier test's family-wise level and the walk's fit on the kept
poses, which item 2 of the issue found failing on held-out data.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.core.poses import PoseTable
from optcal.families.accel.calibration import calibrate

from tests.applications.test_diagnosis_real import planted_xsens

#: Rests kept of the log's 38, spread evenly.
RESTS = 20
#: The knock (g) and the rest it hits: pose 10 of the 20 (its direction 0.60, 0.62, 0.51: the norm residual sees
#: half the knock on z).
KNOCK_G = 1.7e-3
KNOCKED = 10


def xsens_cut(shared_data: Path, tmp_path: Path, effect: str | None = None, axis: int = 0,
              value: float = 0.0) -> PoseTable:
    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    if not path.exists():
        pytest.skip("imutk-xsens recording absent")
    full = planted_xsens(tmp_path, path, effect, axis, value, "planted" if effect else "unplanted")
    return full.subset(np.unique(np.linspace(0, full.n - 1, RESTS).round().astype(int)))


def shifted(poses: PoseTable, k: int, shift_raw: np.ndarray) -> PoseTable:
    """``poses`` with pose ``k``'s mean moved by ``shift_raw`` (raw units)."""
    acc = poses.acc.copy()
    acc[k] += shift_raw
    return replace(poses, acc=acc)


def g_per_raw(poses: PoseTable) -> float:
    return float(np.mean(np.abs(np.diag(calibrate(poses, "mle").T))))


def test_a_knocked_rest_is_named_as_an_outlier_and_not_absorbed_by_the_random_walk(shared_data: Path,
                                                                                     tmp_path: Path) -> None:
    poses = xsens_cut(shared_data, tmp_path)
    settings = DiagnosisSettings(simulations=0)
    own = Diagnoser(settings).run(poses)
    assert own.findings == []
    knock = np.zeros(3)
    knock[2] = KNOCK_G / g_per_raw(poses)
    diag = Diagnoser(settings).run(shifted(poses, KNOCKED, knock))
    assert [(f.effect, f.rows) for f in diag.findings] == [("outliers", [int(poses.rows[KNOCKED])])]
    walk, own_walk = diag.noise_model.random_walk, own.noise_model.random_walk
    assert walk is not None and own_walk is not None and walk.tested and own_walk.tested
    # fitted on the kept poses: the knock does not raise the walk's intensity beyond the unknocked log's interval
    assert own_walk.K_interval_g[0] <= walk.K_g <= own_walk.K_interval_g[1]


#: The issue's case.  Without the correction over the poses it is not flagged either (checked: a 2.6 σ rest is not
#: even a suspect of the robust fit, and neither is one at 3.3 σ once the fit has taken its share): this guards the
#: result, not the correction.
@pytest.mark.parametrize("sigmas", [2.6])
def test_a_rest_a_little_off_beside_a_real_drift_is_not_an_outlier(shared_data: Path, tmp_path: Path,
                                                                   sigmas: float) -> None:
    value = 2.4e-5  # g/s on x: 12 mg over the log's 512 s
    poses = xsens_cut(shared_data, tmp_path, "bias_drift", 0, value)
    settings = DiagnosisSettings(simulations=0)
    drift = Diagnoser(settings).run(poses)
    # named on x; on this cut the synthetic warm-up and the clock are nearly collinear, so the name may be the
    # temperature's (its alternatives then hold the drift)
    (named,) = [(f.effect, f.axes) for f in drift.findings]
    assert named[1] == ["x"] and named[0] in ("bias_drift", "temperature_bias", "temperature_scale")
    # sigmas times the final model's residual rms, along the pose's own direction (the only part the norm residual sees)
    k = KNOCKED
    sigma_g = float(np.sqrt(np.mean(drift.final.residuals[drift.kept] ** 2)))
    direction = poses.acc[k] / np.linalg.norm(poses.acc[k])
    diag = Diagnoser(settings).run(shifted(poses, k, sigmas * sigma_g / g_per_raw(poses) * direction))
    assert [(f.effect, f.axes) for f in diag.findings] == [named]  # the same, and no outlier
