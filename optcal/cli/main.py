"""Entry point of the ``optcal`` command.

Commands are loaded lazily (``COMMANDS`` maps a name to ``module:attribute``) so that
``optcal --help`` does not import CasADi and cvxpy.  Every :class:`~optcal.errors.InputError`
becomes one ``error: ...`` line on standard error and exit code 2 (bad input), every
:class:`~optcal.errors.SolverError` one ``error: ...`` line and exit code 3 (a solver failed),
without a traceback; optcal's warnings (:class:`~optcal.errors.ConvergenceWarning`) become one
``warning: ...`` line.  Library messages name Python arguments; :func:`cli_message` puts the
command line's flags in their place (:data:`CLI_SPELLING`).
"""

from __future__ import annotations

import functools
import sys
import warnings
from collections.abc import Callable
from typing import Any

import click

from optcal.cli.lazy_group import LazyGroup
from optcal.errors import ConvergenceWarning, InputError, SolverError

#: Exit codes: bad input (the user can fix the data or options) and a solver failure.
EXIT_INPUT_ERROR = 2
EXIT_SOLVER_ERROR = 3

#: How a library message's Python argument reads on the command line.
CLI_SPELLING: dict[str, str] = {
    'method="convex"': "--method convex",
    "allow_degenerate=True": "--allow-degenerate",
    "scale_range=(low, high)": "--scale-range LOW HIGH",
}

#: name -> "module:attribute" of a click command.  Add one line per command.
COMMANDS: dict[str, str] = {
    "calibrate": "optcal.cli.cmd_calibrate:calibrate",
    "simulate": "optcal.cli.cmd_simulate:simulate",
    "diagnose": "optcal.cli.cmd_diagnose:diagnose",
    "demo": "optcal.cli.cmd_demo:demo",
    "reproduce": "optcal.cli.cmd_reproduce:reproduce",
    "segment": "optcal.cli.cmd_segment:segment",
    "check": "optcal.cli.cmd_check:check",
    "allan": "optcal.cli.cmd_allan:allan",
    "apply": "optcal.cli.cmd_apply:apply",
    "export": "optcal.cli.cmd_export:export",
    "plan": "optcal.cli.cmd_plan:plan",
    "fleet": "optcal.cli.cmd_fleet:fleet",
}


@click.group(cls=LazyGroup, lazy_commands=COMMANDS, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="optcal")
def cli() -> None:
    """optcal: calibrate triaxial accelerometers as optimisation problems, and diagnose the model."""


def cli_message(message: str) -> str:
    """A library message with the command line's flags in place of Python arguments."""
    for python, flag in CLI_SPELLING.items():
        message = message.replace(python, flag)
    return message


def _show_warning(python_show: Callable[..., None], message: Warning | str, category: type[Warning],
                  *args: Any, **kwargs: Any) -> None:
    """optcal's warnings as one ``warning: ...`` line; any other warning as Python shows it."""
    if issubclass(category, ConvergenceWarning):
        click.echo(f"warning: {cli_message(str(message))}", err=True)
    else:
        python_show(message, category, *args, **kwargs)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit code (2 for bad input, 3 for a solver failure)."""
    try:
        with warnings.catch_warnings():
            warnings.showwarning = functools.partial(_show_warning, warnings.showwarning)
            cli.main(args=argv, prog_name="optcal", standalone_mode=False,
                     obj={"argv": list(sys.argv[1:] if argv is None else argv)})
    except InputError as exc:
        click.echo(f"error: {cli_message(str(exc))}", err=True)
        return EXIT_INPUT_ERROR
    except SolverError as exc:
        click.echo(f"error: {cli_message(str(exc))}", err=True)
        return EXIT_SOLVER_ERROR
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 1
    except click.ClickException as exc:  # usage errors: bad option, missing argument
        exc.show()
        return 2
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except (BrokenPipeError, KeyboardInterrupt):
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
