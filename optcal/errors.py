"""Exceptions and warnings raised by optcal.

* :class:`InputError` (and its subclasses :class:`IdentifiabilityError`, :class:`FitError`):
  the data or the options cannot be used as they are; the message says what is wrong and
  which argument fixes it.  Command line: one ``error: ...`` line, exit code 2.
* :class:`SolverError`: a numerical solver failed (it raised, returned an error status or a
  non-finite answer) on input that was acceptable.  Command line: one ``error: ...`` line,
  exit code 3.
* :class:`ConvergenceWarning`: a solver stopped before its convergence test passed (an
  iteration limit, a stalled line search); the result is returned, its solver record says
  so (``result.solver.success`` is false).  Command line: one ``warning: ...`` line.

Messages name Python arguments (``allow_degenerate=True``); the command line translates them
into its flags (:data:`optcal.cli.messages.CLI_SPELLING`).
"""

from __future__ import annotations

from typing import Protocol


class RankSummary(Protocol):
    """The rank test an :class:`IdentifiabilityError` carries.

    :class:`optcal.core.identifiability.RankReport` provides it (the accelerometer's
    ``IdentifiabilityReport``, the gyro's ``GyroIdentifiability``).
    """

    rank: int
    n_params: int


class OptcalError(Exception):
    """Base class of all optcal errors."""


class InputError(OptcalError, ValueError):
    """The data or the options given by the user cannot be used as they are."""


class IdentifiabilityError(InputError):
    """The pose set does not identify every calibration parameter.

    Attributes
    ----------
    report : RankSummary or None
        Rank, conditioning and the unidentifiable parameter combinations (an
        ``IdentifiabilityReport`` for the accelerometer, a ``GyroIdentifiability`` for the gyro).
    """

    def __init__(self, message: str, report: RankSummary | None = None) -> None:
        super().__init__(message)
        self.report = report


class SolverError(OptcalError, RuntimeError):
    """A numerical solver failed: it raised, returned an error status or a non-finite answer."""


class FitError(InputError):
    """The data do not determine a calibration by the chosen method (e.g. a hyperboloid)."""


class ConvergenceWarning(UserWarning):
    """A solver stopped before converging; the returned result is its last iterate."""
