"""Entry point of the ``optcal`` command.

Commands are loaded lazily (``COMMANDS`` maps a name to ``module:attribute``) so that
``optcal --help`` does not import CasADi and cvxpy.  Every :class:`~optcal.errors.InputError`
becomes one ``error: ...`` line on standard error and exit code 2, without a traceback.
"""

from __future__ import annotations

import importlib
import sys

import click

from optcal.errors import InputError

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
}


class LazyGroup(click.Group):
    """A click group whose sub-commands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = COMMANDS.get(cmd_name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="optcal")
def cli() -> None:
    """optcal: calibrate triaxial accelerometers as optimisation problems, and diagnose the model."""


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit code (2 for bad input)."""
    try:
        cli.main(args=argv, prog_name="optcal", standalone_mode=False,
                 obj={"argv": list(sys.argv[1:] if argv is None else argv)})
    except InputError as exc:
        click.echo(f"error: {exc}", err=True)
        return 2
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
