"""The accelerometer's CalibrationResult (optcal.families.accel.result): JSON round trip, summary, correct(), typed fields."""

import json

import numpy as np
import pytest

import optcal.families.calibration_files as calibration_files
from optcal import calibrate
from optcal.core.fit_result import chi_square
from optcal.core.identifiability import IdentifiabilityReport
from optcal.errors import InputError
from optcal.families.accel.result import CalibrationResult
from optcal.families.caltypes import LumpedCalibration, SixPositionCalibration
from optcal.families.simulate.poses import simulate_poses, tilted_sweeps


@pytest.fixture
def result(lu_model):
    poses = simulate_poses(lu_model, tilted_sweeps(20), 0.005, rng=np.random.default_rng(1))
    return calibrate(poses, method="mle")


def test_json_round_trip(result, tmp_path):
    path = tmp_path / "cal.json"
    result.save(path)
    back = CalibrationResult.load(path)
    np.testing.assert_array_equal(back.T, result.T)
    np.testing.assert_array_equal(back.o, result.o)
    np.testing.assert_array_equal(back.covariance, result.covariance)
    np.testing.assert_array_equal(back.residuals, result.residuals)
    assert back.solver == result.solver
    assert back.summary() == result.summary()
    assert back == result
    data = json.loads(path.read_text())
    assert data["format_version"] == "2.0" and data["cal_type"] == "lumped"
    # the file is a calibration of its type with the fit's statistics attached
    cal = calibration_files.load(path)
    assert cal == result.calibration
    np.testing.assert_array_equal(cal.correct(result.fitted_on.acc), result.correct(result.fitted_on.acc))


def test_equality_compares_values(result):
    other = CalibrationResult.from_dict(json.loads(json.dumps(result.to_dict())))
    assert other == result
    other.o = other.o + 1e-12
    assert other != result


def test_format_1_files_still_load(result, tmp_path):
    """A file as optcal 0.1 wrote it: integer version, no cal_type, no fitted poses."""
    old = {
        "format_version": 1,
        "method": result.method,
        "units": {"input": "g", "output": "g", "T": "g per g", "o": "g"},
        "T": result.T.tolist(),
        "o": result.o.tolist(),
        "params_vector": result.params.tolist(),
        "param_names": result.param_names,
        "covariance": result.covariance.tolist(),
        "residuals": result.residuals.tolist(),
        "weights": result.weights.tolist(),
        "sigma_known": result.sigma_known,
        "solver": result.solver.to_dict(),
        "rows": [int(r) for r in result.rows],
    }
    path = tmp_path / "old.json"
    path.write_text(json.dumps(old))
    back = CalibrationResult.load(path)
    np.testing.assert_array_equal(back.T, result.T)
    assert back.calibration == LumpedCalibration(result.T, result.o, "g")
    assert calibration_files.load(path) == LumpedCalibration(result.T, result.o, "g")


def test_calibration_is_typed(result):
    assert isinstance(result.calibration, LumpedCalibration)
    assert result.fitted_on is not None and result.fitted_on.n == result.n_poses
    np.testing.assert_array_equal(result.calibration.theta, result.params)


def test_summary_is_strict_json(result):
    s = json.dumps(result.summary(), allow_nan=False)
    d = json.loads(s)
    for key in ("method", "T", "o", "A", "stderr", "rms_norm_residual_g", "n_poses", "solver", "aic", "bic"):
        assert key in d
    assert set(d["solver"]) >= {"name", "status", "iterations", "solve_time_s"}
    assert np.asarray(d["T"]).shape == (3, 3)


def test_correct_gives_unit_norm(result, lu_model):
    d = np.array([[0.0, 0.0, 1.0], [0.6, 0.8, 0.0]])
    cal = result.correct(lu_model.measure(d))
    np.testing.assert_allclose(np.linalg.norm(cal, axis=1), 1.0, atol=0.01)
    with pytest.raises(InputError):
        result.correct(np.ones((2, 2)))


def test_statistics(result):
    n, p = result.n_poses, result.n_params
    assert result.dof == n - p
    assert result.bic - result.aic == pytest.approx(p * (np.log(n) - 2))
    assert result.chisqr == pytest.approx(np.sum(result.weights * result.residuals**2))


def test_load_rejects_bad_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="not a JSON"):
        CalibrationResult.load(bad)
    bad.write_text('{"format_version": 99}')
    with pytest.raises(InputError, match="format version 99"):
        CalibrationResult.load(bad)
    bad.write_text('{"format_version": 1}')
    with pytest.raises(InputError, match="not an optcal calibration"):
        CalibrationResult.load(bad)




def test_typed_fields_of_a_fit(result):
    assert isinstance(result.identifiability, IdentifiabilityReport) and result.identifiability.identifiable
    assert result.n_observations == result.n_poses
    assert result.chisqr == chi_square(result.residuals, result.weights)
    assert not result.is_six_position and result.W is None and result.V is None


def test_calibration_type_comes_from_the_fields_not_the_parameter_names(result):
    """A result's calibration is six-position exactly when it carries W and V, whatever its parameters are called."""
    W = result.T + 1e-3 * np.arange(9.0).reshape(3, 3)
    V = -W @ result.o
    renamed = CalibrationResult(**{**vars(result), "param_names": [f"p{k}" for k in range(9)], "W": W, "V": V})
    assert isinstance(renamed.calibration, SixPositionCalibration)
    np.testing.assert_array_equal(renamed.calibration.W, W)
    named_like_sixpos = CalibrationResult(**{**vars(result), "param_names": ["W_xx", *result.param_names[1:]]})
    assert isinstance(named_like_sixpos.calibration, LumpedCalibration)
    with pytest.raises(ValueError, match="both W and V"):
        CalibrationResult(**{**vars(result), "W": W})
