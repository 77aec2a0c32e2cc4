"""Two knocks that hide each other (issue 39), planted in mikoff's MPU-9150 unit 0 (22 real rests).

A knock on x after rest 7 and one on y after rest 15: each is the best split of its axis, yet each one-step test
counts the other knock as noise (p 0.27-0.62 against 0.00125) and the one-step search names nothing.  The two steps
searched together (:mod:`optcal.applications.diagnosis.step_pair`: every pair of places and axes, the joint test
adjusted by minP over the pairs, each knock then tested given the other) name both at their places.  The unplanted
recordings name no step: on IMU-TK's Xsens log (38 rests) the best pair traces the z bias rising after rest 11 and
returning after 29, and its y knock is not needed given the z one.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.report.diagnosis_text import diagnosis_report

from tests.applications.test_diagnosis_small import planted_mikoff
from tests.applications.test_diagnosis_step import stepped, xsens_full


def mikoff(shared_data: Path, tmp_path: Path):
    path = shared_data / "mikoff-mpu9150" / "imu0.log"
    if not path.exists():
        pytest.skip("mikoff-mpu9150 recording absent")
    return planted_mikoff(tmp_path, path, None, 0, 0.0, "unplanted")


def pair_candidates(diag) -> list:
    return [c for s in diag.steps for c in s.candidates if c.second_at is not None]


# measured (docs/diagnosis.md, "Two knocks searched together"): 4 + 3 mg: x +3.90 mg after 7, y +3.54 mg after 15,
# joint p 0.00065 (minP over 1,575 pairs), each knock given the other 0.00087 and 2.5e-5, against 0.00125;
# 6 + 4 mg: +5.90 and +4.54 mg, joint p 0.0001
@pytest.mark.parametrize(("x_mg", "y_mg"), [(4.0, 3.0), (6.0, 4.0)])
def test_two_knocks_that_hide_each_other_are_named_together(shared_data: Path, tmp_path: Path,
                                                             x_mg: float, y_mg: float) -> None:
    poses = stepped(stepped(mikoff(shared_data, tmp_path), 7, 0, x_mg * 1e-3), 15, 1, y_mg * 1e-3)
    diag = Diagnoser(DiagnosisSettings(simulations=0)).run(poses)
    # the one-step search alone names nothing: each step's test counts the other knock as noise
    singles = [c for c in diag.steps[0].candidates if c.effect == "bias_step" and c.second_at is None]
    assert singles and not any(c.significant for c in singles)
    assert [f.effect for f in diag.findings] == ["bias_step"]
    found = diag.findings[0]
    assert found.axes == ["x", "y"]
    steps = found.to_dict()["step"]["steps"]
    assert [s["poses_before"] for s in steps] == [pytest.approx(7, abs=1), pytest.approx(15, abs=1)]
    assert steps[0]["estimate"]["x"] == pytest.approx(x_mg * 1e-3, rel=0.4)
    assert steps[1]["estimate"]["y"] == pytest.approx(y_mg * 1e-3, rel=0.4)
    # each axis's own knock in the finding's estimate, as a check reading one number per axis takes it
    assert found.estimate == {"x": pytest.approx(x_mg * 1e-3, rel=0.4), "y": pytest.approx(y_mg * 1e-3, rel=0.4)}
    accepted = diag.steps[0].accepted
    assert accepted is not None and accepted.second_at is not None and "2 steps together" in accepted.term
    assert accepted.p_value < accepted.threshold <= 0.005 / 4  # its share of the step's level: 3 axes and the pair
    assert diagnosis_report(diag).count("the bias stepped between the rests") == 2


def test_unplanted_recordings_name_no_pair_of_steps(shared_data: Path, tmp_path: Path) -> None:
    """The pair is searched on both (22 and 38 rests, no step placed) and named on neither: on mikoff's unit 0 its
    exact p is 0.02; on the Xsens log the best pair (the z bias rising after rest 11 and returning after 29, with y
    after 11: exact p 2e-7, minP-adjusted 0.00022) has its y knock at p 0.16 given the z one: not two knocks."""
    for poses in (mikoff(shared_data, tmp_path), xsens_full(shared_data, tmp_path)):
        diag = Diagnoser(DiagnosisSettings(simulations=0)).run(poses)
        assert not any(f.effect == "bias_step" for f in diag.findings)
        tried = pair_candidates(diag)
        assert tried and not any(c.significant for c in tried)
    assert any(c.rejected_because and "not needed given the other" in c.rejected_because for c in tried)
