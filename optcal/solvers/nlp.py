"""The one place where optcal builds and runs CasADi NLP solvers.

Every nonlinear program of optcal (the accelerometer's maximum-likelihood problems, the
errors-in-variables problem, the gyroscope's problem, the fleet's problem with a population prior,
the pose planner's refinement on the sphere) is built here:

* :data:`IPOPT_DEFAULTS` — the IPOPT options every problem starts from, one set; a problem adds
  its own tuning on top (a tolerance, an iteration limit, a Hessian approximation), written next
  to the problem and said why, and the user's options go on top of both.
* :func:`cost_scale` and :data:`SCALED_COST_IPOPT_OPTIONS` — the scaling of a least-squares cost
  that lets one tolerance serve any number of residuals, noise level or units, and the IPOPT
  tolerances that go with it.
* :func:`nlp_solver` — ``casadi.nlpsol`` for a plugin named by the caller (``"ipopt"`` unless told
  otherwise); options the plugin refuses are an :class:`~optcal.errors.InputError` that names the
  option and the Python argument that carried it.  :meth:`NLPSolver.solve` runs it; an exception
  inside the solver is a :class:`~optcal.errors.SolverError`.
* :class:`CallbackNLP` — an NLP whose objective, gradient and Hessian are numpy functions handed
  to the plugin as CasADi callbacks (:func:`numpy_callback`): built once for a problem's size, it
  is solved with the functions of one data set at a time (:class:`NumpyObjective`).

The caches of built problems are :mod:`optcal.solvers.cache`; the solver's record and the
convergence check are :mod:`optcal.solvers.convergence`.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError, SolverError
from optcal.solvers.registry import NLP_SOLVERS, SolverChoice, choose_nlp_solver, plugin_accepts, quiet_stdout

#: The plugin of every optcal NLP unless the caller names another one.
DEFAULT_SOLVER: str = "ipopt"

#: The IPOPT options every optcal NLP starts from (a problem's own tuning and the user's options
#: override them):
#:
#: * ``print_level`` 0, ``sb`` (no banner), ``print_time`` off: a solve prints nothing;
#: * ``tol`` 1e-12, ``acceptable_tol`` 1e-9: IPOPT's scaled optimality error at the optimum, tight
#:   for the unscaled problems (the errors-in-variables problem loosens it to 1e-10);
#: * ``max_iter`` 200: the problems converge in 5-40 iterations from their algebraic starts;
#: * ``mu_strategy`` adaptive: the barrier parameter follows the progress (Nocedal, Wächter &
#:   Waltz 2009), fewer iterations than the monotone rule on these least-squares problems;
#: * ``honor_original_bounds`` yes: IPOPT relaxes every bound by ``bound_relax_factor`` (1e-8)
#:   while it iterates and, told so, returns its final point inside the user's bounds
#:   (:meth:`NLPSolver.solve` projects onto them for every plugin as well).
IPOPT_DEFAULTS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": 1e-12,
    "ipopt.acceptable_tol": 1e-9,
    "ipopt.max_iter": 200,
    "ipopt.mu_strategy": "adaptive",
    "ipopt.honor_original_bounds": "yes",
}

#: Largest move onto the bounds :meth:`NLPSolver.solve` accepts as a solver's own relaxation of
#: them, relative to ``max(1, |bound|)`` of the variables as the NLP states them (optcal scales its
#: unknowns to order one): IPOPT relaxes by ``bound_relax_factor`` 1e-8, the SQP plugins' QP
#: solvers by their feasibility tolerances (1e-8 to 1e-12).  A final point farther outside did not
#: solve the bounded problem; its projection is then no optimum and the solve is marked unsuccessful.
BOUND_RELAXATION_RTOL: float = 1e-6


#: Floor of the residual scale in :func:`cost_scale` (normalised units, ≈ g): 10 ng per g, far
#: below the noise of any accelerometer and far above rounding (≈ 1e-16).
MIN_RESIDUAL_RMS: float = 1e-8

#: IPOPT tuning of a cost scaled by :func:`cost_scale` (on top of :data:`IPOPT_DEFAULTS`): the
#: tolerance sits just above the rounding floor of the scaled cost.  That scaling keeps the
#: gradient at the start of order one, below IPOPT's gradient-based scaling threshold (100), so
#: that step is switched off (it would only cost a gradient evaluation); the multipliers of the
#: parameters are not needed.
SCALED_COST_IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.tol": 1e-10,
    "ipopt.acceptable_tol": 1e-5,
    "ipopt.acceptable_iter": 3,
    "ipopt.nlp_scaling_method": "none",
    "calc_lam_p": False,
}


@overload
def cost_scale(n: int, start_rms: float) -> float: ...
@overload
def cost_scale(n: int, start_rms: NDArray) -> float | NDArray[np.float64]: ...
def cost_scale(n: int, start_rms: float | NDArray) -> float | NDArray[np.float64]:
    """Factor ``c = 1/(n s₀)`` applied to a cost ``Σ ρ`` of n residuals (``s₀`` their rms at the start).

    IPOPT stops on the absolute size of the gradient, while the cost can only resolve a
    decrease of about ``eps·f``: with the raw cost a tolerance is either too loose for small
    residuals or out of floating-point reach for large ones (IPOPT then backtracks for tens of
    iterations on a solution that is already exact).  With ``f ≈ n s²`` and a Hessian
    ``≈ 2n``·O(1), scaling by ``1/(n s₀)`` makes ``f·λ(H)`` of order one whatever n, noise or
    units, so one tolerance (:data:`SCALED_COST_IPOPT_OPTIONS`) sits just above the rounding floor
    and leaves the parameters within ~1e-7·√n standard errors of the exact optimum.  ``s₀`` is
    floored at :data:`MIN_RESIDUAL_RMS` so that noise-free data (residuals at rounding level)
    are not scaled up into a spurious gradient.

    Parameters
    ----------
    n : int
        Residuals per problem.
    start_rms : float or ndarray
        Rms (standardised) residual at the start; an array gives one factor per problem.

    Returns
    -------
    float or ndarray
        ``c``, of the shape of ``start_rms``.
    """
    if np.ndim(start_rms) == 0:
        return 1.0 / (n * max(float(start_rms), MIN_RESIDUAL_RMS))
    return 1.0 / (n * np.maximum(np.asarray(start_rms, dtype=float), MIN_RESIDUAL_RMS))


def solver_label(solver: str) -> str:
    """How messages name a solver: ``"IPOPT"`` for ``"ipopt"``, otherwise its catalogue name."""
    return solver.upper() if solver == DEFAULT_SOLVER else solver


def plugin_defaults(solver: str) -> dict[str, Any]:
    """The options a solver starts from: :data:`IPOPT_DEFAULTS` for IPOPT, the catalogue's for another
    (:data:`optcal.solvers.registry.NLP_SOLVERS`), none for a plugin outside it."""
    if solver == DEFAULT_SOLVER:
        return dict(IPOPT_DEFAULTS)
    spec = NLP_SOLVERS.get(solver)
    return {"print_time": False, **(spec.defaults if spec else {})}


def as_choice(solver: str | SolverChoice | None, solver_options: Mapping[str, Any] | None = None,
              constraints: bool = False, callbacks: bool = False) -> SolverChoice:
    """A :class:`~optcal.solvers.registry.SolverChoice` from a name and the user's options (or as given)."""
    if isinstance(solver, SolverChoice):
        if solver_options or callbacks:
            merged = {**solver.user_option_dict(), **dict(solver_options or {})}
            return choose_nlp_solver(solver.name, merged, constraints=constraints, callbacks=callbacks)
        return solver
    return choose_nlp_solver(solver, solver_options, constraints=constraints, callbacks=callbacks)


@dataclass(frozen=True)
class NLPSolver:
    """A built CasADi ``nlpsol`` with the plugin that runs it.

    Attributes
    ----------
    function : casadi.Function
        The solver; it keeps the statistics of its last call, so a caller that shares it between
        threads holds a lock around :meth:`solve`.
    solver : str
        The plugin (``"ipopt"``).
    """

    function: Any
    solver: str = DEFAULT_SOLVER
    writes_stdout: bool = False

    def solve(self, **args: Any) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Run the solver (``x0``, ``p``, ``lbx``, ``ubx``, ``lbg``, ``ubg``) and read its statistics.

        Returns
        -------
        x : ndarray
            The last iterate, flattened.
        stats : dict
            The plugin's statistics (``return_status``, ``success``, ``iter_count``, ...).

        Raises
        ------
        SolverError
            The solver raised an exception (an error inside a callback, a failed factorisation).
        """
        spec = NLP_SOLVERS.get(self.solver)
        if spec is not None and spec.no_bounds and _has_bounds(args):
            runs = [name for name, other in NLP_SOLVERS.items() if not other.no_bounds][:4]
            raise InputError(f"{solver_label(self.solver)} cannot solve a problem with bounds: {spec.no_bounds}; choose "
                             f"another solver (--solver {' / '.join(runs)}) or drop the bounds (--bound)")
        try:
            if self.writes_stdout:
                with quiet_stdout():
                    sol = self.function(**args)
            else:
                sol = self.function(**args)
        except RuntimeError as exc:
            reason = str(exc).strip().splitlines()[-1]
            raise SolverError(f"{solver_label(self.solver)} raised an error in {self.function.name()}: {reason}") from exc
        try:
            stats = self.function.stats()
        except RuntimeError as exc:  # CasADi 3.7's sqpmethod can leave its status unset ("construction from null")
            reason = " ".join(str(exc).strip().splitlines()[-1].split())
            stats = {"return_status": f"no statistics ({reason})", "success": False}
        x, moved, beyond = project_to_bounds(np.asarray(sol["x"]).ravel(), args.get("lbx"), args.get("ubx"))
        if moved > 0:
            stats = {**stats, "bound_projection": moved}
        if beyond:
            stats = {**stats, "success": False,
                     "return_status": f"{stats.get('return_status', '')}; its point lay {moved:.3g} outside the bounds "
                                      f"(more than the relaxation {BOUND_RELAXATION_RTOL:g}): projected onto them"}
        return x, stats


def _has_bounds(args: Mapping[str, Any]) -> bool:
    """Whether the solve's ``lbx`` or ``ubx`` bound any unknown (a finite entry)."""
    return any(args.get(key) is not None and bool(np.any(np.isfinite(np.asarray(args[key], dtype=float))))
               for key in ("lbx", "ubx"))


def project_to_bounds(x: NDArray[np.float64], lbx: Any = None, ubx: Any = None) -> tuple[NDArray[np.float64], float, bool]:
    """``x`` projected onto the box ``lbx ≤ x ≤ ubx`` (absent: unbounded), the largest move and whether it was
    more than a solver's relaxation of its bounds (:data:`BOUND_RELAXATION_RTOL`).

    A solver may return a point just outside its bounds (IPOPT relaxes them by ``bound_relax_factor``);
    the user's bound then holds exactly at the returned point.
    """
    x = np.asarray(x, dtype=float)
    lo, hi = _box_side(lbx, -np.inf, x.size), _box_side(ubx, np.inf, x.size)
    projected = np.minimum(np.maximum(x, lo), hi)
    move = np.abs(projected - x)
    if not np.any(move > 0):
        return x, 0.0, False
    bound = np.where(x < lo, lo, hi)
    beyond = bool(np.any(move > BOUND_RELAXATION_RTOL * np.maximum(1.0, np.abs(bound))))
    return projected, float(move.max()), beyond


def _box_side(value: Any, default: float, n: int) -> NDArray[np.float64]:
    """One side of the box as ``n`` numbers: ``default`` where absent, a scalar spread over all (CasADi's own rule)."""
    side = np.full(n, default) if value is None else np.asarray(value, dtype=float).ravel()
    return np.full(n, side[0]) if side.size == 1 else side


#: What CasADi's message says about an option it refused: the option's name is the group.
_NAMED_IN_MESSAGE = (
    re.compile(r"No such (\w+) option: (?P<name>\S+)"),
    re.compile(r"Unknown option: (?P<name>\S+)"),
    re.compile(r"Illegal type for (?P<name>[^:\s]+):"),
)


def _refused_options(exc: RuntimeError, choice: SolverChoice, solver_options: Mapping[str, Any]) -> list[str]:
    """The user's options that ``solver`` refuses: named by CasADi's message, else found one by one.

    IPOPT says only "Invalid options were detected" for a value out of range (it prints the
    details itself); each of the user's options is then tried alone on a one-variable problem.
    """
    message = str(exc)
    for pattern in _NAMED_IN_MESSAGE:
        match = pattern.search(message)
        if match:
            name = match.group("name")
            named = [key for key in solver_options if key == name or key.split(".", 1)[-1] == name]
            if named:
                return named
    import casadi as ca

    x = ca.SX.sym("x")
    refused = []
    for key, value in solver_options.items():
        try:
            ca.nlpsol("option_probe", choice.plugin, {"x": x, "f": x * x}, {**plugin_defaults(choice.name), key: value})
        except RuntimeError:
            refused.append(key)
    return refused


def nlp_solver(
    name: str,
    nlp: Mapping[str, Any],
    tuning: Mapping[str, Any] | None = None,
    *,
    functions: Mapping[str, Any] | None = None,
    solver: str | SolverChoice = DEFAULT_SOLVER,
    solver_options: Mapping[str, Any] | None = None,
    options_argument: str = "ipopt_options",
) -> NLPSolver:
    """``casadi.nlpsol(name, plugin, nlp, options)`` with optcal's options; refused options are bad input.

    The options are, later ones overriding earlier ones: the solver's defaults
    (:data:`IPOPT_DEFAULTS` for IPOPT, the catalogue's for another,
    :data:`optcal.solvers.registry.NLP_SOLVERS`), the problem's ``tuning`` (IPOPT options, so
    applied with IPOPT only), the problem's ``functions`` and the user's ``solver_options``.

    Parameters
    ----------
    name : str
        The solver's name (in CasADi's messages).
    nlp : mapping
        CasADi's NLP: ``x``, ``f`` and optionally ``p`` and ``g``.
    tuning : mapping, optional
        The problem's own IPOPT options (a tolerance, an iteration limit, ...).
    functions : mapping, optional
        Options that hold the problem's own functions and hold for any plugin (``grad_f``,
        ``hess_lag``).
    solver : str or SolverChoice
        A solver of the catalogue by name (``"ipopt"``, ``"sqpmethod+osqp"``), or resolved by
        :func:`optcal.solvers.registry.choose_nlp_solver` (its user options included).
    solver_options : mapping, optional
        The user's options.
    options_argument : str
        The Python argument that carried ``solver_options``, named in the error.

    Raises
    ------
    InputError
        The solver is not in the catalogue, does not run here or does not suit the problem (the
        message names those that do), or it refused one of the user's options (the message names it).
    SolverError
        The plugin refused the problem with optcal's own options (a defect of optcal).
    """
    import casadi as ca

    functions = dict(functions or {})
    choice = as_choice(solver, solver_options, constraints=nlp.get("g") is not None, callbacks="hess_lag" in functions)
    if not plugin_accepts(choice.plugin, "grad_f"):
        functions.pop("grad_f", None)  # the plugin differentiates f itself (a callback's reverse derivative)
    user = choice.user_option_dict()
    options = {**plugin_defaults(choice.name), **(dict(tuning or {}) if choice.name == DEFAULT_SOLVER else {}),
               **functions, **user}
    try:
        if choice.writes_stdout:
            with quiet_stdout():
                built = ca.nlpsol(name, choice.plugin, dict(nlp), options)
        else:
            built = ca.nlpsol(name, choice.plugin, dict(nlp), options)
        return NLPSolver(built, choice.name, choice.writes_stdout)
    except RuntimeError as exc:
        reason = str(exc).strip().splitlines()[-1].split(": ")[-1]  # CasADi's last line says why
        label = solver_label(choice.name)
        if not user:
            raise SolverError(f"{label} refused the options of {name} ({reason})") from exc
        refused = _refused_options(exc, choice, user) or list(user)
        listed = ", ".join(f"{key!r}: {user[key]!r}" for key in refused)
        raise InputError(f"{label} refused the options {{{listed}}} ({reason}); check {options_argument}") from exc


def numpy_callback(
    name: str,
    inputs: list[tuple[str, Any]],
    outputs: list[tuple[str, Any]],
    evaluate: Callable[[list[NDArray]], list[Any]],
    reverse: Callable[[str, list, list, dict], Any] | None = None,
) -> Any:
    """A CasADi ``Callback`` evaluated in numpy.

    ``inputs`` and ``outputs`` are ``(name, sparsity)`` pairs; ``evaluate`` receives each input's
    nonzeros as a float array (a view into CasADi's memory, valid during the call) and returns
    each output's nonzeros (arrays or floats, in the output sparsity's order), which are copied
    into CasADi's memory (``eval_buffer``: no element-wise conversion, which for thousands of
    values costs more than the numpy work itself).  ``reverse(name, inames, onames, opts)``, if
    given, returns the Function of the first-order reverse derivative.
    """
    import casadi as ca

    class NumpyCallback(ca.Callback):
        def __init__(self) -> None:
            ca.Callback.__init__(self)
            self.construct(name, {})

        def get_n_in(self) -> int:
            return len(inputs)

        def get_n_out(self) -> int:
            return len(outputs)

        def get_name_in(self, i: int) -> str:
            return inputs[i][0]

        def get_name_out(self, i: int) -> str:
            return outputs[i][0]

        def get_sparsity_in(self, i: int) -> Any:
            return inputs[i][1]

        def get_sparsity_out(self, i: int) -> Any:
            return outputs[i][1]

        def eval(self, arg: Any) -> list[Any]:
            values = evaluate([np.asarray(a, dtype=float).ravel(order="F") for a in arg])
            return [ca.DM(sparsity, np.asarray(value, dtype=float).ravel())
                    for (_, sparsity), value in zip(outputs, values)]

        def has_eval_buffer(self) -> bool:
            return True

        def eval_buffer(self, arg: Any, res: Any) -> int:
            # an absent buffer: an input without nonzeros, or an output the caller does not need
            values = evaluate([np.empty(0) if a is None else np.frombuffer(a, dtype=np.float64) for a in arg])
            for buffer, value in zip(res, values):
                if buffer is not None:
                    np.frombuffer(buffer, dtype=np.float64)[:] = value
            return 0

        def has_reverse(self, nadj: int) -> bool:
            return reverse is not None and nadj == 1

        def get_reverse(self, nadj: int, fname: str, inames: Any, onames: Any, opts: Any) -> Any:
            assert reverse is not None
            return reverse(fname, inames, onames, opts)

    return NumpyCallback()


@dataclass(frozen=True)
class NumpyObjective:
    """The numpy functions of one solve of a :class:`CallbackNLP`, each of the flat variable vector x.

    Attributes
    ----------
    value : callable
        ``x -> f(x)``.
    gradient : callable
        ``x -> (f(x), ∇f(x))``.
    hessian : callable, optional
        ``(x, λ_f) -> λ_f ∇²f(x)`` (or its Gauss–Newton approximation): a dense (n, n) matrix, or
        the (n/b, b, b) diagonal blocks of a problem built with ``hessian_block_size`` b.  The
        factor ``λ_f`` is IPOPT's multiplier of the objective in its Lagrangian.
    """

    value: Callable[[NDArray], float]
    gradient: Callable[[NDArray], tuple[float, NDArray]]
    hessian: Callable[[NDArray, float], NDArray] | None = None


class CallbackNLP:
    """``min_x f(x)`` (subject to ``g(x)`` bounds) with f, ∇f and ∇²f evaluated in numpy.

    The objective, its gradient (``grad_f``) and, when ``hessian_block_size`` is given, the
    Hessian of the Lagrangian (``hess_lag``, block diagonal with blocks of that size, dense for
    blocks of size n) are CasADi callbacks calling the :class:`NumpyObjective` of the current
    :meth:`solve`; the objective's reverse derivative is the gradient callback.  Without a
    Hessian the problem's ``tuning`` says how the plugin approximates it (IPOPT:
    ``hessian_approximation`` limited-memory).  Constraints are CasADi expressions of x.

    Built once for a size and options and solved with one data set at a time: :meth:`solve`
    holds a lock while the callbacks read that solve's functions.

    Parameters
    ----------
    name : str
        The solver's name; the callbacks are ``name_f``, ``name_grad_f``, ``name_hess_lag``.
    n : int
        Number of variables.
    hessian_block_size : int, optional
        Size of the diagonal blocks of the Hessian the objective provides (n for a dense one).
    constraints : callable, optional
        ``x (casadi.MX) -> g(x)``; bounds ``lbg``, ``ubg`` are given to :meth:`solve`.  Not with a
        Hessian callback (its Lagrangian would need the constraints' curvature).
    tuning, solver, solver_options, options_argument
        As :func:`nlp_solver`.
    """

    def __init__(
        self,
        name: str,
        n: int,
        *,
        hessian_block_size: int | None = None,
        constraints: Callable[[Any], Any] | None = None,
        tuning: Mapping[str, Any] | None = None,
        solver: str | SolverChoice = DEFAULT_SOLVER,
        solver_options: Mapping[str, Any] | None = None,
        options_argument: str = "ipopt_options",
    ) -> None:
        import casadi as ca

        if hessian_block_size is not None and constraints is not None:
            raise ValueError("a Hessian callback covers the objective only: give constraints without it")
        if hessian_block_size is not None and (hessian_block_size < 1 or n % hessian_block_size):
            raise ValueError(f"hessian_block_size {hessian_block_size} does not divide n = {n}")
        self.n = n
        self._objective: NumpyObjective | None = None
        self._lock = threading.Lock()
        vector, scalar, empty = ca.Sparsity.dense(n, 1), ca.Sparsity.dense(1, 1), ca.Sparsity(0, 1)

        gradient = numpy_callback(f"{name}_grad_f", [("x", vector), ("p", empty)], [("f", scalar), ("grad_f", vector)],
                                  lambda arg: list(self._current().gradient(arg[0])))

        def value_reverse(fname: str, inames: list, onames: list, opts: dict) -> Any:
            x, out, adj = ca.MX.sym("x", n), ca.MX.sym("f", 1), ca.MX.sym("adj", 1)
            _, g = gradient(x, ca.MX(0, 1))
            return ca.Function(fname, [x, out, adj], [adj * g], inames, onames, opts)

        value = numpy_callback(f"{name}_f", [("x", vector)], [("f", scalar)],
                               lambda arg: [self._current().value(arg[0])], reverse=value_reverse)
        self._callbacks = [gradient, value]  # alive as long as the solver
        functions: dict[str, Any] = {"grad_f": gradient}
        choice = as_choice(solver, solver_options, constraints=constraints is not None,
                           callbacks=hessian_block_size is not None)
        if hessian_block_size is not None:
            # IPOPT (and Bonmin, IPOPT inside) take the upper triangle of the Hessian, the SQP methods the whole
            triangle = choice.plugin in TRIANGULAR_HESSIAN_PLUGINS
            sparsity, upper = (_block_upper_triangles if triangle else _block_entries)(n, hessian_block_size)

            def hessian(arg: list) -> list:
                objective = self._current()
                assert objective.hessian is not None, f"{name} needs the objective's Hessian"
                return [np.asarray(objective.hessian(arg[0], float(arg[2][0]))).ravel()[upper]]

            hess_lag = numpy_callback(f"{name}_hess_lag", [("x", vector), ("p", empty), ("lam_f", scalar), ("lam_g", empty)],
                                      [("triu_hess_gamma_x_x", sparsity)], hessian)
            self._callbacks.append(hess_lag)
            functions["hess_lag"] = hess_lag
        elif choice.plugin != DEFAULT_SOLVER and plugin_accepts(choice.plugin, "hessian_approximation"):
            # no Hessian of a numpy objective: the plugin approximates one (IPOPT's tuning says so for IPOPT)
            functions["hessian_approximation"] = "limited-memory"
        x = ca.MX.sym("x", n)
        nlp = {"x": x, "f": value(x)}
        if constraints is not None:
            nlp["g"] = constraints(x)
        self.solver = nlp_solver(name, nlp, tuning, functions=functions, solver=choice, options_argument=options_argument)

    def _current(self) -> NumpyObjective:
        assert self._objective is not None, "solve() sets the objective"
        return self._objective

    def solve(self, objective: NumpyObjective, **args: Any) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve with ``objective``'s functions from ``x0`` (and bounds); the last iterate and the statistics."""
        with self._lock:
            self._objective = objective
            try:
                return self.solver.solve(**args)
            finally:
                self._objective = None


#: Plugins whose ``hess_lag`` returns the upper triangle of the Hessian (IPOPT's convention).
TRIANGULAR_HESSIAN_PLUGINS: frozenset[str] = frozenset({"ipopt", "bonmin"})


def _block_entries(n: int, block: int) -> tuple[Any, NDArray[np.intp]]:
    """As :func:`_block_upper_triangles`, every entry of the diagonal blocks (a symmetric sparsity)."""
    import casadi as ca

    index, col, row = np.array([(k, c, r) for k in range(n // block) for c in range(block) for r in range(block)]).T
    sparsity = ca.Sparsity.triplet(n, n, (block * index + row).tolist(), (block * index + col).tolist())
    return sparsity, index * block * block + row * block + col


def _block_upper_triangles(n: int, block: int) -> tuple[Any, NDArray[np.intp]]:
    """The sparsity of the upper triangles of n/block diagonal blocks and, in CasADi's column-major
    nonzero order, the position of each nonzero in the row-major ravel of the (n/block, block, block) blocks."""
    import casadi as ca

    index, col, row = np.array([(k, c, r) for k in range(n // block) for c in range(block) for r in range(c + 1)]).T
    sparsity = ca.Sparsity.triplet(n, n, (block * index + row).tolist(), (block * index + col).tolist())
    return sparsity, index * block * block + row * block + col


__all__ = [
    "DEFAULT_SOLVER",
    "IPOPT_DEFAULTS",
    "MIN_RESIDUAL_RMS",
    "SCALED_COST_IPOPT_OPTIONS",
    "CallbackNLP",
    "NLPSolver",
    "NumpyObjective",
    "as_choice",
    "cost_scale",
    "nlp_solver",
    "numpy_callback",
    "plugin_defaults",
    "solver_label",
]
