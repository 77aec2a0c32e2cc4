"""Solver failures raise SolverError, early stops warn ConvergenceWarning, data problems stay FitError.

Library messages name Python arguments; the command line prints its flags instead, exit code 2 for
bad input, 3 for a solver failure, and one ``warning:`` line for an early stop.
"""

import warnings

import numpy as np
import pytest

from optcal import calibrate
from optcal.cli.main import EXIT_INPUT_ERROR, EXIT_SOLVER_ERROR, main
from optcal.errors import ConvergenceWarning, FitError, IdentifiabilityError, InputError, SolverError
from optcal.families.accel.mle import ML_PROBLEMS
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS
from optcal.families.simulate.poses import cap_directions, lu2017_sweeps, simulate_poses, uniform_directions

from helpers.common import rngs


@pytest.fixture
def poses(lu_model):
    rd, rn = rngs(21)
    return simulate_poses(lu_model, uniform_directions(23, rd), 0.003, rng=rn)


def test_error_classes_say_whose_fault_it_is():
    assert issubclass(FitError, InputError) and issubclass(IdentifiabilityError, InputError)
    assert not issubclass(SolverError, InputError)
    assert issubclass(ConvergenceWarning, Warning)


@pytest.mark.parametrize("method, settings, advice", [
    ("mle", {"ipopt_options": {"ipopt.max_iter": 1}}, "ipopt_options={'ipopt.max_iter'"),
    ("exact", {"ipopt_options": {"ipopt.max_iter": 2}}, "ipopt_options={'ipopt.max_iter'"),
    ("gd", {"max_iter": 5}, "max_iter"),
    ("convex", {"solver_options": {"max_iter": 2}}, "solver_options"),
])
def test_an_early_stop_warns_and_returns_the_last_iterate(poses, method, settings, advice):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = calibrate(poses, method=method, **settings)
    ours = [w for w in caught if issubclass(w.category, ConvergenceWarning)]
    assert len(ours) == 1 and f"the {method} fit did not converge" in str(ours[0].message)
    assert advice in str(ours[0].message)
    assert not [w for w in caught if "Solution may be inaccurate" in str(w.message)]  # said once, by optcal
    assert not result.solver.success and np.all(np.isfinite(result.params))
    assert not any("converge" in n or "success" in n for n in result.notes)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the converged fit warns nothing
        assert calibrate(poses, method=method).solver.success


def test_a_diverging_gradient_descent_is_a_solver_error(poses):
    with pytest.raises(SolverError, match=r"diverged.*step='auto'") as info:
        calibrate(poses, method="gd", step=50.0)
    assert not isinstance(info.value, InputError)


def test_an_ipopt_error_status_is_a_solver_error_and_a_refused_option_bad_input(poses):
    """MA57 is a valid IPOPT setting whose library (HSL) the CasADi wheel does not ship: IPOPT starts,
    then ends with the error status Invalid_Option.  An unknown setting is refused before any solve."""
    with pytest.raises(SolverError, match=r"Invalid_Option.*ipopt_options"):
        calibrate(poses, method="mle", ipopt_options={"ipopt.linear_solver": "ma57"})
    with pytest.raises(InputError, match="IPOPT refused the options.*ipopt_options"):
        calibrate(poses, method="mle", ipopt_options={"ipopt.linear_solver": "no_such_solver"})


def test_data_that_cannot_determine_the_fit_stay_fit_errors(lu_model):
    # a 20° cap with 10 mg noise: the SVD fit is a hyperboloid (the case of test_estimators)
    rd, rn = np.random.default_rng([1, 1]), np.random.default_rng([1, 2])
    cap = simulate_poses(lu_model, cap_directions(30, 20, rd), 0.01, rng=rn)
    with pytest.raises(FitError, match='hyperboloid.*method="convex"'):
        calibrate(cap, method="svd", allow_degenerate=True)


@pytest.fixture
def pose_csv(tmp_path, poses):
    path = tmp_path / "poses.csv"
    path.write_text("ax,ay,az\n" + "\n".join(",".join(f"{v:.12g}" for v in row) for row in poses.acc) + "\n")
    return path


@pytest.fixture
def ipopt_defaults(monkeypatch):
    """Change the ML problems' IPOPT defaults for one test (the built problems are dropped around it)."""
    ML_PROBLEMS.clear()
    yield lambda key, value: monkeypatch.setitem(SCALED_COST_IPOPT_OPTIONS, key, value)
    monkeypatch.undo()
    ML_PROBLEMS.clear()


def test_cli_solver_failure_is_one_line_and_exit_3(capsys, pose_csv, ipopt_defaults):
    ipopt_defaults("ipopt.linear_solver", "ma57")
    code = main(["calibrate", str(pose_csv)])
    _, err = capsys.readouterr()
    assert code == EXIT_SOLVER_ERROR == 3
    assert err.startswith("error: the mle fit failed") and err.count("\n") == 1 and "Traceback" not in err
    assert err.rstrip().endswith("--method convex")  # the library's method="convex", as the CLI spells it


def test_cli_early_stop_is_one_warning_line(capsys, pose_csv, ipopt_defaults):
    for key, value in (("ipopt.max_iter", 1), ("ipopt.tol", 1e-30), ("ipopt.acceptable_tol", 1e-30)):
        ipopt_defaults(key, value)  # the convex start is not optimal to 1e-30 after one iteration
    code = main(["calibrate", str(pose_csv), "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert err.startswith("warning: the mle fit did not converge") and err.count("\n") == 1
    assert '"success": false' in out


def test_cli_prints_flags_where_the_library_names_arguments(capsys, tmp_path, lu_model):
    poses = simulate_poses(lu_model, lu2017_sweeps(20), 0.001, rng=np.random.default_rng(2))
    with pytest.raises(IdentifiabilityError, match="allow_degenerate=True"):
        calibrate(poses)
    path = tmp_path / "degenerate.csv"
    path.write_text("ax,ay,az\n" + "\n".join(",".join(f"{v:.12g}" for v in row) for row in poses.acc) + "\n")
    code = main(["calibrate", str(path)])
    _, err = capsys.readouterr()
    assert code == EXIT_INPUT_ERROR == 2
    assert "--allow-degenerate" in err and "allow_degenerate=True" not in err
