"""The command line as a new user meets it: usage errors, messages in flags, export, identifiability, simulate."""

import re

import numpy as np
import pytest

from helpers.cli_run import run_args as run


@pytest.mark.parametrize("args, expected", [
    (("apply", "{cal}", "{data}"), "Missing option '-o' / '--output'"),
    (("export", "{cal}", "--format", "matlab"), "Invalid value for '--format'"),
    (("calibrate", "{data}", "--rate", "-3"), "Invalid value for '--rate'"),
    (("calibrate", "{data}", "--rate", "0"), "Invalid value for '--rate'"),
    (("calibrate", "{data}", "--scale-range", "-1", "2"), "Invalid value for '--scale-range'"),
    (("export", "{cal}", "--format", "ardupilot", "--counts-per-g", "-5"), "Invalid value for '--counts-per-g'"),
    (("calibrate", "{data}", "--no-such-flag"), "No such option"),
])
def test_usage_errors_are_one_error_line_with_exit_2(capsys, pose_csv, tmp_path, args, expected):
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    argv = [a.format(cal=cal, data=pose_csv) for a in args]
    code, out, err = run(capsys, *argv)
    lines = err.strip().splitlines()
    assert code == 2
    assert len(lines) == 1 and lines[0].startswith("error: ") and expected in lines[0], err
    assert "--help" in lines[0] and "Usage:" not in err


# ----------------------------------------------------------------------------- library messages in CLI words
@pytest.fixture
def counts_cal(tmp_path):
    """A lumped calibration in counts (fitted on 30 noise-free poses) and a recording in m/s²."""
    from optcal.families.caltypes import FitPoses, LumpedCalibration
    from optcal.core.model import LumpedModel, lu2017_reference_model
    from optcal.families.simulate.poses import uniform_directions

    model = LumpedModel(np.diag([16300.0, 16450.0, 16700.0]) @ lu2017_reference_model().C,
                        np.array([700.0, -360.0, -1830.0]))
    d = uniform_directions(30, rng=2)
    LumpedCalibration.from_model(model, "counts", FitPoses(model.measure(d))).save(tmp_path / "cal.json")
    n = 400
    acc = np.repeat(uniform_directions(20, rng=3), n // 20, axis=0) * 9.80665
    lines = ["t_s,ax_m_s2,ay_m_s2,az_m_s2"] + [f"{i / 100:.2f},{a:.6f},{b:.6f},{c:.6f}" for i, (a, b, c) in enumerate(acc)]
    (tmp_path / "ms2.csv").write_text("\n".join(lines) + "\n")
    return tmp_path / "cal.json", tmp_path / "ms2.csv"


def one_error(code, err):
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: "), err
    return err


def test_export_messages_name_the_flags(capsys, counts_cal):
    cal, _ = counts_cal
    err = one_error(*run(capsys, "export", str(cal), "--format", "ardupilot")[::2])
    assert "give --counts-per-g (" in err and "counts_per_g" not in err
    err = one_error(*run(capsys, "export", str(cal), "--format", "kalibr")[::2])
    assert "pass --allan FILE (an optcal allan --json result)" in err
    err = one_error(*run(capsys, "export", str(cal), "--format", "px4", "--counts-per-g", "16384",
                         "--counts-zero", "0", "--max-loss", "0.5")[::2])
    assert "more than --max-loss 0.5 mg" in err and "Raise --max-loss to export anyway" in err
    assert "max_loss_g" not in err


def test_apply_names_data_units_and_columns(capsys, counts_cal, tmp_path):
    cal, ms2 = counts_cal
    err = one_error(*run(capsys, "apply", str(cal), str(ms2), "-o", str(tmp_path / "out.csv"))[::2])
    assert "(or pass --data-units counts if that is what it is)" in err and "units=" not in err
    from optcal.families.caltypes import ExtendedCalibration, FitPoses
    from optcal.core.extended_model import ExtendedModel
    from optcal.core.model import LumpedModel

    model = ExtendedModel(LumpedModel(np.eye(3), np.zeros(3)), {"temperature_bias": np.array([1e-3, 0, 0])}, temp_ref=25.0)
    ExtendedCalibration.from_model(model, "g", fitted_on=None).save(tmp_path / "ext.json")
    err = one_error(*run(capsys, "apply", str(tmp_path / "ext.json"), str(ms2), "-o", str(tmp_path / "out.csv"))[::2])
    assert "map it with --columns temp=NAME" in err


def test_calibrate_names_time_unit(capsys, counts_cal):
    _, ms2 = counts_cal
    err = one_error(*run(capsys, "calibrate", str(ms2), "--time-unit", "ms")[::2])
    assert "--time-unit ms contradicts the column name" in err and " time_unit " not in err


@pytest.fixture
def one_ipopt_iteration(monkeypatch):
    """IPOPT limited to one iteration; the problems built meanwhile are not kept for other tests."""
    from optcal.families.accel import mle
    from optcal.solvers import nlp

    monkeypatch.setitem(nlp.SCALED_COST_IPOPT_OPTIONS, "ipopt.max_iter", 1)
    mle.ML_PROBLEMS.clear()
    yield
    mle.ML_PROBLEMS.clear()


def test_ipopt_advice_says_what_a_cli_user_can_do(capsys, pose_csv, one_ipopt_iteration):
    code, _, err = run(capsys, "calibrate", str(pose_csv), "--method", "mle")
    assert code == 0
    warning = next(line for line in err.splitlines() if line.startswith("warning: "))
    assert "the mle fit did not converge" in warning and "try --method convex" in warning
    assert "ipopt_options" not in warning and "init=" not in warning


# ----------------------------------------------------------------------------- identifiability: wording and order
def test_weakly_determined_pose_set_is_refused_with_consistent_wording(capsys, shared_data):
    path = shared_data / "mpu6050-imucalibration" / "example_data_calibration.csv"
    if not path.exists():
        pytest.skip(f"shared data not available: {path}")
    code, out, err = run(capsys, "calibrate", str(path))
    err = one_error(code, err)
    assert "only weakly (Fisher rank 9/9" in err and re.search(r"weakly determined \(standard error 0\.\d+ of full scale\)", err)
    assert "does not determine" not in err and "--allow-degenerate" in err
    assert out.startswith("DATA: ") and re.search(r"→ 1[01] static poses", out)  # what was read, next to the refusal
    code, out, err = run(capsys, "calibrate", str(path), "--allow-degenerate")
    assert code == 0, err
    assert "Fisher rank 9/9" in out and "WEAKLY DETERMINED POSE SET" in out and "does not determine" not in out


def test_identifiability_is_checked_before_the_iterative_fit(capsys, tmp_path, one_ipopt_iteration):
    from optcal.core.model import lu2017_reference_model
    from optcal.families.simulate.poses import simulate_poses

    # six cube faces: rank 6 of 9 whatever the noise; an IPOPT limit of 1 iteration would warn if it ran
    faces = np.repeat(np.vstack([np.eye(3), -np.eye(3)]), 3, axis=0)
    poses = simulate_poses(lu2017_reference_model(), faces, 0.002, rng=np.random.default_rng(1))
    path = tmp_path / "faces.csv"
    path.write_text("ax,ay,az\n" + "\n".join(",".join(f"{v:.10g}" for v in row) for row in poses.acc) + "\n")
    for method in ("default", "mle", "exact", "gd"):
        code, _, err = run(capsys, "calibrate", str(path), "--method", method, "--format", "poses")
        err = one_error(code, err)
        assert "warning" not in err and ("identifies only" in err or "only weakly" in err), (method, err)


# ----------------------------------------------------------------------------- simulate -> calibrate --method sixpos
def test_simulated_six_positions_calibrate_with_sixpos(capsys, tmp_path):
    import optcal.families.calibration_files as calibration_files
    from optcal.data import load
    from optcal.families.simulate.poses import six_position, user_directions

    path = tmp_path / "six.csv"
    code, _, err = run(capsys, "simulate", "--schedule", "sixpos", "--sigma", "0", "-o", str(path))
    assert code == 0, err
    table = load(path)
    angles = np.column_stack([table.extra["roll_deg"], table.extra["pitch_deg"]])
    np.testing.assert_allclose(user_directions(angles, "euler_deg"), six_position(), atol=1e-12)
    code, out, err = run(capsys, "calibrate", str(path), "--method", "sixpos", "-o", str(tmp_path / "cal.json"))
    assert code == 0, err
    cal = calibration_files.load(tmp_path / "cal.json")
    # noise-free: the fitted W, V map every simulated pose onto its true direction
    np.testing.assert_allclose(cal.correct(table.acc), six_position(), atol=1e-8)
