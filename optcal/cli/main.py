"""Entry point of the ``optcal`` command.

Commands are loaded lazily (``COMMANDS`` maps a name to ``module:attribute``) so that
``optcal --help`` does not import CasADi and cvxpy.  Every :class:`~optcal.errors.InputError`
becomes one ``error: ...`` line on standard error and exit code 2 (bad input), every
:class:`~optcal.errors.SolverError` one ``error: ...`` line and exit code 3 (a solver failed),
without a traceback; a file that cannot be read or written (:class:`OSError`) is one line and
exit code 2, Ctrl-C exit code 130 with no partial output left; optcal's warnings (:class:`~optcal.errors.ConvergenceWarning`) become one
``warning: ...`` line.  Library messages name Python arguments; :func:`optcal.cli.messages.cli_message`
puts the command line's flags in their place.
"""

from __future__ import annotations

import functools
import os
import sys
import warnings
from collections.abc import Callable
from typing import Any

import click

from optcal.cli.lazy_group import LazyGroup
from optcal.cli.messages import cli_message, missing_extra_message
from optcal.errors import ConvergenceWarning, InputError, SolverError

#: Exit codes: bad input (the user can fix the data or options), a solver failure, and an interrupt
#: (128 + SIGINT, as a shell reports a command ended by Ctrl-C).
EXIT_INPUT_ERROR = 2
EXIT_SOLVER_ERROR = 3
EXIT_INTERRUPTED = 130

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


#: Commands whose linear algebra is all of tall, thin matrices (the rest model's (n, 3) by (3, 3) products, the noise
#: fit's small least squares) while the command runs threads of its own on every core (the ranged reader, the rest
#: check beside the Allan analysis): there BLAS's own pool of a thread per core finds each core taken, a product of
#: 172,800 rows waited 50-150 ms for its second thread instead of taking 2 ms on one, and the pool's threads spin after
#: each call on the core the command's other thread needs (0.15 s of CPU, of it 0.07 s on the rest check, on the
#: 12-hour still log).  Its thread variables are set to one for them when unset (a variable the user set wins), before
#: numpy is imported: the same products and sums, on one thread.
ONE_BLAS_THREAD: frozenset[str] = frozenset({"allan"})
BLAS_THREAD_VARIABLES: tuple[str, ...] = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread(command: str | None) -> bool:
    """Set BLAS to one thread for a command of :data:`ONE_BLAS_THREAD` run in a process that has not imported numpy
    yet (where the setting can still take effect; never in a process that has, whose pool is made); True if set."""
    if command not in ONE_BLAS_THREAD or "numpy" in sys.modules:
        return False
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    return True


def _before_command(context: click.Context) -> None:
    """What every command does on its parsed arguments before any work: refuse a number that is not
    finite and an output that is an input, and decide once whether long work shows progress (:func:`decide_progress`)."""
    from optcal.cli.numbers import refuse_non_finite_numbers
    from optcal.cli.outputs import refuse_outputs_over_inputs
    from optcal.cli.quiet import decide_progress

    refuse_non_finite_numbers(context)
    refuse_outputs_over_inputs(context)
    decide_progress(context)


@click.group(cls=LazyGroup, lazy_commands=COMMANDS, before_command=_before_command, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="optcal")
@click.option("-q", "--quiet", is_flag=True, help="No progress bars on standard error (they appear only in a terminal).")
@click.pass_context
def cli(context: click.Context, quiet: bool) -> None:
    """optcal: calibrate triaxial accelerometers as optimisation problems, and diagnose the model."""
    if isinstance(context.obj, dict):
        context.obj["quiet"] = quiet


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
    one_blas_thread(command)
    from optcal.core import progress

    progress.set_enabled(False)  # until the command's arguments decide (_before_command)
    try:
        return _run(args, argv, command)
    finally:
        progress.set_enabled(False)  # a library call after main() in the same process draws nothing


def _run(args: list[str], argv: list[str] | None, command: str | None) -> int:
    """:func:`main`'s body: the command run, its failures turned into one line and an exit code."""
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
    except click.exceptions.Abort:  # click's form of Ctrl-C; the outputs are written whole or not at all
        click.echo("interrupted: nothing written", err=True)
        return EXIT_INTERRUPTED
    except click.ClickException as exc:  # usage errors: bad option, missing argument, invalid value
        click.echo(f"error: {usage_message(exc)}", err=True)
        return EXIT_INPUT_ERROR
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except KeyboardInterrupt:  # an output being written is removed (optcal.core.atomic): nothing partial is left
        click.echo("interrupted: nothing written", err=True)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return 1
    except ImportError as exc:  # an optional package missing: one line with the extra that installs it
        message = missing_extra_message(exc, command)
        if message is None:
            raise
        click.echo(f"error: {message}", err=True)
        return EXIT_INPUT_ERROR
    except OSError as exc:  # a file that cannot be read or written (read-only folder, full disk, /proc): one line
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"error: {where}{exc.strerror or exc}", err=True)
        return EXIT_INPUT_ERROR
    return exit_code if isinstance(exit_code, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
