"""The outlier recheck under the final model returns a pose by the backward check's rule, held-out check included.

IMU-TK's real Xsens log, 38 rests, with a 3 mg knock planted on y after rest 12, selection started with rest 35 set
aside (as an outlier step taken early leaves it).  Under the final model its deleted residual is not significant,
but the held-out rms rises with it back: the backward check keeps it aside, and the final recheck used to return it
all the same (by the test alone).  It now stays aside, with a note that says why.  A pose whose return lowers the
held-out rms is still returned by the final recheck (the drift-planted log with the backward check off).
"""

from __future__ import annotations

from pathlib import Path

from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.applications.diagnosis.backward import removals
from optcal.applications.diagnosis.selection import ForwardSelection
from optcal.core.stats import rms

from tests.applications.test_diagnosis_outlier_recheck import drift_and_its_outlier
from tests.applications.test_diagnosis_step import stepped, xsens_full

ASIDE = 35  # a rest whose departure no model explains or needs: its deleted residual's p is 1 under the final model


def test_a_pose_the_held_out_check_keeps_aside_is_not_returned_at_the_end(shared_data: Path, tmp_path: Path) -> None:
    poses = stepped(xsens_full(shared_data, tmp_path), 12, 1, 3e-3)
    fitter, _ = Diagnoser(DiagnosisSettings(simulations=0)).prepare(poses)
    start = fitter.fit({}, frozenset({ASIDE}), fitter.fit({}).x)
    notes: list[str] = []
    selection = ForwardSelection(fitter, [(e, a) for e in ("bias_drift", "bias_step") for a in range(3)], True, 0.02,
                                 notes.append)
    final = selection.run(start).final
    assert ("bias_step", 1) in final.terms
    assert final.outliers == frozenset({ASIDE})
    # the case: not significant under the final model (its test or its ΔBIC fails), the held-out rms rises without it
    [pose] = removals(fitter, final, {}, {}, None, (), selection.alpha_outliers, frozenset())
    assert pose.pose == ASIDE and (pose.p_value >= pose.level or pose.delta_bic >= 0)
    mask = pose.without.kept(fitter.n)
    assert rms(fitter.heldout(pose.without), mask) > rms(fitter.heldout(final), mask)
    row = int(poses.rows[ASIDE])
    assert [n for n in notes if n.startswith(f"outlier pose row {row} stays aside")]
    assert not [n for n in notes if n.startswith("outlier poses returned")]


def test_a_pose_whose_return_lowers_the_held_out_rms_is_returned_at_the_end(shared_data: Path, tmp_path: Path) -> None:
    poses, fitter, plain, k = drift_and_its_outlier(shared_data, tmp_path)  # the paper's model's outlier
    notes: list[str] = []
    selection = ForwardSelection(fitter, [("bias_drift", a) for a in range(3)], True, 0.02, notes.append,
                                 drop_unneeded=False)  # no backward check: the final recheck alone returns it
    final = selection.run(fitter.fit({}, frozenset({k}), plain.x)).final
    assert ("bias_drift", 0) in final.terms and k not in final.outliers
    [note] = [n for n in notes if n.startswith("outlier poses returned")]
    before, after = (float(v) for v in note.split("held-out rms ")[1].split(" mg")[0].split(" → "))
    assert f"pose rows {int(poses.rows[k])} " in note and after <= before
