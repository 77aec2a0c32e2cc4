"""Solvers by name: which CasADi ``nlpsol`` plugins and cvxpy conic solvers run here, and the options they start from.

Every optimisation problem of optcal is solved by a solver the user may name (``--solver NAME``,
``solver="NAME"`` in Python; ``--conic-solver NAME``, ``conic_solver="NAME"`` for the convex
ellipsoid fit).  A name is resolved here, once, into a :class:`SolverChoice`: the plugin, the
options it starts from (quiet, tolerances comparable to IPOPT's) and the user's options on top.
A name that is not installed, not licensed, or not suited to the problem is refused by
:func:`choose_nlp_solver` / :func:`choose_conic_solver` in one line naming the ones that are.

What "installed" means is measured, not assumed: :func:`probe_nlp_solver` builds each
candidate on a two-variable problem with a bound and an equality constraint (Rosenbrock's
valley cut by ``x + y = 1``) and solves it; a plugin whose library is missing (``madnlp`` is not
in the PyPI wheel), whose licence is absent (``knitro``, ``snopt``, ``worhp``) or whose linear
solver is missing (``blocksqp`` needs HSL's ``ma27``) fails that probe, with CasADi's reason.
The probes run once per process (a few milliseconds each).

The catalogue :data:`NLP_SOLVERS` names an ``sqpmethod`` by its QP solver (``sqpmethod`` is
CasADi's SQP with its own ``qrqp``; ``sqpmethod+osqp``, ``sqpmethod+qpoases``, ... use another
QP solver), so the solver study can compare them like plugins.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import threading
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

from optcal.errors import InputError

#: The plugin every NLP of optcal uses unless told otherwise.
DEFAULT_NLP_SOLVER: str = "ipopt"
#: The conic solver of the convex ellipsoid fit unless told otherwise (an interior-point SDP solver).
DEFAULT_CONIC_SOLVER: str = "CLARABEL"

#: Printing switched off in CasADi's SQP methods (their iteration tables go to standard output).
_SQP_QUIET: dict[str, Any] = {"print_header": False, "print_iteration": False, "print_status": False}
#: CasADi's own QP solver, quiet.
_QRQP_QUIET: dict[str, Any] = {"print_iter": False, "print_header": False, "print_info": False}
#: Convergence of the SQP methods: primal and dual infeasibility to 1e-8 on the cost scaled to
#: order one by :func:`optcal.solvers.nlp.cost_scale` (at 1e-10 their line search stops first,
#: "Search_Direction_Becomes_Too_Small", on optima already exact to 1e-13 in the objective: 5
#: of the 25 instances of the quick solver study); 200 iterations as IPOPT's limit.  The exact
#: Hessian of a robust loss, or far from the optimum, is indefinite, which a convex QP solver
#: (OSQP, and qrqp's factorisation) refuses: its negative eigenvalues are clipped
#: (``convexify_strategy`` eigen-clip), which leaves the fixed points, hence the optimum, unchanged.
_SQP_TOLERANCES: dict[str, Any] = {"tol_pr": 1e-8, "tol_du": 1e-8, "max_iter": 200, "convexify_strategy": "eigen-clip"}


@dataclass(frozen=True)
class NLPSolverSpec:
    """One solver of the catalogue: a CasADi ``nlpsol`` plugin with the options it starts from.

    Attributes
    ----------
    name : str
        The name users give (``"ipopt"``, ``"sqpmethod+osqp"``).
    plugin : str
        The ``nlpsol`` plugin.
    defaults : dict
        Options it starts from (printing off, tolerances); a problem's IPOPT tuning applies to
        IPOPT only, the user's options go on top of both.
    constraints : bool
        Handles general (nonlinear) constraints ``lbg ≤ g(x) ≤ ubg``, not only bounds.
    writes_stdout : bool
        Prints whatever its options say (a debugging line, a banner, the QP solver's matrix
        when a QP fails): its solves run with the process's standard output and error silenced
        (:func:`quiet_stdout`).  True for every plugin but IPOPT, whose ``print_level`` 0 holds.
    description : str
        What it is, in a few words.
    no_bounds : str
        Why it cannot solve a problem with bounds on its unknowns (``lbx``, ``ubx``: a user's
        ``--bound``), measured here; empty when it can.  Such a problem is refused with it in one line.
    """

    name: str
    plugin: str
    defaults: dict[str, Any] = field(default_factory=dict)
    constraints: bool = True
    writes_stdout: bool = True
    description: str = ""
    no_bounds: str = ""


def _sqp(qpsol: str, qp_options: dict[str, Any] | None = None) -> dict[str, Any]:
    return {**_SQP_QUIET, **_SQP_TOLERANCES, "qpsol": qpsol, "qpsol_options": dict(qp_options or {})}


#: The NLP solvers optcal knows how to start quietly, in the order they are listed.  Whether
#: each runs here is measured by :func:`probe_nlp_solver`.
NLP_SOLVERS: dict[str, NLPSolverSpec] = {spec.name: spec for spec in (
    NLPSolverSpec("ipopt", "ipopt", writes_stdout=False, description="interior point, MUMPS (Wächter & Biegler 2006)"),
    NLPSolverSpec("sqpmethod", "sqpmethod", _sqp("qrqp", _QRQP_QUIET),
                  description="CasADi's SQP with its active-set QP solver qrqp"),
    NLPSolverSpec("sqpmethod+osqp", "sqpmethod", _sqp("osqp", {"osqp": {"verbose": False, "eps_abs": 1e-12, "eps_rel": 1e-12}}),
                  description="CasADi's SQP with the ADMM QP solver OSQP"),
    NLPSolverSpec("sqpmethod+qpoases", "sqpmethod", _sqp("qpoases", {"printLevel": "none"}),
                  description="CasADi's SQP with the active-set QP solver qpOASES"),
    NLPSolverSpec("sqpmethod+proxqp", "sqpmethod", _sqp("proxqp"),
                  description="CasADi's SQP with the proximal QP solver ProxQP"),
    NLPSolverSpec("blocksqp", "blocksqp", {"print_header": False, "print_iteration": False},
                  description="SQP with block-wise quasi-Newton updates (needs HSL ma27)"),
    NLPSolverSpec("fatrop", "fatrop", {"structure_detection": "none", "fatrop.print_level": 0},
                  description="structure-exploiting interior point (Vanroye et al. 2023)"),
    NLPSolverSpec("feasiblesqpmethod", "feasiblesqpmethod",
                  {**_SQP_QUIET, "qpsol": "qrqp", "qpsol_options": dict(_QRQP_QUIET), "max_iter": 200,
                   "tol_pr": 1e-8, "tol_du": 1e-8, "optim_tol": 1e-10, "feas_tol": 1e-10},
                  description="feasible SQP with a trust region (FSLP)",
                  # CasADi 3.7: on imu_tk's Xsens log with T_xx bounded its trust-region QP gets lbx > ubx
                  no_bounds="CasADi's feasiblesqpmethod builds its trust-region QP with crossed bounds on a bounded "
                            "problem (\"LBX[0] <= UBX[0] was violated\")"),
    NLPSolverSpec("uno", "uno", {"uno.logger": "SILENT"}, description="Uno, unified SQP / interior point (Vanaret & Leyffer)"),
    NLPSolverSpec("alpaqa", "alpaqa", description="augmented Lagrangian with PANOC (Pas et al. 2022)"),
    NLPSolverSpec("sleqp", "sleqp", description="SLEQP, sequential linear-equality QP"),
    NLPSolverSpec("madnlp", "madnlp", description="MadNLP, interior point in Julia"),
    NLPSolverSpec("bonmin", "bonmin", {"bonmin.print_level": 0, "bonmin.bb_log_level": 0, "bonmin.nlp_log_level": 0,
                                       "bonmin.sb": "yes"},
                  description="Bonmin (MINLP; on a continuous problem one IPOPT solve)"),
    NLPSolverSpec("knitro", "knitro", description="Artelys Knitro (commercial licence)"),
    NLPSolverSpec("snopt", "snopt", description="SNOPT (commercial licence)"),
    NLPSolverSpec("worhp", "worhp", description="WORHP (licence)"),
)}

#: cvxpy solvers that take the convex fit's semidefinite constraint ``A ⪰ εI`` (an SDP); the
#: others cvxpy may have installed (HIGHS, OSQP, ECOS, SCIPY, ...) do not.
SDP_SOLVERS: tuple[str, ...] = ("CLARABEL", "SCS", "CVXOPT", "MOSEK", "COPT", "SDPA")

#: One lock around the process's standard output while a solver that writes to it runs.
_STDOUT_LOCK = threading.Lock()


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Silence file descriptors 1 and 2 (the C libraries' ``printf`` and CasADi's warnings, Python's too) for the block.

    A solver's errors still arrive: CasADi raises them as exceptions, whose text is kept.
    """
    with _STDOUT_LOCK:
        sys.stdout.flush()
        sys.stderr.flush()
        try:
            saved = [os.dup(1), os.dup(2)]
        except OSError:  # no standard streams to silence
            yield
            return
        devnull = os.open(os.devnull, os.O_WRONLY)
        sink = io.StringIO()  # CasADi's Python build writes through sys.stdout as well as to the descriptors
        try:
            os.dup2(devnull, 1)
            os.dup2(devnull, 2)
            with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
                yield
        finally:
            sys.stdout.flush()  # what CasADi wrote through Python, or the C library buffered, goes to /dev/null
            sys.stderr.flush()
            _flush_c_streams()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(devnull)
            for fd in saved:
                os.close(fd)


def _flush_c_streams() -> None:
    """``fflush(NULL)``: the C library's buffered output of every stream, written now."""
    import ctypes

    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to reach (not on a POSIX system): nothing buffered there to lose
        pass


@dataclass(frozen=True)
class Probe:
    """The outcome of :func:`probe_nlp_solver`: whether the solver runs here, and why not."""

    name: str
    available: bool
    reason: str = ""


@lru_cache(maxsize=None)
def probe_nlp_solver(name: str) -> Probe:
    """Build and run ``name`` on a two-variable problem with a bound and an equality constraint.

    ``min (x − 1)² + 10 (y − x²)²`` s.t. ``x + y = 1``, ``−5 ≤ x, y ≤ 5``, from (0.5, 0.5); the
    solver is available when it reports success within 1e-4 of the optimum (0.6255, 0.3745).
    """
    spec = NLP_SOLVERS.get(name)
    if spec is None:
        return Probe(name, False, "not in optcal's catalogue")
    import casadi as ca
    import numpy as np

    if not ca.has_nlpsol(spec.plugin):
        return Probe(name, False, f"CasADi has no nlpsol plugin {spec.plugin!r} in this installation (not installed)")
    x = ca.SX.sym("x", 2)
    nlp = {"x": x, "f": (x[0] - 1) ** 2 + 10 * (x[1] - x[0] ** 2) ** 2, "g": x[0] + x[1]}
    try:
        with quiet_stdout():
            solver = ca.nlpsol(f"probe_{spec.plugin}", spec.plugin, nlp,
                               {"print_time": False, **(_ipopt_quiet() if spec.plugin == "ipopt" else {}), **spec.defaults})
            sol = solver(x0=[0.5, 0.5], lbx=-5, ubx=5, lbg=1, ubg=1)
        stats = solver.stats()
    except RuntimeError as exc:
        reason = " ".join(str(exc).strip().splitlines()[-1].split())
        if "licen" in reason.lower():
            reason = f"not licensed: {reason}"
        return Probe(name, False, reason[:160])
    xs = np.asarray(sol["x"]).ravel()
    if not stats.get("success", False) or not np.allclose(xs, [0.625451, 0.374549], atol=1e-4):
        return Probe(name, False, f"did not solve the probe problem (status {stats.get('return_status', '?')})")
    return Probe(name, True)


def _ipopt_quiet() -> dict[str, Any]:
    return {"ipopt.print_level": 0, "ipopt.sb": "yes"}


@lru_cache(maxsize=None)
def plugin_accepts(plugin: str, option: str) -> bool:
    """Whether the ``nlpsol`` plugin has the option (``hess_lag``: it takes the problem's own Hessian function)."""
    import casadi as ca

    try:
        return option in ca.nlpsol_options(plugin)
    except RuntimeError:
        return False


def takes_callbacks(name: str) -> bool:
    """Whether the solver takes a problem evaluated in numpy (:class:`optcal.solvers.nlp.CallbackNLP`).

    Such a problem hands the plugin its own Hessian (``hess_lag``) or lets it approximate one
    (``hessian_approximation``): CasADi cannot differentiate a numpy callback twice.
    """
    spec = NLP_SOLVERS.get(name)
    plugin = spec.plugin if spec else name
    # feasiblesqpmethod has the options but asserts a one-output grad_f (CasADi 3.7's feasiblesqpmethod.cpp:287)
    return plugin_accepts(plugin, "hess_lag") and plugin != "feasiblesqpmethod"


def available_nlp_solvers(constraints: bool = False, callbacks: bool = False) -> list[str]:
    """The catalogue's solvers that run here (and take general constraints when ``constraints``,
    numpy callbacks when ``callbacks``)."""
    return [name for name, spec in NLP_SOLVERS.items()
            if probe_nlp_solver(name).available and (spec.constraints or not constraints)
            and (not callbacks or takes_callbacks(name))]


@dataclass(frozen=True)
class SolverChoice:
    """A resolved NLP solver: the plugin, its options (defaults, then the user's), its name.

    ``options`` holds the catalogue defaults of a plugin other than IPOPT, then the user's; for
    IPOPT the defaults are :data:`optcal.solvers.nlp.IPOPT_DEFAULTS`, which
    :func:`optcal.solvers.nlp.nlp_solver` applies with the problem's own tuning.
    """

    name: str = DEFAULT_NLP_SOLVER
    plugin: str = DEFAULT_NLP_SOLVER
    options: tuple[tuple[str, Any], ...] = ()
    user_options: tuple[tuple[str, Any], ...] = ()
    writes_stdout: bool = False

    @property
    def label(self) -> str:
        """How results name it: ``IPOPT`` for IPOPT, the catalogue name otherwise."""
        return "IPOPT" if self.name == DEFAULT_NLP_SOLVER else self.name

    def option_dict(self) -> dict[str, Any]:
        return thaw(self.options)

    def user_option_dict(self) -> dict[str, Any]:
        return thaw(self.user_options)


def freeze(options: Mapping[str, Any] | None) -> tuple[tuple[str, Any], ...]:
    """Options as a sorted tuple, nested dictionaries frozen too (a hashable cache key)."""
    return tuple(sorted((k, freeze(v) if isinstance(v, Mapping) else v) for k, v in (options or {}).items()))


def thaw(frozen: tuple[tuple[str, Any], ...]) -> dict[str, Any]:
    """The inverse of :func:`freeze`."""
    return {k: thaw(v) if _is_frozen(v) else v for k, v in frozen}


def _is_frozen(value: Any) -> bool:
    return isinstance(value, tuple) and all(isinstance(i, tuple) and len(i) == 2 and isinstance(i[0], str) for i in value) \
        and len(value) > 0


def choose_nlp_solver(name: str | None = None, options: Mapping[str, Any] | None = None, *,
                      constraints: bool = False, callbacks: bool = False, problem: str = "this problem") -> SolverChoice:
    """Resolve a solver name (and the user's options) or refuse it in one line naming those that run.

    Parameters
    ----------
    name : str, optional
        A name of :data:`NLP_SOLVERS` (``None``: IPOPT).
    options : mapping, optional
        The user's options, passed to the plugin as CasADi options on top of its defaults
        (``{"max_iter": 50}``; IPOPT's as ``"ipopt.max_iter"``).
    constraints : bool
        The problem has general constraints ``g(x)`` (a fixed physical parameter, the
        errors-in-variables problem): a solver that handles only bounds is not suited.
    callbacks : bool
        The problem is evaluated in numpy (:func:`takes_callbacks`): a solver that cannot take
        its Hessian function is not suited.
    problem : str
        The problem, named in the refusal.

    Raises
    ------
    InputError
        The name is unknown, the solver does not run here, or it does not suit the problem.
    """
    name = DEFAULT_NLP_SOLVER if name is None else str(name).strip().lower()
    spec = NLP_SOLVERS.get(name)
    user = dict(options or {})
    if name == DEFAULT_NLP_SOLVER:  # IPOPT ships with every casadi wheel: no probe on the default path
        return SolverChoice(name, name, freeze(user), freeze(user), False)
    if spec is None:
        raise InputError(f"unknown NLP solver {name!r}; the ones that run here: {', '.join(available_nlp_solvers(constraints))}")
    probe = probe_nlp_solver(name)
    if not probe.available:
        raise InputError(f"NLP solver {name!r} is not available ({probe.reason}); "
                         f"the ones that run here: {', '.join(available_nlp_solvers(constraints))}")
    if constraints and not spec.constraints:
        raise InputError(f"NLP solver {name!r} does not take the general constraints of {problem}; "
                         f"suited ones that run here: {', '.join(available_nlp_solvers(constraints, callbacks))}")
    if callbacks and not takes_callbacks(name):
        raise InputError(f"NLP solver {name!r} does not take {problem}, whose objective is evaluated in numpy "
                         f"(it cannot be handed the problem's Hessian); suited ones that run here: "
                         f"{', '.join(available_nlp_solvers(constraints, callbacks))}")
    return SolverChoice(name, spec.plugin, freeze({**spec.defaults, **user}), freeze(user), spec.writes_stdout)


def available_conic_solvers() -> list[str]:
    """cvxpy's installed solvers that take the convex fit's semidefinite constraint."""
    import cvxpy as cp

    installed = set(cp.installed_solvers())
    return [s for s in SDP_SOLVERS if s in installed]


def choose_conic_solver(name: str | None = None) -> str:
    """A cvxpy solver name for the convex ellipsoid fit, or a one-line refusal naming the suited installed ones.

    The default (Clarabel, which cvxpy installs with itself) is taken without importing cvxpy: most fits never
    solve the conic problem (the KKT solve answers when the semidefinite constraint is inactive), and cvxpy's
    import is most of a short command's time.
    """
    name = DEFAULT_CONIC_SOLVER if name is None else str(name).strip().upper()
    if name == DEFAULT_CONIC_SOLVER:
        return name
    import cvxpy as cp

    suited = available_conic_solvers()
    if name in suited:
        return name
    installed = cp.installed_solvers()
    if name in installed:
        raise InputError(f"conic solver {name!r} is installed but does not take the fit's semidefinite constraint "
                         f"A ⪰ εI; suited ones installed: {', '.join(suited)}")
    raise InputError(f"conic solver {name!r} is not installed (cvxpy has {', '.join(installed)}); "
                     f"suited ones installed: {', '.join(suited)}")


def parse_option_value(text: str) -> Any:
    """``KEY=VALUE``'s value: an integer, a float, true/false, or the string itself."""
    low = text.strip().lower()
    if low in ("true", "yes"):
        return True if low == "true" else "yes"
    if low in ("false", "no"):
        return False if low == "false" else "no"
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def parse_solver_options(items: list[str] | tuple[str, ...]) -> dict[str, Any]:
    """``["max_iter=50", "qpsol_options.print_iter=false"]`` → options; a dotted key below ``*_options`` nests.

    IPOPT's own options keep their dotted CasADi spelling (``ipopt.tol=1e-9``).
    """
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InputError(f"solver option {item!r} is not KEY=VALUE")
        head, dot, rest = key.partition(".")
        if dot and head.endswith("_options"):
            out.setdefault(head, {})[rest] = parse_option_value(value)
        else:
            out[key] = parse_option_value(value)
    return out


__all__ = [
    "DEFAULT_CONIC_SOLVER", "DEFAULT_NLP_SOLVER", "NLP_SOLVERS", "NLPSolverSpec", "Probe", "SDP_SOLVERS", "SolverChoice",
    "available_conic_solvers", "available_nlp_solvers", "choose_conic_solver", "choose_nlp_solver", "freeze",
    "parse_option_value", "parse_solver_options", "plugin_accepts", "probe_nlp_solver", "quiet_stdout",
    "takes_callbacks", "thaw",
]
