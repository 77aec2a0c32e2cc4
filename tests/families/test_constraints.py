"""User constraints: a fixed parameter stays at its value with zero standard error, a bound holds and is
reported when active, the covariance is that of the free subspace, and both round-trip through the file."""

from __future__ import annotations

import json

import numpy as np
import pytest

import optcal
from optcal.core.constraints import (
    ParameterConstraints,
    constrained_covariance,
    parameter_value,
    parse_cli,
    physical_of_theta,
)
from optcal.core.model import LumpedModel
from optcal.errors import InputError
from optcal.families.accel.result import CalibrationResult
from optcal.families.simulate.poses import simulate_poses, uniform_directions
from optcal.report.parameters import result_parameters

from helpers.cli_run import run_args


@pytest.fixture(scope="module")
def poses() -> optcal.PoseTable:
    return simulate_poses(optcal.lu2017_reference_model(), uniform_directions(60, np.random.default_rng(5)), 0.003,
                          rng=np.random.default_rng(6))


@pytest.fixture(scope="module")
def free(poses: optcal.PoseTable) -> CalibrationResult:
    return optcal.calibrate(poses)


def test_physical_parameters_in_closed_form_match_the_model(free: CalibrationResult) -> None:
    phys = LumpedModel.from_theta(free.params).physical()
    values = physical_of_theta(free.params)
    np.testing.assert_allclose(values[:3], phys.scale, rtol=1e-12)
    np.testing.assert_allclose(values[3:], np.rad2deg([phys.rho, phys.phi, phys.lam]), atol=1e-12)


def test_fixed_parameters_stay_at_their_value_with_zero_standard_error(poses, free) -> None:
    se = np.sqrt(np.diag(free.covariance))
    o_x = free.params[6] + 4 * se[6]  # a value the data would not choose
    s_y = parameter_value(free.params, "S_y") * 1.002
    fixed = optcal.calibrate(poses, fix={"o_x": o_x, "scale_y": s_y})
    assert fixed.params[6] == pytest.approx(o_x, rel=1e-12)
    assert parameter_value(fixed.params, "S_y") == pytest.approx(s_y, rel=1e-9)
    fixed_se = np.sqrt(np.clip(np.diag(fixed.covariance), 0, None))
    assert fixed_se[6] <= 1e-9 * se[6]
    engineering = {q.symbol: q for q in result_parameters(fixed).rows}
    assert engineering["S_y"].stderr <= 1e-6 * result_parameters(free).scale[1].stderr
    assert engineering["S_x"].stderr > 0.5 * result_parameters(free).scale[0].stderr  # the free ones keep theirs
    held = fixed.extra["constraints"]
    assert held["fixed"] == {"o_x": o_x, "S_y": s_y} and "free subspace" in held["covariance"]
    assert fixed.identifiability is not None and fixed.identifiability.constrained == ["o_x", "S_y"]
    assert "held by the user" in fixed.identifiability.describe()


def test_a_bound_holds_and_is_reported_active_with_its_effect_on_the_covariance(poses, free) -> None:
    rho = parameter_value(free.params, "rho")
    high = rho - 0.3  # degrees: below the free optimum, so the bound binds
    bounded = optcal.calibrate(poses, bounds={"rho": (-10.0, high), "o_z": (-1.0, 1.0)})
    assert parameter_value(bounded.params, "rho") <= high + 1e-7
    held = bounded.extra["constraints"]
    assert held["active"] == {"rho": "high"}  # o_z's wide bound is inactive
    assert any("rho" in note and "active at its high end" in note for note in bounded.notes)
    assert "rho held" in held["covariance"]
    engineering = {q.symbol: q for q in result_parameters(bounded).rows}
    assert engineering["ρ"].stderr <= 1e-6
    inactive = optcal.calibrate(poses, bounds={"rho": (rho - 5, rho + 5)})
    np.testing.assert_allclose(inactive.params, free.params, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(inactive.covariance, free.covariance, rtol=1e-6, atol=1e-18)
    assert inactive.extra["constraints"]["active"] == {}


def test_constraints_round_trip_through_the_saved_calibration(poses, free, tmp_path) -> None:
    result = optcal.calibrate(poses, fix={"o_y": float(free.params[7])}, bounds={"S_z": (0.0, np.inf), "phi": (-1.0, 1.0)},
                              solver="sqpmethod")
    path = tmp_path / "cal.json"
    result.save(path)
    loaded = CalibrationResult.load(path)
    assert loaded.constraints == result.constraints == ParameterConstraints.of(
        {"o_y": float(free.params[7])}, {"S_z": (0.0, np.inf), "phi": (-1.0, 1.0)})
    assert loaded.extra["constraints"] == result.extra["constraints"]
    assert loaded.solver == result.solver and loaded.solver.name == "sqpmethod"
    np.testing.assert_array_equal(loaded.covariance, result.covariance)
    saved = json.loads(path.read_text())
    assert saved["constraints"]["fixed"] == {"o_y": float(free.params[7])}
    assert saved["constraints"]["bounds"]["S_z"] == [0.0, "inf"]
    assert saved["solver"]["name"] == "sqpmethod" and saved["solver"]["iterations"] >= 1


def test_bad_constraints_are_refused() -> None:
    with pytest.raises(InputError, match="unknown parameter 'T_xy'"):
        ParameterConstraints.of({"T_xy": 1.0})
    with pytest.raises(InputError, match="empty bound"):
        ParameterConstraints.of(bounds={"S_x": (2.0, 1.0)})
    with pytest.raises(InputError, match="both fixed and bounded"):
        ParameterConstraints.of({"rho": 0.1}, {"ρ": (0, 1)})
    with pytest.raises(InputError, match="LOW:HIGH"):
        parse_cli((), ("S_x=3",))
    assert parse_cli(("o_x=2",), ("S_x=:16500",)) == ParameterConstraints.of({"o_x": 2.0}, {"S_x": (-np.inf, 16500.0)})


def test_constrained_covariance_is_the_inverse_information_on_the_free_subspace() -> None:
    rng = np.random.default_rng(1)
    J = rng.standard_normal((40, 4))
    F = J.T @ J
    G = np.array([[0.0, 1.0, 0.0, 0.0]])  # hold the second parameter
    cov = constrained_covariance(F, G)
    expected = np.zeros((4, 4))
    keep = [0, 2, 3]
    expected[np.ix_(keep, keep)] = np.linalg.inv(F[np.ix_(keep, keep)])
    np.testing.assert_allclose(cov, expected, atol=1e-12)


def test_cli_fix_and_bound_with_a_solver_by_name(tmp_path, capsys, poses, free) -> None:
    data = tmp_path / "poses.csv"
    np.savetxt(data, poses.acc, delimiter=",", header="ax,ay,az", comments="")
    out = tmp_path / "cal.json"
    code, stdout, err = run_args(capsys, "calibrate", str(data), "--json", "-o", str(out), "--solver", "uno",
                                 "--solver-option", "uno.max_iterations=100", "--fix", f"o_x={free.params[6]:.12g}",
                                 "--bound", "rho=:0", "--conic-solver", "SCS")
    assert code == 0, err
    summary = json.loads(stdout)
    assert summary["solver"]["name"] == "uno" and summary["solver"]["iterations"] >= 1
    assert summary["constraints"]["fixed"] == {"o_x": float(f"{free.params[6]:.12g}")}
    assert summary["stderr"]["o_x"] <= 1e-9
    assert CalibrationResult.load(out).constraints.bounds == {"rho": (-np.inf, 0.0)}
    for args, message in ((["--solver", "knitro"], "NLP solver 'knitro' is not available"),
                          (["--conic-solver", "HIGHS"], "does not take the fit's semidefinite constraint"),
                          (["--method", "gd", "--solver", "sqpmethod"], "not to gd"),
                          (["--method", "svd", "--fix", "o_x=1"], "not to svd"),
                          (["--fix", "zz=1"], "unknown parameter 'zz'")):
        code, stdout, err = run_args(capsys, "calibrate", str(data), *args)
        assert code == 2 and err.startswith("error: ") and message in err and err.count("\n") == 1, err
