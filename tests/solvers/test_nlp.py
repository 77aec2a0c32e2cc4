"""The NLP builder of optcal.solvers.nlp: reference problems with known optima, refused options, plugins, caches.

Every nonlinear program of optcal is built by :func:`nlp_solver` or :class:`CallbackNLP`; here each
form solves a problem whose optimum is known in closed form, options the plugin refuses are an
``InputError`` that names them, and a built problem is shared through its cache.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from optcal.core.fit_result import SolverInfo
from optcal.errors import ConvergenceWarning, InputError, SolverError
from optcal.solvers.cache import freeze_options, problem_cache
from optcal.solvers.convergence import Remedy, check_solver, solver_record
from optcal.solvers.nlp import (
    IPOPT_DEFAULTS,
    MIN_RESIDUAL_RMS,
    CallbackNLP,
    NumpyObjective,
    cost_scale,
    nlp_solver,
)


def rosenbrock(x: np.ndarray) -> float:
    return float((1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2)


def rosenbrock_gradient(x: np.ndarray) -> tuple[float, np.ndarray]:
    return rosenbrock(x), np.array([-2 * (1 - x[0]) - 400 * x[0] * (x[1] - x[0] ** 2), 200 * (x[1] - x[0] ** 2)])


def rosenbrock_hessian(x: np.ndarray, lam_f: float) -> np.ndarray:
    return lam_f * np.array([[2 - 400 * (x[1] - 3 * x[0] ** 2), -400 * x[0]], [-400 * x[0], 200.0]])


def rosenbrock_sx() -> dict:
    import casadi as ca

    x = ca.SX.sym("x", 2)
    return {"x": x, "f": (1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2}


def test_symbolic_rosenbrock_reaches_its_optimum():
    x, stats = nlp_solver("rosenbrock", rosenbrock_sx()).solve(x0=[-1.2, 1.0])
    assert stats["success"] and stats["return_status"] == "Solve_Succeeded"
    np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-9)


def test_callback_rosenbrock_with_numpy_derivatives_reaches_its_optimum():
    nlp = CallbackNLP("rosenbrock_numpy", 2, hessian_block_size=2)
    x, stats = nlp.solve(NumpyObjective(rosenbrock, rosenbrock_gradient, rosenbrock_hessian), x0=np.array([-1.2, 1.0]))
    assert stats["success"]
    np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-9)


def test_separable_least_squares_with_block_hessian_equals_lstsq():
    """Three independent least-squares problems in one NLP with a block-diagonal Hessian (as the batched ML)."""
    rng = np.random.default_rng(4)
    A = rng.standard_normal((3, 20, 4))
    b = rng.standard_normal((3, 20))

    def value(x: np.ndarray) -> float:
        r = A @ x.reshape(3, 4, 1) - b[..., None]
        return float(np.sum(r**2))

    def gradient(x: np.ndarray) -> tuple[float, np.ndarray]:
        r = A @ x.reshape(3, 4, 1) - b[..., None]
        return float(np.sum(r**2)), (2 * np.swapaxes(A, 1, 2) @ r).ravel()

    nlp = CallbackNLP("separable_lsq", 12, hessian_block_size=4)
    blocks = 2 * np.swapaxes(A, 1, 2) @ A
    x, stats = nlp.solve(NumpyObjective(value, gradient, lambda x, lam_f: blocks * lam_f), x0=np.zeros(12))
    assert stats["success"]
    for j in range(3):
        np.testing.assert_allclose(x[4 * j:4 * j + 4], np.linalg.lstsq(A[j], b[j], rcond=None)[0], rtol=1e-8, atol=1e-10)


def test_constrained_callback_problem_without_hessian():
    """max c·x on the unit sphere (limited-memory Hessian, an equality constraint): x = c/‖c‖."""
    c = np.array([1.0, -2.0, 2.0])
    nlp = CallbackNLP("sphere", 3, constraints=lambda x: x[0] ** 2 + x[1] ** 2 + x[2] ** 2 - 1.0,
                      tuning={"ipopt.hessian_approximation": "limited-memory"})
    x, stats = nlp.solve(NumpyObjective(lambda x: float(-c @ x), lambda x: (float(-c @ x), -c)),
                         x0=np.array([0.6, 0.0, 0.8]), lbg=0.0, ubg=0.0)
    assert stats["success"]
    np.testing.assert_allclose(x, c / 3.0, atol=1e-7)


def test_another_plugin_by_name_without_the_ipopt_defaults():
    """sqpmethod (CasADi's SQP with its own QP solver): IPOPT's defaults and tuning are not handed to it."""
    quiet = {"print_header": False, "print_iteration": False, "print_status": False, "print_time": False,
             "qpsol": "qrqp", "qpsol_options": {"print_iter": False, "print_header": False, "print_info": False}}
    x, stats = nlp_solver("rosenbrock_sqp", rosenbrock_sx(), {"ipopt.tol": 1e-12}, solver="sqpmethod",
                          solver_options=quiet).solve(x0=[-1.2, 1.0])
    assert stats["success"]
    np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-6)
    with pytest.raises(InputError, match="no_such_plugin"):
        nlp_solver("rosenbrock", rosenbrock_sx(), solver="no_such_plugin")


@pytest.mark.parametrize("options, name", [
    ({"ipopt.tol": -1.0}, "ipopt.tol"),  # IPOPT says only "Invalid options were detected"
    ({"ipopt.mu_strategy": "bogus"}, "ipopt.mu_strategy"),
    ({"ipopt.max_iter": "many"}, "ipopt.max_iter"),  # a type CasADi cannot pass on
    ({"ipopt.no_such_option": 1}, "ipopt.no_such_option"),
    ({"no_such_casadi_option": 1}, "no_such_casadi_option"),
    ({"print_time": "sometimes"}, "print_time"),
])
def test_a_refused_option_is_bad_input_naming_the_option_and_the_argument(options, name):
    good = {"ipopt.max_iter": 50}
    with pytest.raises(InputError) as info:
        nlp_solver("rosenbrock", rosenbrock_sx(), solver_options={**good, **options}, options_argument="solver_options")
    message = str(info.value)
    assert message.startswith("IPOPT refused the options") and message.endswith("check solver_options")
    assert repr(name) in message and "'ipopt.max_iter': 50" not in message  # the refused one, not the good one


def test_a_failing_evaluation_is_a_failure_status_and_a_raising_solver_a_solver_error():
    """IPOPT turns an exception in a callback into its Invalid_Number_Detected status (a failure of
    optcal.solvers.convergence.SOLVER_FAILURES); an exception out of the solver itself is a SolverError."""
    from optcal.solvers.convergence import SOLVER_FAILURES

    def broken(x: np.ndarray) -> float:
        raise FloatingPointError("the data went away")

    nlp = CallbackNLP("broken", 2, hessian_block_size=2)
    objective = NumpyObjective(broken, rosenbrock_gradient, rosenbrock_hessian)
    _, stats = nlp.solve(objective, x0=np.zeros(2))
    assert not stats["success"] and stats["return_status"] in SOLVER_FAILURES
    with pytest.raises(SolverError, match="IPOPT raised an error in broken"):
        nlp.solve(objective, x0=np.zeros(5))  # three variables too many


def test_the_cache_returns_the_same_solver_for_the_same_structure():
    def build(n: int, options: tuple) -> object:
        import casadi as ca

        x = ca.SX.sym("x", n)
        return nlp_solver(f"quadratic_{n}", {"x": x, "f": ca.sumsqr(x - 1)}, solver_options=dict(options))

    cache = problem_cache(build, maxsize=4)
    a = cache.get(3, freeze_options({"ipopt.max_iter": 20}))
    assert cache.get(3, freeze_options({"ipopt.max_iter": 20})) is a
    assert cache.get(4, freeze_options({"ipopt.max_iter": 20})) is not a
    assert cache.get(3, freeze_options({"ipopt.max_iter": 30})) is not a
    x, _ = a.solve(x0=np.zeros(3))
    np.testing.assert_allclose(x, 1.0, atol=1e-9)
    with pytest.raises(InputError, match="ipopt.tol"):
        cache.get(3, freeze_options({"ipopt.tol": -1.0}))
    assert len(cache) == 3  # the refused problem was not kept


def test_one_set_of_ipopt_defaults():
    assert IPOPT_DEFAULTS["ipopt.print_level"] == 0 and IPOPT_DEFAULTS["ipopt.mu_strategy"] == "adaptive"
    assert all(key.startswith("ipopt.") or key == "print_time" for key in IPOPT_DEFAULTS)


def test_cost_scale_of_one_problem_and_of_a_stack():
    assert cost_scale(10, 0.5) == pytest.approx(0.2)
    assert cost_scale(10, 0.0) == 1.0 / (10 * MIN_RESIDUAL_RMS)
    np.testing.assert_allclose(cost_scale(10, np.array([0.5, 0.0])), [0.2, 1.0 / (10 * MIN_RESIDUAL_RMS)])


def test_solver_record_and_convergence_check():
    stats = {"return_status": "Maximum_Iterations_Exceeded", "success": False, "iter_count": 7}
    record = solver_record(stats, 0.25, "IPOPT", "a test")
    assert record == SolverInfo("IPOPT", "Maximum_Iterations_Exceeded", False, 7, 0.25, "a test")
    assert solver_record(stats, 0.25, iterations=12).iterations == 12
    remedy = Remedy(stopped_early="raise max_iter", failed="try another method")
    with pytest.warns(ConvergenceWarning, match="did not converge.*after 7 iterations.*raise max_iter"):
        check_solver("test", record, np.ones(3), remedy)
    with pytest.raises(SolverError, match="non-finite answer; try another method"):
        check_solver("test", record, np.array([1.0, np.nan]), remedy)
    failed = solver_record({"return_status": "Invalid_Option", "success": False, "iter_count": 0}, 0.0)
    with pytest.raises(SolverError, match="'Invalid_Option'"):
        check_solver("test", failed, np.ones(3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_solver("test", solver_record({"return_status": "Solve_Succeeded", "success": True}, 0.0), np.ones(3))
