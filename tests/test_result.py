"""CalibrationResult: JSON round trip, summary, report, correct()."""

import json

import numpy as np
import pytest

from optcal import calibrate
from optcal.errors import InputError
from optcal.result import CalibrationResult
from optcal.simulate import simulate_poses, tilted_sweeps


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
    assert json.loads(path.read_text())["format_version"] == 1


def test_summary_is_strict_json(result):
    s = json.dumps(result.summary(), allow_nan=False)
    d = json.loads(s)
    for key in ("method", "T", "o", "A", "stderr", "rms_norm_residual_g", "n_poses", "solver", "aic", "bic"):
        assert key in d
    assert set(d["solver"]) >= {"name", "status", "iterations", "solve_time_s"}
    assert np.asarray(d["T"]).shape == (3, 3)


def test_report_mentions_parameters(result):
    text = result.report()
    for name in result.param_names:
        assert name in text
    assert "IPOPT" in text


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


def test_pose_table_copies_extra_columns():
    from optcal.poses import PoseTable

    col = np.arange(9.0)
    table = PoseTable(acc=np.eye(3)[np.arange(9) % 3], extra={"roll_deg": col})
    table.extra["roll_deg"][0] = 99.0
    assert col[0] == 0.0
