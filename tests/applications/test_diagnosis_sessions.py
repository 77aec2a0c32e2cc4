"""Several sessions of one sensor diagnosed together: the turn-on bias repeatability as a named cause."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers.diagnosis_cases import make_case, write_pose_table

import optcal.families.calibration_files
from optcal.cli.main import main
from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.applications.diagnosis.sessions import stack_sessions
from optcal.errors import InputError
from optcal.core.model import AXES, lu2017_reference_model
from optcal.report.diagnosis_text import diagnosis_report

SETTINGS = DiagnosisSettings(simulations=10)
#: No simulation check where only the selection matters.
NO_SIMULATION = DiagnosisSettings(simulations=0)


def sessions_with_shift(shift_g: float, axis: int, seed: int, n: int = 40):
    """Two sessions of the reference sensor; the second's bias on output ``axis`` is ``shift_g`` higher."""
    first = make_case(None, seed, n_range=(n, n)).poses
    second = make_case(None, seed + 1000, n_range=(n, n)).poses
    sensitivity = np.linalg.norm(lu2017_reference_model().C, axis=1)  # raw units per g (bias terms are per g)
    acc = second.acc.copy()
    acc[:, axis] += shift_g * sensitivity[axis]
    return [first, second.with_acc(acc)], sensitivity


@pytest.mark.parametrize("seed, axis, shift_g", [(11, 2, 3e-3), (12, 0, -2e-3)])
def test_a_planted_turn_on_shift_is_named_with_its_axis_and_size(seed: int, axis: int, shift_g: float) -> None:
    sessions, sensitivity = sessions_with_shift(shift_g, axis, seed)
    diag = Diagnoser(SETTINGS).run_sessions(sessions, names=["monday", "tuesday"])
    found = diag.finding("session_bias")
    assert found is not None and found.axes == [AXES[axis]]
    offsets = found.sessions
    assert offsets is not None and offsets.names == ["monday", "tuesday"]
    difference = offsets.offsets_g[AXES[axis]][1] - offsets.offsets_g[AXES[axis]][0]
    assert difference == pytest.approx(shift_g, rel=0.3)
    # the spread of two sessions' biases is |shift|/√2; the finding's estimate is that spread
    assert found.estimate[AXES[axis]] == pytest.approx(abs(shift_g) / np.sqrt(2), rel=0.3)
    assert all(0 < se < abs(shift_g) / 3 for se in offsets.stderr_g[AXES[axis]])
    assert diag.final_heldout_rms() < diag.baseline_heldout_rms()  # held out over the k-fold, like every effect
    # S − 1 coefficients per axis, counted in the model size
    assert diag.final.n_params == 9 + 1 + len(diag.final.outliers) + sum(
        order for (e, _), order in diag.final.terms.items() if e != "session_bias")
    # the calibration a user can apply: the mean of the sessions' biases, the spread as its uncertainty
    cal = diag.calibration()
    assert cal.bias_repeatability is not None and cal.bias_repeatability.sessions == 2
    assert cal.bias_repeatability.per_axis_g[axis] == pytest.approx(found.estimate[AXES[axis]])
    shift_raw = (cal.o - diag.model.base.o)[axis]
    fitted_sensitivity = np.linalg.norm(diag.model.base.C, axis=1)[axis]  # raw units per g of the fit
    assert shift_raw == pytest.approx(0.5 * difference * fitted_sensitivity, rel=1e-9)
    assert fitted_sensitivity == pytest.approx(sensitivity[axis], rel=1e-3)
    assert "mean of 2 sessions" in cal.describe() and "repeatability" in cal.describe()
    assert "turn-on repeatability" in diagnosis_report(diag) and "cannot be applied to a future session" in diagnosis_report(diag)


def test_sessions_without_a_shift_name_no_session_bias() -> None:
    named = 0
    for seed in (21, 22, 23):
        sessions, _ = sessions_with_shift(0.0, 0, seed)
        diag = Diagnoser(NO_SIMULATION).run_sessions(sessions)
        named += diag.finding("session_bias") is not None
        assert "session_bias" in diag.effects_tested
    assert named == 0
    assert diag.calibration().cal_type in ("lumped", "extended")
    assert diag.to_dict()["sessions"]["poses"] == [40, 40]


def test_the_saved_repeatability_round_trips_as_a_minor_format_version(tmp_path: Path) -> None:
    sessions, _ = sessions_with_shift(3e-3, 1, 31)
    cal = Diagnoser(SETTINGS).run_sessions(sessions).calibration()
    path = tmp_path / "cal.json"
    cal.save(path)
    data = json.loads(path.read_text())
    assert data["format_version"] == "2.1" and data["bias_repeatability"]["sessions"] == 2
    back = optcal.families.calibration_files.load(path)
    assert back.bias_repeatability == cal.bias_repeatability
    np.testing.assert_allclose(back.o, cal.o, rtol=0, atol=1e-12)
    # a 2.0 file (no repeatability) still loads
    data.pop("bias_repeatability")
    data["format_version"] = "2.0"
    path.write_text(json.dumps(data))
    assert optcal.families.calibration_files.load(path).bias_repeatability is None


def test_each_session_keeps_its_own_time_origin_and_bad_stacks_are_refused() -> None:
    first = make_case(None, 41, n_range=(30, 30)).poses
    second = make_case(None, 42, n_range=(30, 30)).poses
    later = second.with_acc(second.acc)
    later.t = second.t + 86400.0  # recorded a day later: a drift is within a session
    stack = stack_sessions([first, later])
    assert stack.time_origins[1] == pytest.approx(float(np.min(later.t)))
    assert np.min(stack.poses.t[stack.session == 1]) == 0.0 and np.max(stack.poses.t) < 2000
    with pytest.raises(InputError, match="sessions"):
        stack_sessions([first])
    with pytest.raises(InputError, match="units"):
        stack_sessions([first, type(first)(acc=later.acc * 9.80665, units="m/s^2")])
    with pytest.raises(InputError, match="several sessions"):
        Diagnoser(DiagnosisSettings(effects="session_bias")).run(first)


def test_cli_diagnoses_sessions_together_and_saves_the_mean_bias(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    sessions, _ = sessions_with_shift(3e-3, 2, 51)
    paths = [str(write_pose_table(p, tmp_path / f"s{k}.csv")) for k, p in enumerate(sessions)]
    code = main(["diagnose", *paths, "--simulations", "10", "-o", str(tmp_path / "cal.json"),
                 "--report", str(tmp_path / "report.html")])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert sum("pose table" in line for line in out.out.splitlines()[:2]) == 2  # each session's data decisions
    assert "session_bias" in out.out and "turn-on repeatability" in out.out
    assert "mean of 2 sessions' biases" in out.out  # what the saved calibration applies, stated
    assert "session_bias on axis z" in (tmp_path / "report.html").read_text()
    code = main(["diagnose", *paths, "--simulations", "0", "--json"])
    obj = json.loads(capsys.readouterr().out)
    assert [d["path"] for d in obj["data"]] == paths and obj["sessions"]["names"] == paths
    found = next(f for f in obj["findings"] if f["effect"] == "session_bias")
    assert found["axes"] == ["z"] and len(found["sessions"]["offsets_g"]["z"]) == 2


def test_two_halves_of_the_xsens_log_with_a_planted_shift(shared_data: Path, tmp_path: Path) -> None:
    """The Xsens log cut in two sessions; the second half's z counts raised by 4 mg (truth hidden from diagnose)."""
    from optcal.data import load

    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    if not path.exists():
        pytest.skip("imutk-xsens recording absent")
    frame = pd.read_csv(path)
    half = len(frame) // 2
    frame.iloc[:half].to_csv(tmp_path / "a.csv", index=False)
    clean = frame.iloc[half:].copy()
    clean.to_csv(tmp_path / "b.csv", index=False)
    first, second = load(tmp_path / "a.csv"), load(tmp_path / "b.csv")
    unplanted = Diagnoser(NO_SIMULATION).run_sessions([first, second])
    assert unplanted.finding("session_bias") is None
    counts_per_g = float(np.linalg.norm(unplanted.model.base.C, axis=1)[2])
    shift_counts = int(round(4e-3 * counts_per_g))
    clean["acc_z_counts"] += shift_counts
    clean.to_csv(tmp_path / "b_shifted.csv", index=False)
    diag = Diagnoser(NO_SIMULATION).run_sessions([first, load(tmp_path / "b_shifted.csv")])
    found = diag.finding("session_bias")
    assert found is not None and found.axes == ["z"]
    difference = found.sessions.offsets_g["z"][1] - found.sessions.offsets_g["z"][0]
    assert difference == pytest.approx(shift_counts / counts_per_g, rel=0.3)


def test_an_outlier_in_the_second_session_is_named_with_its_session(tmp_path: Path) -> None:
    """File row numbers repeat across sessions: the JSON, the text and the HTML name the outlier's session."""
    from optcal.applications.quality.evidence import outlier_names

    sessions, sensitivity = sessions_with_shift(0.0, 0, 21)
    second = sessions[1]
    acc = second.acc.copy()
    k = 7
    acc[k] += 40e-3 * sensitivity  # 40 mg off on every axis
    sessions[1] = second.with_acc(acc)
    assert int(sessions[0].rows[k]) == int(sessions[1].rows[k])  # the same row number in both files
    diag = Diagnoser(SETTINGS).run_sessions(sessions, names=["first.csv", "second.csv"])
    found = diag.finding("outliers")
    assert found is not None
    at = found.rows.index(int(sessions[1].rows[k]))
    assert found.row_sessions[at] == "second.csv"
    assert found.pose_index[at] == sessions[0].n + k  # its place in the stack, not the first session's row
    out = diag.to_dict()
    row = next(f for f in out["findings"] if f["effect"] == "outliers")
    assert row["row_sessions"][at] == "second.csv"
    assert f"{int(sessions[1].rows[k])} of second.csv" in diagnosis_report(diag)
    assert outlier_names(diag.poses, found)[at].endswith("of second.csv")
