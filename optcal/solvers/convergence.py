"""What a solver did, and whether its answer can be used: the solver record and the convergence check.

* :func:`solver_record` — a CasADi ``nlpsol``'s statistics as the :class:`~optcal.core.fit_result.SolverInfo`
  of a result (name, status, success, iterations, solve time).
* :func:`check_solver` — a failed solve (an error status of :data:`SOLVER_FAILURES`, a non-finite
  answer) is a :class:`~optcal.errors.SolverError`; a solve that stopped before its convergence
  test passed is a :class:`~optcal.errors.ConvergenceWarning`, its last iterate kept.  The
  :class:`Remedy` of the estimator says which argument to change.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.fit_result import SolverInfo
from optcal.errors import ConvergenceWarning, SolverError

#: Solver statuses that mean a failure (no usable answer), not an early stop: IPOPT's error
#: return codes (``ApplicationReturnStatus`` of IpReturnCodes.h, as CasADi names them) and the
#: gradient descent's divergence.
SOLVER_FAILURES: frozenset[str] = frozenset({
    "Infeasible_Problem_Detected", "Diverging_Iterates", "Error_In_Step_Computation",
    "Not_Enough_Degrees_Of_Freedom", "Invalid_Problem_Definition", "Invalid_Option", "Invalid_Number_Detected",
    "Unrecoverable_Exception", "NonIpopt_Exception_Thrown", "Insufficient_Memory", "Internal_Error",
    "diverged",
    # CasADi's plugin-independent statuses (``unified_return_status``) that mean no usable answer
    "SOLVER_RET_NAN", "SOLVER_RET_INFEASIBLE", "SOLVER_RET_EXCEPTION",
})


@dataclass(frozen=True)
class Remedy:
    """What to tell the user when an estimator's solver stops early or fails (Python arguments)."""

    stopped_early: str
    failed: str


def solver_record(stats: dict[str, Any], seconds: float, name: str = "IPOPT", message: str = "",
                  iterations: int | None = None) -> SolverInfo:
    """The :class:`SolverInfo` of a CasADi ``nlpsol`` solve from its statistics.

    Parameters
    ----------
    stats : dict
        ``solver.stats()`` of the (last) solve: ``return_status``, ``success``, ``iter_count``.
    seconds : float
        Wall time of the solve(s).
    name : str
        The solver as the record names it.
    message : str
        Anything else worth saying (the problem's form, the passes).
    iterations : int, optional
        Iterations of all the solves when there were several (the last solve's count otherwise).
    """
    return SolverInfo(
        name=name,
        status=plugin_status(stats),
        success=bool(stats.get("success", False)),
        iterations=plugin_iterations(stats) if iterations is None else int(iterations),
        solve_time_s=float(seconds),
        message=message,
    )


def plugin_status(stats: dict[str, Any]) -> str:
    """The plugin's own status (``return_status``), or CasADi's unified one when the plugin gives none.

    A plugin's numeric status (fatrop's 0) is kept with its unified meaning: ``"0 (SOLVER_RET_SUCCESS)"``.
    """
    own = stats.get("return_status")
    unified = stats.get("unified_return_status")
    if own is None or own == "":
        return str(unified or "unknown")
    if not isinstance(own, str) and unified:
        return f"{own} ({unified})"
    return str(own)


def plugin_iterations(stats: dict[str, Any]) -> int:
    """The plugin's iteration count; for a plugin that reports none (alpaqa), its gradient evaluations."""
    count = stats.get("iter_count")
    if count is not None:
        return int(count)
    gradients = [int(v) for k, v in stats.items() if k.startswith("n_call_nlp_grad") and isinstance(v, (int, float))]
    return max(gradients, default=0)


def check_solver(method: str, solver: SolverInfo, theta: NDArray, remedy: Remedy | None = None) -> None:
    """Raise :class:`SolverError` for a failed solve; warn :class:`ConvergenceWarning` for an early stop.

    A failure: a status in :data:`SOLVER_FAILURES` or a non-finite θ.  An early stop: the
    solver does not report success but returned a finite answer (kept, its record says so).
    """
    finite = bool(np.all(np.isfinite(theta)))
    if solver.status in SOLVER_FAILURES or not finite:
        raise SolverError(
            f"the {method} fit failed: {solver.name} ended with {solver.status!r}"
            + ("" if finite else " and a non-finite answer")
            + (f"; {remedy.failed}" if remedy else "")
        )
    if not solver.success:
        warnings.warn(
            f"the {method} fit did not converge: {solver.name} stopped with {solver.status!r} after "
            f"{solver.iterations} iterations; the result is its last iterate"
            + (f"; {remedy.stopped_early}" if remedy else ""),
            ConvergenceWarning,
            stacklevel=3,
        )


__all__ = ["SOLVER_FAILURES", "Remedy", "check_solver", "plugin_iterations", "plugin_status", "solver_record"]
