"""``optcal check CAL.json DATA``: a saved calibration evaluated on other data; validation helpers."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli_run import run
from optcal.data import load
from optcal.families.simulate.recording import synthesize_recording
from optcal.applications.quality.validation import (
    check_calibration,
    displacement_integration,
    held_out_validation,
    kfold_masks,
    levelling_rotation,
)
from optcal.errors import InputError
from optcal.core.model import STANDARD_GRAVITY, LumpedModel
from optcal.core.norm_residual import norm_residuals
from optcal.families.simulate.poses import uniform_directions

SIGMA = 0.003
MODEL = LumpedModel.from_physical([1.02, 0.98, 1.03], np.deg2rad(0.8), np.deg2rad(-0.5), np.deg2rad(0.6),
                                  [0.05, -0.03, -0.08])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A calibration from recording A, and a second recording B of the same sensor (g and m/s²)."""
    from optcal.families.accel.calibration import calibrate

    d = tmp_path_factory.mktemp("check")
    a = synthesize_recording(MODEL, uniform_directions(30, rng=1), sigma=SIGMA, rng=2)
    b = synthesize_recording(MODEL, uniform_directions(15, rng=3), sigma=SIGMA, rng=4)
    a.to_csv(d / "a.csv")
    b.to_csv(d / "b.csv")
    ms2 = b.frame.copy()
    ms2[["ax", "ay", "az"]] *= STANDARD_GRAVITY
    ms2.to_csv(d / "b_ms2.csv", index=False, float_format="%.9g")
    calibrate(load(d / "a.csv")).save(d / "cal.json")
    return d, b



def test_check_json_reports_before_and_after(files, capsys):
    d, b = files
    code, out, err = run(["check", str(d / "cal.json"), str(d / "b.csv"), "--json"], capsys)
    assert code == 0, err
    r = json.loads(out)
    assert r["data"]["kind"] == "raw recording"
    assert r["n_poses"] == len(b.dwells) == len(r["poses"])
    # after calibration only the noise of the poses (and of the calibration) is left
    assert r["rms_after_g"] < 3 * r["rms_noise_g"]
    # the uncalibrated sensor is off by its scale factors (2-3 %) and bias (up to 0.08 g)
    assert r["rms_before_g"] > 10e-3
    # the per-pose errors are those of the true calibration, up to the calibration's own error
    with_truth = np.linalg.norm(MODEL.correct(load(d / "b.csv").acc), axis=1) - 1
    assert np.allclose([p_["after_g"] for p_ in r["poses"]], with_truth, atol=5 * SIGMA / np.sqrt(300))


def test_check_text_and_unit_conversion(files, capsys):
    d, _ = files
    code, out_g, _ = run(["check", str(d / "cal.json"), str(d / "b.csv")], capsys)
    assert code == 0 and "rms |a|-1 over 15 poses: before" in out_g and "read as a raw recording" in out_g
    code, out_ms2, _ = run(["check", str(d / "cal.json"), str(d / "b_ms2.csv")], capsys)
    assert code == 0 and "DATA converted from m/s^2 to g" in out_ms2
    rms = [line for line in out_g.splitlines() if line.startswith("rms")][0]
    rms2 = [line for line in out_ms2.splitlines() if line.startswith("rms")][0]
    assert rms.split("after")[1][:12] == rms2.split("after")[1][:12]


def test_check_bad_inputs(files, tmp_path, capsys):
    d, _ = files
    (tmp_path / "bad.json").write_text("{not json")
    code, out, err = run(["check", str(tmp_path / "bad.json"), str(d / "b.csv")], capsys)
    assert code == 2 and "not a JSON calibration file" in err and out == ""
    code, _, err = run(["check", str(tmp_path / "missing.json"), str(d / "b.csv")], capsys)
    assert code == 2 and "no such calibration file" in err
    code, _, err = run(["check", str(d / "cal.json"), str(d / "b.csv"), "--units", "counts"], capsys)
    # --units counts on data in g is refused when DATA is read (the norm contradicts it), before the check
    assert code == 2 and "units counts (given with --units) contradict the data: the median |a| is 1.002" in err


def test_check_calibration_counts_nominal_baseline():
    from optcal.core.fit_result import SolverInfo, chi_square
    from optcal.families.accel.result import CalibrationResult

    model = LumpedModel.from_physical([4065.0, 4047.0, 4063.0], 0.0, 0.0, 0.0, [33122.0, 33278.0, 32371.0])
    d = uniform_directions(20, rng=0)
    from optcal.families.simulate.poses import simulate_poses

    poses = simulate_poses(model, d, 0.5, rng=1, units="counts")
    T, o = model.T_canonical, model.o
    residuals = norm_residuals(T, o, poses.acc)
    cal = CalibrationResult(method="test", T=T, o=o, units="counts", params=np.zeros(9), param_names=[], covariance=None,
                            residuals=residuals, weights=np.ones(poses.n), chisqr=chi_square(residuals, np.ones(poses.n)),
                            n_observations=poses.n, sigma_known=True, solver=SolverInfo("none", "ok", True, 0, 0.0))
    check = check_calibration(cal, poses)
    assert "offset 32768" in check.nominal.description
    assert check.rms_after < 1e-3 < check.rms_before


def test_held_out_validation_on_known_truth():
    from optcal.families.simulate.poses import simulate_poses

    poses = simulate_poses(MODEL, uniform_directions(40, rng=5), SIGMA / 10, rng=6)
    h = held_out_validation(poses, folds=4, rng=0)
    assert np.all(np.isfinite(h.residuals)) and len(h.folds) == 4
    # held-out residuals are noise-sized, a little larger than in-sample
    assert h.rms_in_sample < h.rms_held_out < 2 * SIGMA / 10
    masks = kfold_masks(40, 4, 0)
    assert np.array_equal(np.sum(masks, axis=0), np.ones(40))
    with pytest.raises(InputError, match="training poses"):
        held_out_validation(poses.subset(np.arange(10)), folds=2)


def test_displacement_integration_eq31():
    """A static log with norm error e: ε_z = ½ e g T², horizontal zero (levelled)."""
    t = np.arange(0, 200, 0.01)
    direction = np.array([0.3, -0.2, 0.9])
    direction /= np.linalg.norm(direction)
    e = 1e-3  # 1 mg norm error
    acc = np.tile((1 + e) * direction, (t.size, 1))
    res = displacement_integration(acc, t)
    assert res.final[2] == pytest.approx(0.5 * e * STANDARD_GRAVITY * t[-1] ** 2, rel=1e-9)
    assert np.allclose(res.final[:2], 0, atol=1e-6)
    assert np.allclose(levelling_rotation(direction) @ direction, [0, 0, 1])
    # levelling over the first second only: a later tilt of 0.1° shows up horizontally
    tilt = np.deg2rad(0.1)
    later = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    acc2 = np.where(t[:, None] < 100, np.array([0.0, 0.0, 1.0]), later)
    res2 = displacement_integration(acc2, t, align_s=1.0)
    assert res2.final[0] == pytest.approx(0.5 * np.sin(tilt) * STANDARD_GRAVITY * 100**2, rel=1e-3)
