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

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list of ``optcal --help``, from the sources' docstrings: no command is imported."""
        rows = [(name, command_short_help(COMMANDS[name], formatter.width - 6 - len(name))) for name in self.list_commands(ctx)]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = COMMANDS.get(cmd_name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)


def command_short_help(target: str, limit: int) -> str:
    """First sentence of a command's docstring, read from its source file without importing it."""
    import ast
    import importlib.util

    module, attr = target.split(":")
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        return ""
    with open(spec.origin, encoding="utf-8") as fh:
        tree = ast.parse(fh.read())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == attr:
            return first_sentence(ast.get_docstring(node) or "", max(limit, 30))
    return ""


def first_sentence(doc: str, limit: int) -> str:
    """The first sentence of ``doc`` on one line, cut to ``limit`` characters with '...'."""
    text = " ".join(doc.split("\n\n")[0].split())
    end = text.find(". ")
    text = text[: end + 1] if end >= 0 else text
    return text if len(text) <= limit else text[: limit - 3].rsplit(" ", 1)[0] + "..."


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="optcal")
def cli() -> None:
    """optcal: calibrate triaxial accelerometers as optimisation problems, and diagnose the model."""


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit code (2 for bad input)."""
    try:
        cli.main(args=argv, prog_name="optcal", standalone_mode=False)
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
