"""--solver, --solver-option, --conic-solver, --fix and --bound on diagnose and fleet (calibrate's are in
tests/families/test_constraints.py), and the fleet's estimator settings on its units and its prior refit."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers.diagnosis_cases import make_case, write_table

from optcal.applications.fleet.inputs import expand_inputs
from optcal.applications.fleet.prior import PopulationPrior, fit_with_prior
from optcal.applications.fleet.synthetic import write_fleet
from optcal.applications.fleet.unit import fit_units, read_unit
from helpers.cli_run import run_args
from optcal.cli.main import main
from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import simulate_poses, six_position


def test_diagnose_calibrates_its_baseline_with_the_solver_and_constraints(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    case = make_case("temperature_bias", 27)
    path = write_table(case, tmp_path / "poses.csv")
    assert main(["diagnose", str(path), "--json", "--quiet", "--simulations", "0", "--effects", "none", "--folds", "2",
                 "--solver", "sqpmethod", "--bound", "rho=-10:10"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["settings"]["calibration"] == {"solver": "sqpmethod", "fix": {}, "bounds": {"rho": [-10.0, 10.0]}}
    code = main(["diagnose", str(path), "--quiet", "--simulations", "0", "--solver", "sqpmethod",
                 "--baseline", str(tmp_path / "cal.json")])
    err = capsys.readouterr().err
    assert code == 2 and "not with --baseline" in err and err.count("\n") == 1


def test_fleet_refuses_a_solver_before_starting_a_cluster(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    code = main(["fleet", str(tmp_path), "-o", str(tmp_path / "r.parquet"), "--solver", "nope"])
    err = capsys.readouterr().err
    assert code == 2 and "unknown NLP solver 'nope'" in err and err.count("\n") == 1


def test_fleet_units_fitted_with_the_solver_and_a_fixed_parameter(tmp_path: Path) -> None:
    write_fleet(tmp_path, 6, seed=4)
    units = expand_inputs([str(tmp_path)])
    data = [read_unit(u, {}) for u in units]
    default = fit_units(units, data)
    held = fit_units(units, data, {"solver": "sqpmethod", "fix": {"o_x": 0.0}})
    for a, b in zip(default, held):
        if a.theta is None:
            continue
        assert b.status == a.status and b.theta is not None and b.theta[6] == 0.0
        assert b.stderr is not None and b.stderr[6] <= 1e-12


def test_prior_refit_by_another_solver_reaches_ipopts_answer() -> None:
    model = LumpedModel.from_physical([1.01, 0.99, 1.02], 0.003, -0.002, 0.001, [0.02, -0.01, 0.03])
    poses = simulate_poses(model, np.repeat(six_position(), 2, axis=0), 0.002, rng=np.random.default_rng(1))
    prior = PopulationPrior(model.theta, np.diag([1e-4, 1e-5, 1e-4, 1e-5, 1e-5, 1e-4, 4e-4, 4e-4, 4e-4]), 50, "g", 0.001)
    ipopt = fit_with_prior(poses, prior)
    sqp = fit_with_prior(poses, prior, solver="sqpmethod")
    se = np.sqrt(np.diag(ipopt.result.covariance))
    assert sqp.result.solver.name == "sqpmethod" and sqp.result.solver.success
    assert np.max(np.abs(sqp.result.params - ipopt.result.params) / se) < 1e-4


# ----------------------------------------------------------------------------- plan: the refinement's solver
def test_plan_refines_with_the_solver_named(capsys) -> None:
    """The pose planner's refinement on the sphere is an NLP like the others: --solver names its plugin, the
    plan is the same (the relaxation's efficiency bound reached), an unknown one is refused in one line."""
    plans = {}
    for solver in ("ipopt", "sqpmethod"):
        code, out, err = run_args(capsys, "plan", "--poses", "12", "--solver", solver, "--json")
        assert code == 0, err
        plans[solver] = json.loads(out)
    assert plans["sqpmethod"]["efficiency"] == pytest.approx(plans["ipopt"]["efficiency"], abs=1e-4)
    assert plans["sqpmethod"]["refinement"] == "Solve_Succeeded"
    code, _, err = run_args(capsys, "plan", "--poses", "12", "--solver", "nosuch")
    assert code == 2 and "unknown NLP solver 'nosuch'" in err and len(err.strip().splitlines()) == 1
