"""A click group whose sub-commands are imported on first use (``optcal --help`` imports no solver)."""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from typing import Any

import click


class LazyGroup(click.Group):
    """A click group of sub-commands given as ``name -> "module:attribute"``, imported when used.

    Parameters
    ----------
    lazy_commands : dict
        The sub-commands (``click.group(cls=LazyGroup, lazy_commands={...})``).
    before_command : callable, optional
        Called with each sub-command's context once its arguments are parsed and before its
        body runs (checks every command shares, such as an output that is an input).
    """

    def __init__(self, *args: Any, lazy_commands: dict[str, str],
                 before_command: Callable[[click.Context], None] | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.lazy_commands = lazy_commands
        self.before_command = before_command

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(self.lazy_commands)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list of ``--help``, from the sources' docstrings: no command is imported."""
        rows = [
            (name, command_short_help(self.lazy_commands[name], formatter.width - 6 - len(name)))
            for name in self.list_commands(ctx)
        ]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = self.lazy_commands.get(cmd_name)
        if target is None:
            return None
        module, attr = target.split(":")
        command: click.Command = getattr(importlib.import_module(module), attr)
        if self.before_command is not None and command.callback is not None \
                and getattr(command.callback, "_optcal_before", None) is not self.before_command:
            command.callback = _checked(command.callback, self.before_command)
        return command


def _checked(callback: Callable[..., Any], before: Callable[[click.Context], None]) -> Callable[..., Any]:
    """``callback`` preceded by ``before(context)`` (the command's own context, arguments parsed)."""

    @functools.wraps(callback)
    def run(*args: Any, **kwargs: Any) -> Any:
        before(click.get_current_context())
        return callback(*args, **kwargs)

    run._optcal_before = before  # type: ignore[attr-defined]  # wrapped once per command object
    return run


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
