"""A bias step that persists (issue 39, item 2: "a knock that is hidden"), planted in real recordings.

A knock between two rests moves the accelerometer's zero offset and it stays moved: every rest after it carries the
same extra bias on the knocked axis.  Planted on the pose means of every rest from one on (what adding the offset to
every later sample does to them), in IMU-TK's real Xsens log cut to 20 rests and in mikoff's MPU-9150 unit 0 (22
rests): the log's own noise, pose scatter and slow biases stay in.  The diagnosis names ``bias_step`` on the knocked
axis, its size within 40 %, its place within one rest; the unplanted recordings name no step, and a knocked rest
that did not persist stays an outlier (tests/applications/test_diagnosis_knock.py).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.applications.diagnosis.bias_step import scan_step
from optcal.applications.diagnosis.fitting import Fitter
from optcal.applications.diagnosis.regressors import Regressors
from optcal.core.poses import PoseTable
from optcal.report.diagnosis_text import diagnosis_report
from optcal.families.accel.calibration import calibrate

from tests.applications.test_diagnosis_knock import g_per_raw, xsens_cut
from tests.applications.test_diagnosis_small import planted_mikoff

#: The rest the step comes before (the 11th of 20 Xsens rests; the 12th of mikoff's 22).
XSENS_AT = 10
MIKOFF_AT = 11


def stepped(poses: PoseTable, at: int, axis: int, size_g: float) -> PoseTable:
    """``poses`` with the bias of ``axis`` raised by ``size_g`` from pose ``at`` on (poses in time order)."""
    acc = poses.acc.copy()
    acc[at:, axis] += size_g / g_per_raw(poses)
    return replace(poses, acc=acc)


def steps_named(poses: PoseTable) -> list:
    diag = Diagnoser(DiagnosisSettings(simulations=0)).run(poses)
    return [f for f in diag.findings if f.effect == "bias_step"], diag


def check_step(finding, axis: str, size_g: float, at: int) -> None:
    assert finding.axes == [axis]
    assert finding.estimate[axis] == pytest.approx(size_g, rel=0.4)
    assert finding.stderr[axis] > 0
    assert abs(finding.step["poses_before"] - at) <= 1
    assert finding.to_dict()["step"]["t_s"] > finding.to_dict()["step"]["previous_t_s"]


# Xsens, 20 rests: 1.5 mg on y is 1.49 mg after 11 rests, on z 1.71 mg after 9 (the log's own slow z bias).  On x the
# step is missed at 1.5-2 mg (p 0.047 and 0.0078 against 0.0017: these rests' directions give x little weight after
# rest 10).
@pytest.mark.parametrize("axis", [1, 2])
def test_a_persisting_step_in_20_xsens_rests_is_named_as_a_bias_step(shared_data: Path, tmp_path: Path,
                                                                    axis: int) -> None:
    poses = xsens_cut(shared_data, tmp_path)
    size = 1.5e-3
    found, diag = steps_named(stepped(poses, XSENS_AT, axis, size))
    assert [f.effect for f in diag.findings] == ["bias_step"]  # not outliers, not a cubic drift
    check_step(found[0], "xyz"[axis], size, XSENS_AT)


# mikoff's unit 0 scatters more from pose to pose (its rests' σ 0.28 mg, the poses more): 2 mg is the best candidate
# at the right place but p 0.003-0.02 against 0.0017 (0.00125 since two steps are also searched together); 3 mg
# on x is named +4 %, after rest 11 exactly.
def test_a_persisting_step_in_a_mikoff_unit_is_named_as_a_bias_step(shared_data: Path, tmp_path: Path) -> None:
    path = shared_data / "mikoff-mpu9150" / "imu0.log"
    if not path.exists():
        pytest.skip("mikoff-mpu9150 recording absent")
    poses = planted_mikoff(tmp_path, path, None, 0, 0.0, "unplanted")
    size = 3e-3
    found, diag = steps_named(stepped(poses, MIKOFF_AT, 0, size))
    assert [f.effect for f in diag.findings] == ["bias_step"]
    check_step(found[0], "x", size, MIKOFF_AT)


def test_unplanted_recordings_name_no_step(shared_data: Path, tmp_path: Path) -> None:
    path = shared_data / "mikoff-mpu9150" / "imu0.log"
    if not path.exists():
        pytest.skip("mikoff-mpu9150 recording absent")
    for poses in (xsens_cut(shared_data, tmp_path), planted_mikoff(tmp_path, path, None, 0, 0.0, "unplanted")):
        found, diag = steps_named(poses)
        assert diag.findings == []
        # the step was searched (a candidate of the first step), and its p adjusted over the positions is not small
        tried = [c for c in diag.steps[0].candidates if c.effect == "bias_step"]
        assert tried and all(c.p_value > c.threshold for c in tried)


def test_the_linearised_scan_places_the_step_where_the_exact_fits_do(shared_data: Path, tmp_path: Path) -> None:
    poses = stepped(xsens_cut(shared_data, tmp_path), XSENS_AT, 2, 1.5e-3)
    cal = calibrate(poses, "mle")
    fitter = Fitter(poses, Regressors.of(poses), cal.T, cal.o, 5)
    base = fitter.fit({})
    scan = scan_step(fitter, base, 2)
    assert scan is not None and scan.positions == len(scan.splits) == poses.n - 2 * 3 + 1  # three poses each side
    rss = {k: fitter.fit({("bias_step", 2): 1}, frozenset(), base.x, fitter.step_data(k)).rss for k in scan.splits}
    assert scan.at == min(rss, key=lambda k: rss[k])
    assert abs(scan.at - XSENS_AT) <= 1


def test_a_step_not_named_has_its_own_detection_limit(shared_data: Path, tmp_path: Path) -> None:
    """20 unplanted Xsens rests: each axis's step gets a detection limit (the median over the positions searched,
    their range, the step's own level and minP); a y step after rest 10 at twice the largest y limit is named there,
    at half the smallest it is not (measured: y 0.45-0.57 mg, median 0.47; x 1.4-48 mg, these rests' directions
    give x little weight after rest 10, where 2 mg was missed at p 0.0078)."""
    poses = xsens_cut(shared_data, tmp_path)
    _, diag = steps_named(poses)
    limits = {lim.axis: lim for lim in diag.detection_limits if lim.effect == "bias_step"}
    assert sorted(limits) == ["x", "y", "z"]
    for lim in limits.values():
        assert lim.low is not None and lim.high is not None
        assert 0 < lim.low <= lim.limit <= lim.high and lim.adjusted == "minP"
        assert "bias_step" in lim.text() and lim.to_dict()["high"] == lim.high
    y = limits["y"]
    assert y.high is not None and y.low is not None
    found, diag = steps_named(stepped(poses, XSENS_AT, 1, 2 * y.high))
    assert [f.effect for f in diag.findings] == ["bias_step"]
    check_step(found[0], "y", 2 * y.high, XSENS_AT)
    found, _ = steps_named(stepped(poses, XSENS_AT, 1, 0.5 * y.low))
    assert found == []


def xsens_full(shared_data: Path, tmp_path: Path) -> PoseTable:
    """All 38 rests of the Xsens log (a second step is searched while it leaves MIN_DOF residual degrees of
    freedom: 20 rests leave 9 after one step)."""
    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    if not path.exists():
        pytest.skip("imutk-xsens recording absent")
    from tests.applications.test_diagnosis_real import planted_xsens

    return planted_xsens(tmp_path, path, None, 0, 0.0, "unplanted")


# measured (docs/diagnosis.md, "A knock, then another"): 3 mg on y after rest 12 and 1.5 mg on z after rest 26 named
# at 12 and 26, +2.9 and +1.31 mg (z's first-step offset 0.25 mg, fitted beside it); two steps on y (1.5 mg after 12,
# 3 mg after 26) named after 25 and 12, 3.09 and 1.45 mg
def test_two_knocks_in_the_real_xsens_log_are_each_named_at_their_place(shared_data: Path, tmp_path: Path) -> None:
    """A knock moves y by 3 mg after rest 12, a later one z by 1.5 mg after rest 26: one ``bias_step`` finding on
    y and z, its two steps at their places (within one rest) with their sizes within 40 %."""
    poses = stepped(stepped(xsens_full(shared_data, tmp_path), 12, 1, 3e-3), 26, 2, 1.5e-3)
    found, diag = steps_named(poses)
    assert len(found) == 1 and found[0].axes == ["y", "z"]
    steps = found[0].to_dict()["step"]["steps"]
    assert [s["poses_before"] for s in steps] == [pytest.approx(12, abs=1), pytest.approx(26, abs=1)]
    assert steps[0]["estimate"]["y"] == pytest.approx(3e-3, rel=0.4)
    assert steps[1]["estimate"]["z"] == pytest.approx(1.5e-3, rel=0.4)
    assert all(f.effect != "outliers" for f in diag.findings)
    assert diagnosis_report(diag).count("the bias stepped between the rests") == 2
    assert "stepped once" not in diagnosis_report(diag)


def test_one_knock_in_the_real_xsens_log_is_not_named_twice(shared_data: Path, tmp_path: Path) -> None:
    """1.5 mg on y after rest 12: one step placed; the second step is searched (every axis, the first step's
    position excluded) and none is significant at its family-wise level (measured: p 0.26 on y, 0.0088 on z
    against 0.0017)."""
    found, diag = steps_named(stepped(xsens_full(shared_data, tmp_path), 12, 1, 1.5e-3))
    assert len(found) == 1 and found[0].axes == ["y"]
    check_step(found[0], "y", 1.5e-3, 12)
    assert "steps" not in found[0].step
    second = [c for s in diag.steps for c in s.candidates if c.effect == "bias_step" and c.order == 2
              and c.step_at is not None]
    assert second and not any(c.significant for c in second)


def drifted(poses: PoseTable, axis: int, total_g: float) -> PoseTable:
    """``poses`` with the bias of ``axis`` rising linearly in time by ``total_g`` over the recording."""
    acc = poses.acc.copy()
    s = (poses.t - poses.t.mean()) / (poses.t[-1] - poses.t[0])
    acc[:, axis] += total_g * s / g_per_raw(poses)
    return replace(poses, acc=acc)


# measured (docs/diagnosis.md, "A term made unneeded"): bias_drift(y) enters first (p 5e-16), the steps after 25 and
# 12 (p 2.5e-5 each); given both, the drift's p is far above the 0.00056 it entered at and it is dropped
def test_a_drift_taken_before_two_knocks_on_one_axis_is_dropped(shared_data: Path, tmp_path: Path) -> None:
    """Two y knocks, 1.5 mg after rest 12 and 3 mg after rest 26 of the 38 Xsens rests, no drift planted: a staircase
    that a first-order drift fits first, and keeps with the backward check off.  Once both steps are in, the drift
    is tested for removal given them and dropped; the steps stay at their places with their sizes, the JSON lists the dropped term with its p and level,
    and the report says so in one line."""
    poses = stepped(stepped(xsens_full(shared_data, tmp_path), 12, 1, 1.5e-3), 26, 1, 3e-3)
    kept = Diagnoser(DiagnosisSettings(simulations=0, drop_unneeded=False)).run(poses)  # optcal diagnose --keep-terms
    assert ("bias_drift", 1) in kept.final.terms and kept.dropped == []
    assert kept.to_dict()["settings"]["drop_unneeded"] is False
    found, diag = steps_named(poses)
    assert ("bias_drift", 1) not in diag.final.terms
    assert len(found) == 1 and found[0].axes == ["y"]
    steps = sorted(found[0].to_dict()["step"]["steps"], key=lambda s: s["poses_before"])
    assert [s["poses_before"] for s in steps] == [pytest.approx(12, abs=1), pytest.approx(26, abs=1)]
    assert steps[0]["estimate"]["y"] + steps[1]["estimate"]["y"] == pytest.approx(4.5e-3, rel=0.4)
    dropped = diag.to_dict()["dropped"]
    assert [(d["effect"], d["axis"]) for d in dropped] == [("bias_drift", "y")]
    assert dropped[0]["p_value"] >= dropped[0]["level"] or dropped[0]["delta_bic"] >= 0
    assert dropped[0]["heldout_rms_g_without"] <= dropped[0]["heldout_rms_g_with"]
    assert "bias_step" in dropped[0]["after"]
    assert diagnosis_report(diag).count("dropped bias_drift(y)") == 1
    assert not any(f.effect == "bias_drift" and "y" in f.axes for f in diag.findings)


# measured: the step after rest 10 (3.56 mg, p 0.00075 against 0.0017) enters first, then the drift (0.053 mg/s, 8.0
# mg over the log; p 0.00048 against 0.00071); the step given the drift is not tested away
def test_a_real_drift_and_a_knock_are_both_kept(shared_data: Path, tmp_path: Path) -> None:
    """mikoff's unit 0 (22 rests) with a drift of 8 mg over the log on x and a 4 mg x knock after rest 11: both named,
    nothing dropped (the backward check does not remove a term the data still need)."""
    path = shared_data / "mikoff-mpu9150" / "imu0.log"
    if not path.exists():
        pytest.skip("mikoff-mpu9150 recording absent")
    poses = drifted(stepped(planted_mikoff(tmp_path, path, None, 0, 0.0, "unplanted"), MIKOFF_AT, 0, 4e-3), 0, 8e-3)
    found, diag = steps_named(poses)
    assert sorted(f.effect for f in diag.findings) == ["bias_drift", "bias_step"]
    check_step(found[0], "x", 4e-3, MIKOFF_AT)
    drift = diag.finding("bias_drift")
    span = float(poses.t[-1] - poses.t[0])
    assert drift.axes == ["x"] and drift.estimate["x"] * span == pytest.approx(8e-3, rel=0.4)
    assert diag.dropped == [] and "dropped" not in diag.to_dict()


def test_a_knock_taken_before_the_drift_it_stood_for_is_dropped(shared_data: Path, tmp_path: Path) -> None:
    """mikoff's unit 0 (22 rests) with a drift of 8 mg over the log on x and no knock: a step of x at the middle is a
    drift's two-level summary.  Had it entered first (at its share of the step's level, 0.00125), the drift entering
    after it makes it unneeded: the backward check re-tests the knock by its entry test (the F test of its offset
    given the drift, adjusted for the positions searched) and drops it, the held-out rms not rising.  With the
    planted knock of the test above the knock stays (it is tested the same way there)."""
    from optcal.applications.diagnosis.selection import ForwardSelection

    path = shared_data / "mikoff-mpu9150" / "imu0.log"
    if not path.exists():
        pytest.skip("mikoff-mpu9150 recording absent")
    poses = drifted(planted_mikoff(tmp_path, path, None, 0, 0.0, "unplanted"), 0, 8e-3)
    cal = calibrate(poses, "mle")
    fitter = Fitter(poses, Regressors.of(poses), cal.T, cal.o, 5)
    candidates = [(e, a) for e in ("bias_drift", "bias_step") for a in range(3)]
    selection = ForwardSelection(fitter, candidates, True, 0.02, lambda text: None)
    fitter.set_steps((MIKOFF_AT,))
    both = fitter.fit({("bias_step", 0): 1, ("bias_drift", 0): 1})
    levels = {("bias_step", 0): 0.00125, ("bias_drift", 0): 0.00071}
    final, dropped = selection.backward_check(both, levels, ("bias_drift", 0), "bias_drift(x)")
    assert [(d.effect, d.axis) for d in dropped] == [("bias_step", "x")]
    assert dropped[0].p_value >= dropped[0].level or dropped[0].delta_bic >= 0
    assert dropped[0].heldout_rms_g_without <= dropped[0].heldout_rms_g_with
    assert final.terms == {("bias_drift", 0): 1} and fitter.steps_at == ()
    assert selection.step_axes(final) == [1, 2]  # the dropped knock is not searched again
