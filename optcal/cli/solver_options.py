"""The solver and constraint options shared by every command that solves an NLP.

Usage in a command module::

    @click.command()
    @solver_options
    def calibrate(..., **solver_opts: Any) -> None:
        settings = estimator_settings(method, **solver_opts)

:func:`solver_options` adds ``--solver NAME``, ``--solver-option KEY=VALUE`` (repeatable),
``--conic-solver NAME``, ``--fix NAME=VALUE`` and ``--bound NAME=LOW:HIGH`` (repeatable);
:func:`estimator_settings` turns them into the keyword settings of the estimator of a
``--method`` (:func:`optcal.calibrate`), refusing in one line an option the method does not take.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import click

#: Keyword names that :func:`solver_options` adds to a command.
SOLVER_OPTION_NAMES: tuple[str, ...] = ("solver", "solver_option", "conic_solver", "fix", "bound")

_OPTIONS: tuple[Callable[[Callable[..., Any]], Callable[..., Any]], ...] = (
    click.option("--solver", default=None, metavar="NAME",
                 help="NLP solver (a CasADi nlpsol plugin): ipopt (default), sqpmethod, sqpmethod+osqp, sqpmethod+qpoases, "
                      "fatrop, feasiblesqpmethod, uno, alpaqa, sleqp, bonmin, ...; one that does not run here is refused, "
                      "naming those that do."),
    click.option("--solver-option", multiple=True, metavar="KEY=VALUE",
                 help="An option of the NLP solver (CasADi's spelling: ipopt.max_iter=500, max_iter=50, "
                      "qpsol_options.print_iter=false); repeatable."),
    click.option("--conic-solver", default=None, metavar="NAME",
                 help="cvxpy solver of the convex ellipsoid fit: CLARABEL (default), SCS, or any installed one that "
                      "takes its semidefinite constraint."),
    click.option("--fix", multiple=True, metavar="NAME=VALUE",
                 help="Hold a parameter at a known value: θ entries T_xx..T_zz, o_x..o_z (bias, raw units), scale "
                      "factors S_x..S_z (raw units per g), angles rho, phi, lambda (degrees); repeatable. Zero standard error."),
    click.option("--bound", multiple=True, metavar="NAME=LOW:HIGH",
                 help="Bound a parameter (names as --fix; an empty side is unbounded, e.g. S_x=:16500); repeatable. "
                      "A bound active at the optimum is reported."),
)


def solver_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding the solver and constraint options (see the module docstring)."""
    for option in reversed(_OPTIONS):
        func = option(func)
    return func


def pop_solver_options(opts: dict[str, Any]) -> dict[str, Any]:
    """Remove the options of :func:`solver_options` from a command's keyword arguments and return them."""
    return {name: opts.pop(name) for name in SOLVER_OPTION_NAMES if name in opts}


def nlp_settings(solver: str | None = None, solver_option: tuple[str, ...] = (), **_: Any) -> dict[str, Any]:
    """``solver`` and ``solver_options`` from ``--solver`` and ``--solver-option`` (empty when neither is given)."""
    from optcal.solvers.registry import choose_nlp_solver, parse_solver_options

    out: dict[str, Any] = {}
    options = parse_solver_options(list(solver_option))
    if solver is not None or options:
        choose_nlp_solver(solver, options)  # refused here, in one line, before any data is read
        out["solver"] = solver
        if options:
            out["solver_options"] = options
    return out


def estimator_settings(method: str, solver: str | None = None, solver_option: tuple[str, ...] = (),
                       conic_solver: str | None = None, fix: tuple[str, ...] = (), bound: tuple[str, ...] = ()) -> dict[str, Any]:
    """The estimator's keyword settings from the options of :func:`solver_options`.

    ``--solver`` and ``--solver-option`` go to a method that solves an NLP through the solver
    catalogue (its estimator takes ``solver``), ``--conic-solver`` to ``convex`` (its ``solver``)
    and to the convex start of ``mle``, ``--fix`` and ``--bound`` to a method that takes
    ``fix`` and ``bounds``.  An option the method does not take is an :class:`~optcal.errors.InputError`.
    """
    from optcal.core.constraints import parse_cli
    from optcal.errors import InputError
    from optcal.families.accel.calibration import DEFAULT_METHOD, estimator_class
    from optcal.solvers.registry import choose_conic_solver

    name = DEFAULT_METHOD if method == "default" else method
    params = inspect.signature(estimator_class(method)).parameters
    settings: dict[str, Any] = {}
    nlp = nlp_settings(solver, solver_option)
    if nlp:
        if name == "convex" or "solver_options" not in params:
            raise InputError(f"--solver and --solver-option apply to the methods that solve an NLP by name (mle); "
                             f"not to {name}" + (" (its solver is --conic-solver)" if name == "convex" else ""))
        settings.update(nlp)
    if conic_solver is not None:
        chosen = choose_conic_solver(conic_solver)
        if "conic_solver" in params:
            settings["conic_solver"] = chosen
        else:
            raise InputError(f"--conic-solver applies to the convex fit and to mle's convex start; not to {name}")
    if fix or bound:
        constraints = parse_cli(fix, bound)
        if "fix" not in params:
            raise InputError(f"--fix and --bound apply to the mle method; not to {name}")
        settings["fix"] = dict(constraints.fixed)
        settings["bounds"] = dict(constraints.bounds)
    return settings


__all__ = ["SOLVER_OPTION_NAMES", "estimator_settings", "nlp_settings", "pop_solver_options", "solver_options"]
