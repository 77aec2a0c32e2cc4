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
import re
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

#: How a library message's Python wording reads on the command line: regular expression ->
#: replacement, applied in order after the command's own table (:data:`COMMAND_SPELLING`).
#: IPOPT's advice when it stops early (optcal.families.accel.mle.IPOPT_REMEDY), which names Python arguments.
IPOPT_ADVICE = re.escape("raise the iteration limit (ipopt_options={'ipopt.max_iter': 1000}) or start from another fit (init=...)")
CLI_SPELLING: dict[str, str] = {
    # the command line sets no IPOPT options
    IPOPT_ADVICE:
        "on the command line, try --method convex (the convex fit alone, no IPOPT) or add poses in orientations "
        "not yet covered",
    re.escape('check ipopt_options, or use method="convex"'): "use --method convex",
    re.escape("raise the solver's iteration limit (solver_options) or try solver='SCS'"): "try --method mle",
    re.escape("pass a larger max_iter or a looser tol"): "use --method default instead",
    re.escape('method="convex"'): "--method convex",
    re.escape("allow_degenerate=True"): "--allow-degenerate",
    re.escape("scale_range=(low, high)"): "--scale-range LOW HIGH",
    r'\bunits="([^"]*)"': r"--units \1",
    r'\bcolumns="([^"]*)"': r"--columns \1",
    r"\bcolumns=": "--columns",
    r"\btime_unit\b": "--time-unit",
    r"\bcounts_per_g\b": "--counts-per-g",
    r"\bcounts_zero=(\S+)": r"--counts-zero \1",
    r"\ballan=": "--allan FILE",
    re.escape("random_walk_bound=True"): "--random-walk-bound",
    r"\bmax_loss_g( =)?": "--max-loss",
}

#: Per command: wording that reads differently there (the same Python argument, another flag).
COMMAND_SPELLING: dict[str, dict[str, str]] = {
    "apply": {r'\bunits="([^"]*)"': r"--data-units \1"},  # apply's --units is the output unit
    "export": {r' \(or pass units="[^"]*" if that is what it is\)': ""},  # export reads --poses in their own units
    "reproduce": {IPOPT_ADVICE: "the reproduction keeps that fit and reports it"},  # its fits are fixed by the paper
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


def cli_message(message: str, command: str | None = None) -> str:
    """A library message with the command line's flags in place of Python arguments.

    Parameters
    ----------
    message : str
        The library's message (Python wording).
    command : str, optional
        The optcal command that ran (``"apply"``); its :data:`COMMAND_SPELLING` is applied first.
    """
    for pattern, flag in (*COMMAND_SPELLING.get(command or "", {}).items(), *CLI_SPELLING.items()):
        message = re.sub(pattern, flag, message)
    return message


def command_name(argv: list[str]) -> str | None:
    """The optcal command in ``argv`` (its first word that is not an option)."""
    return next((word for word in argv if not word.startswith("-")), None)


def usage_message(exc: click.ClickException) -> str:
    """A click usage error as one line that points to the command's ``--help``."""
    message = " ".join(exc.format_message().split())
    context = getattr(exc, "ctx", None)
    if context is not None:
        message = f"{message.rstrip('.')}; see '{context.command_path} --help'"
    return message


def _show_warning(python_show: Callable[..., None], command: str | None, message: Warning | str,
                  category: type[Warning], *args: Any, **kwargs: Any) -> None:
    """optcal's warnings as one ``warning: ...`` line; any other warning as Python shows it."""
    if issubclass(category, ConvergenceWarning):
        click.echo(f"warning: {cli_message(str(message), command)}", err=True)
    else:
        python_show(message, category, *args, **kwargs)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit code (2 for bad input, 3 for a solver failure)."""
    args = list(sys.argv[1:] if argv is None else argv)
    command = command_name(args)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = functools.partial(_show_warning, warnings.showwarning, command)
            # without standalone mode click returns the code of a click.exceptions.Exit (e.g. a failed acceptance)
            exit_code = cli.main(args=argv, prog_name="optcal", standalone_mode=False, obj={"argv": args})
    except InputError as exc:
        click.echo(f"error: {cli_message(str(exc), command)}", err=True)
        return EXIT_INPUT_ERROR
    except SolverError as exc:
        click.echo(f"error: {cli_message(str(exc), command)}", err=True)
        return EXIT_SOLVER_ERROR
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 1
    except click.ClickException as exc:  # usage errors: bad option, missing argument, invalid value
        click.echo(f"error: {usage_message(exc)}", err=True)
        return EXIT_INPUT_ERROR
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except (BrokenPipeError, KeyboardInterrupt):
        return 1
    return exit_code if isinstance(exit_code, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
