"""Solvers by name: the catalogue, its probes, the refusals, and every plugin on imu_tk's Xsens log.

Acceptance (issue 29): on the Xsens log at least four NLP plugins besides IPOPT reach IPOPT's
optimum to 0.01 standard errors; Clarabel and SCS give the same convex fit to 1e-6.  Each
plugin's test skips cleanly where it does not run here.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

import optcal
from optcal.errors import InputError
from optcal.solvers.registry import (
    NLP_SOLVERS,
    SolverChoice,
    available_conic_solvers,
    available_nlp_solvers,
    choose_conic_solver,
    choose_nlp_solver,
    freeze,
    parse_solver_options,
    probe_nlp_solver,
    quiet_stdout,
    thaw,
)

#: Plugins other than IPOPT held to IPOPT's optimum on the Xsens log (the catalogue minus IPOPT,
#: sleqp (20 s on this log: its trust-region subproblem fails and recovers) and feasiblesqpmethod
#: (stops at 0.011 standard errors whatever its tolerances: its stopping test is on the step)).
XSENS_PLUGINS = ("sqpmethod", "sqpmethod+osqp", "sqpmethod+qpoases", "fatrop", "uno", "alpaqa", "bonmin")
#: 0.01 standard errors: the issue's acceptance.
STDERR_TOLERANCE = 0.01


@pytest.fixture(scope="module")
def xsens(shared_data_module: Path) -> tuple[optcal.PoseTable, optcal.families.accel.result.CalibrationResult]:  # type: ignore[name-defined]
    from optcal.data import load

    poses = load(shared_data_module / "imutk-xsens" / "xsens_imutk.csv")
    return poses, optcal.calibrate(poses)


@pytest.fixture(scope="module")
def shared_data_module() -> Path:
    from helpers.common import SHARED

    d = SHARED / "data"
    if not (d / "imutk-xsens" / "xsens_imutk.csv").exists():
        pytest.skip("../shared/data/imutk-xsens is not present")
    return d


def needs(name: str) -> None:
    probe = probe_nlp_solver(name)
    if not probe.available:
        pytest.skip(f"{name} does not run here: {probe.reason}")


@pytest.mark.parametrize("name", XSENS_PLUGINS)
def test_plugin_reaches_ipopts_optimum_on_the_xsens_log(xsens, name: str) -> None:
    needs(name)
    poses, reference = xsens
    result = optcal.calibrate(poses, solver=name)
    stderr = np.sqrt(np.diag(reference.covariance))
    # sqpmethod stops with "Search_Direction_Becomes_Too_Small" when it starts within a step below its minimum
    # of the optimum (the convex fit on the Xsens log's poses is that close): the distance to IPOPT's optimum,
    # asserted below, is what says it got there
    assert result.solver.success or result.solver.status == "Search_Direction_Becomes_Too_Small", result.solver
    # bonmin counts branch-and-bound nodes: 0 on a continuous problem
    assert result.solver.name == name and result.solver.iterations >= (name != "bonmin") and result.solver.solve_time_s > 0
    assert np.max(np.abs(result.params - reference.params) / stderr) <= STDERR_TOLERANCE


def test_at_least_four_plugins_besides_ipopt_run_here() -> None:
    """The issue's acceptance needs four: a wheel that ships fewer fails here, not silently."""
    running = [n for n in XSENS_PLUGINS if probe_nlp_solver(n).available]
    assert len(running) >= 4, running


def test_clarabel_and_scs_give_the_same_convex_fit(xsens) -> None:
    from optcal.families.accel.base import Normaliser
    from optcal.families.accel.ellipsoid import ConvexEllipsoidFit

    for name in ("CLARABEL", "SCS"):
        if name not in available_conic_solvers():
            pytest.skip(f"cvxpy has no {name}")
    poses, _ = xsens
    norm = Normaliser.of(poses.acc)
    fits = {name: ConvexEllipsoidFit(solver=name, polish=False).fit(poses) for name in ("CLARABEL", "SCS")}
    theta = {name: norm.theta_to_normalised(fit.params) for name, fit in fits.items()}  # entries of order one
    assert all(fit.solver.success for fit in fits.values())
    assert np.max(np.abs(theta["CLARABEL"] - theta["SCS"])) <= 1e-6


def test_unknown_unavailable_and_unsuited_solvers_are_refused_in_one_line() -> None:
    runs = available_nlp_solvers()
    with pytest.raises(InputError, match="unknown NLP solver 'nope'.*ipopt") as unknown:
        choose_nlp_solver("nope")
    assert "\n" not in str(unknown.value) and all(name in str(unknown.value) for name in runs)
    absent = [n for n in NLP_SOLVERS if not probe_nlp_solver(n).available]
    if absent:
        with pytest.raises(InputError, match=f"'{absent[0]}' is not available .*the ones that run here: ipopt"):
            choose_nlp_solver(absent[0])
    with pytest.raises(InputError, match="does not take the fit's semidefinite constraint|is not installed"):
        choose_conic_solver("OSQP")
    with pytest.raises(InputError, match="not installed.*suited ones installed: CLARABEL"):
        choose_conic_solver("NO_SUCH_SOLVER")
    assert choose_conic_solver("scs") == "SCS"


def test_probe_reports_a_missing_plugin_with_casadis_reason() -> None:
    assert probe_nlp_solver("ipopt").available
    assert not probe_nlp_solver("not-in-catalogue").available
    import casadi as ca

    if not ca.has_nlpsol("knitro"):
        assert "not installed" in probe_nlp_solver("knitro").reason


def test_solver_options_parse_freeze_and_thaw() -> None:
    options = parse_solver_options(["max_iter=50", "qpsol_options.print_iter=false", "ipopt.tol=1e-9", "name=abc"])
    assert options == {"max_iter": 50, "qpsol_options": {"print_iter": False}, "ipopt.tol": 1e-9, "name": "abc"}
    frozen = freeze(options)
    hash(frozen)
    assert thaw(frozen) == options
    with pytest.raises(InputError, match="KEY=VALUE"):
        parse_solver_options(["max_iter"])
    assert choose_nlp_solver(None) == SolverChoice()


def test_a_quiet_plugin_writes_nothing_to_the_standard_streams(capfd: pytest.CaptureFixture) -> None:
    """A plugin that prints whatever its options say (feasiblesqpmethod's debugging lines) is silenced."""
    needs("feasiblesqpmethod")
    from optcal.families.simulate.poses import simulate_poses, uniform_directions

    poses = simulate_poses(optcal.lu2017_reference_model(), uniform_directions(30, 1), 0.002, rng=3)
    capfd.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        optcal.calibrate(poses, solver="feasiblesqpmethod")
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    with quiet_stdout():
        os.write(1, b"hidden\n")
    assert capfd.readouterr().out == ""
