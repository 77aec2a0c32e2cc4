"""Exceptions raised by optcal.

Every problem with the user's input raises :class:`InputError` (or a subclass) with a
message that says what is wrong and how to fix it.  The command line turns these into a
single ``error: ...`` line on standard error and exit code 2, without a traceback.
"""

from __future__ import annotations


class OptcalError(Exception):
    """Base class of all optcal errors."""


class InputError(OptcalError, ValueError):
    """The data or the options given by the user cannot be used as they are."""


class IdentifiabilityError(InputError):
    """The pose set does not identify every calibration parameter.

    Attributes
    ----------
    report : optcal.identifiability.IdentifiabilityReport
        Rank, conditioning and the unidentifiable parameter combinations.
    """

    def __init__(self, message: str, report: object | None = None) -> None:
        super().__init__(message)
        self.report = report


class SolverError(OptcalError, RuntimeError):
    """A numerical solver failed in a way the caller should know about."""


class FitError(InputError):
    """The data do not determine a calibration by the chosen method (e.g. a hyperboloid)."""
