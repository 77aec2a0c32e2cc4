"""Every number given on the command line is finite (issue 40).

click's ``FloatRange`` lets ``nan`` through an unbounded side and ``inf`` through an open upper
bound, and a plain ``float`` option takes both; a flag that is not used by the mode a command runs
in would then be accepted silently.  One check on the parsed arguments, before any work, refuses
them all (every optcal option takes a quantity of the sensor, a time or a tolerance; none has a
meaning at infinity: a limit that is off is its flag left out).
"""

from __future__ import annotations

import math

import click

from optcal.errors import InputError


def _is_float_option(param: click.Parameter) -> bool:
    """True for an option whose values click converts to float (``float``, ``FloatRange``)."""
    return isinstance(param.type, click.types.FloatParamType)


def refuse_non_finite_numbers(context: click.Context) -> None:
    """Refuse a ``nan``, ``inf`` or ``-inf`` given to any float option of the command.

    Parameters
    ----------
    context : click.Context
        The command's context (its ``params`` parsed).

    Raises
    ------
    InputError
        One line naming the flag and the value, and what a finite value means.
    """
    for param in context.command.params:
        if not isinstance(param, click.Option) or not _is_float_option(param) or param.name is None:
            continue
        value = context.params.get(param.name)
        values = value if isinstance(value, (tuple, list)) else (value,)
        for v in values:
            if isinstance(v, float) and not math.isfinite(v):
                raise InputError(f"{param.opts[-1]} {v}: is not a finite number; give a finite value "
                                 "(or leave the flag out for its default)")
