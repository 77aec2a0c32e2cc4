"""A calibration problem as an object: variables, parameters, objective, constraints, bounds, scaling.

:class:`Formulation` holds one nonlinear program as CasADi states it — ``min_x f(x, p)`` subject
to ``lbg ≤ g(x, p) ≤ ubg`` and ``lbx ≤ x ≤ ubx`` — with the numbers of one data set (the
parameter values ``p``, the start ``x0``, the bounds) and what a reader needs to check it against
the paper: the equation it comes from, the names of the variables and of the parameter blocks,
and how it is scaled.  It is solved by any ``nlpsol`` plugin of the catalogue
(:mod:`optcal.solvers.registry`) through :func:`optcal.solvers.nlp.nlp_solver`, or handed to
CasADi directly (:meth:`Formulation.nlp`, :meth:`Formulation.arguments`).

A problem whose objective is evaluated in numpy (:class:`optcal.solvers.nlp.CallbackNLP`: the
vectorised ML problem, the gyroscope's problem, the pose planner's refinement) is a formulation
with a ``callback``: it builds the CallbackNLP for a solver and holds the numpy objective of its
data.

:class:`ConicFormulation` is the same for a cvxpy problem (the convex ellipsoid fit), solved by
any installed cvxpy solver that takes it.

The builders of optcal's calibration problems are :mod:`optcal.problems`.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.solvers.convergence import plugin_iterations, plugin_status
from optcal.solvers.nlp import CallbackNLP, NumpyObjective, nlp_solver
from optcal.solvers.registry import SolverChoice, choose_conic_solver, choose_nlp_solver


@dataclass(frozen=True)
class Solution:
    """What one solve of a formulation returned.

    Attributes
    ----------
    x : ndarray
        The solver's last iterate (in the formulation's scaled variables).
    objective : float
        ``f`` at ``x`` (NaN when the plugin does not report it).
    solver : str
        The solver's catalogue name.
    status : str
        The solver's own status.
    success : bool
        Whether the solver reports success.
    iterations : int
        Its iterations (:func:`optcal.solvers.convergence.plugin_iterations`).
    seconds : float
        Wall time of the solve (building the solver excluded).
    """

    x: NDArray[np.float64]
    objective: float
    solver: str
    status: str
    success: bool
    iterations: int
    seconds: float


@dataclass
class Formulation:
    """One NLP with the data of one problem (see the module docstring).

    Attributes
    ----------
    name : str
        What it is (``"norm-residual ML"``).
    equation : str
        The problem as written in the source, with the citation.
    variables : list of str
        Names of the entries of x (or of its blocks, ``"d_k (3 per pose)"``).
    parameters : dict
        Parameter block → what it holds (the data enter as parameters, so one built solver
        serves any data set of the same size).
    scaling : str
        How the problem is scaled (normalised data, cost scale) and how x maps back to θ.
    nlp_dict : dict
        CasADi's ``x``, ``f`` and optionally ``p``, ``g`` (SX or MX expressions).
    values : dict
        ``x0``, ``p``, ``lbx``, ``ubx``, ``lbg``, ``ubg`` of this data set (numpy arrays; absent: unbounded).
    constraints : list of str
        What each block of g is.
    tuning : dict
        The problem's own IPOPT tuning (applied with IPOPT only).
    functions : dict
        Plugin-independent functions handed to ``nlpsol`` (``hess_lag``).
    callback : callable, optional
        ``solver choice -> CallbackNLP`` for a problem evaluated in numpy; ``objective`` its functions.
    objective : NumpyObjective, optional
    structure : hashable, optional
        What the symbolic problem depends on (its kind and sizes, not its data): formulations
        with the same structure share their built solvers (:data:`BUILT_SOLVERS`).
    """

    name: str
    equation: str
    variables: list[str]
    parameters: dict[str, str]
    scaling: str
    nlp_dict: dict[str, Any]
    values: dict[str, NDArray[np.float64]]
    constraints: list[str] = field(default_factory=list)
    tuning: dict[str, Any] = field(default_factory=dict)
    functions: dict[str, Any] = field(default_factory=dict)
    callback: Callable[[SolverChoice], CallbackNLP] | None = None
    objective: NumpyObjective | None = None
    structure: Hashable | None = None

    @property
    def has_constraints(self) -> bool:
        return self.nlp_dict.get("g") is not None

    def nlp(self) -> dict[str, Any]:
        """CasADi's NLP dictionary (``casadi.nlpsol(name, plugin, formulation.nlp())``)."""
        return dict(self.nlp_dict)

    def arguments(self) -> dict[str, Any]:
        """The solver call's arguments for this data set (``solver(**formulation.arguments())``)."""
        return {k: v for k, v in self.values.items() if v is not None}

    def choose(self, solver: str | SolverChoice | None = None, options: Mapping[str, Any] | None = None) -> SolverChoice:
        """The solver resolved for this problem (refused in one line when it does not run here or does not suit it)."""
        if isinstance(solver, SolverChoice) and not options:
            return solver
        name = solver.name if isinstance(solver, SolverChoice) else solver
        return choose_nlp_solver(name, options, constraints=self.has_constraints, problem=f"the {self.name} problem")

    def solve(self, solver: str | SolverChoice | None = None, options: Mapping[str, Any] | None = None) -> Solution:
        """Solve with a solver of the catalogue by name (IPOPT by default) and the user's options."""
        choice = self.choose(solver, options)
        args = self.arguments()
        if self.callback is not None:
            assert self.objective is not None, "a callback formulation holds its numpy objective"
            built = self.callback(choice)
            t0 = time.perf_counter()
            x, stats = built.solve(self.objective, **args)
            seconds = time.perf_counter() - t0
            value = float(self.objective.value(x))
        else:
            nlp, lock = self._built(choice)
            with lock:  # a built solver keeps the statistics of its last call
                t0 = time.perf_counter()
                x, stats = nlp.solve(**args)
                seconds = time.perf_counter() - t0
            value = _objective_value(self.nlp_dict, x, self.values.get("p"))
        return Solution(x, value, choice.name, plugin_status(stats), bool(stats.get("success", False)),
                        plugin_iterations(stats), seconds)

    def _built(self, choice: SolverChoice) -> tuple[Any, threading.Lock]:
        """The solver built for this formulation (shared by formulations of the same structure)."""
        def build() -> Any:
            return nlp_solver(self.name.replace(" ", "_").replace("-", "_"), self.nlp_dict, self.tuning,
                              functions=self.functions, solver=choice, options_argument="options")

        if self.structure is None:
            return build(), threading.Lock()
        key = (self.structure, choice)
        with _BUILT_LOCK:
            if key in BUILT_SOLVERS:
                BUILT_SOLVERS.move_to_end(key)
                return BUILT_SOLVERS[key]
        built = (build(), threading.Lock())
        with _BUILT_LOCK:
            BUILT_SOLVERS[key] = built
            while len(BUILT_SOLVERS) > BUILT_MAXSIZE:
                BUILT_SOLVERS.popitem(last=False)
        return built

    def describe(self) -> str:
        """The formulation in words: equation, variables, parameters, constraints, bounds, scaling."""
        lines = [f"{self.name}", f"  problem: {self.equation}", f"  variables ({_size(self.nlp_dict['x'])}): "
                 + ", ".join(self.variables)]
        lines += [f"  parameter {k}: {v}" for k, v in self.parameters.items()]
        lines += [f"  constraint: {c}" for c in self.constraints] or ["  constraints: none"]
        bounded = [f"{name} in [{lo:.6g}, {hi:.6g}]" for name, lo, hi in self._bounds()]
        lines.append("  bounds: " + (", ".join(bounded) if bounded else "none"))
        lines.append(f"  scaling: {self.scaling}")
        return "\n".join(lines)

    def _bounds(self) -> list[tuple[str, float, float]]:
        lbx, ubx = self.values.get("lbx"), self.values.get("ubx")
        if lbx is None and ubx is None:
            return []
        n = _size(self.nlp_dict["x"])
        lo = np.full(n, -np.inf) if lbx is None else np.broadcast_to(lbx, (n,))
        hi = np.full(n, np.inf) if ubx is None else np.broadcast_to(ubx, (n,))
        names = self.variables if len(self.variables) == n else [f"x[{k}]" for k in range(n)]
        return [(names[k], float(lo[k]), float(hi[k])) for k in range(n) if np.isfinite(lo[k]) or np.isfinite(hi[k])]


#: Built solvers of formulations with a ``structure``, by (structure, solver choice), least
#: recently used dropped first beyond :data:`BUILT_MAXSIZE`.
BUILT_SOLVERS: OrderedDict[tuple[Hashable, SolverChoice], tuple[Any, threading.Lock]] = OrderedDict()
BUILT_MAXSIZE: int = 64
_BUILT_LOCK = threading.Lock()


def _size(x: Any) -> int:
    return int(x.numel()) if hasattr(x, "numel") else int(np.size(x))


def _objective_value(nlp: dict[str, Any], x: NDArray, p: NDArray | None) -> float:
    import casadi as ca

    args = [nlp["x"]] + ([nlp["p"]] if nlp.get("p") is not None else [])
    f = ca.Function("objective", args, [nlp["f"]])
    values = [x] + ([p] if nlp.get("p") is not None else [])
    return float(np.asarray(f(*values), dtype=float).ravel()[0])


@dataclass(frozen=True)
class ConicSolution:
    """What one solve of a :class:`ConicFormulation` returned (cvxpy's status, the variables' values)."""

    values: dict[str, NDArray[np.float64] | None]
    objective: float
    solver: str
    status: str
    success: bool
    iterations: int
    seconds: float


@dataclass
class ConicFormulation:
    """A cvxpy problem with the data of one problem set, solved by any installed solver that takes it.

    Attributes
    ----------
    name, equation, scaling : str
        As :class:`Formulation`.
    problem : cvxpy.Problem
        With its parameters' values set.
    variables : dict
        Name → cvxpy variable (or expression) read after a solve.
    solver_defaults : dict
        Solver name → options it starts from (the user's on top).
    """

    name: str
    equation: str
    scaling: str
    problem: Any
    variables: dict[str, Any]
    solver_defaults: dict[str, dict[str, Any]] = field(default_factory=dict)

    def solve(self, solver: str | None = None, options: Mapping[str, Any] | None = None) -> ConicSolution:
        """Solve with a cvxpy solver by name (CLARABEL by default); one that is not suited is refused."""
        import cvxpy as cp

        name = choose_conic_solver(solver)
        opts = {**self.solver_defaults.get(name, {}), **dict(options or {})}
        t0 = time.perf_counter()
        self.problem.solve(solver=name, **opts)
        seconds = time.perf_counter() - t0
        values = {k: None if v.value is None else np.asarray(v.value, dtype=float) for k, v in self.variables.items()}
        value = self.problem.value
        return ConicSolution(values, float(value) if value is not None else float("nan"), name, str(self.problem.status),
                             self.problem.status == cp.OPTIMAL, int(self.problem.solver_stats.num_iters or 0), seconds)

    def describe(self) -> str:
        return "\n".join([self.name, f"  problem: {self.equation}", "  variables: " + ", ".join(self.variables),
                          f"  scaling: {self.scaling}"])


__all__ = ["ConicFormulation", "ConicSolution", "Formulation", "Solution"]
