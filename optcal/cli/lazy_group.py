"""A click group whose sub-commands are imported on first use (``optcal --help`` imports no solver)."""

from __future__ import annotations

import importlib
from typing import Any

import click


class LazyGroup(click.Group):
    """A click group of sub-commands given as ``name -> "module:attribute"``, imported when used.

    Parameters
    ----------
    lazy_commands : dict
        The sub-commands (``click.group(cls=LazyGroup, lazy_commands={...})``).
    """

    def __init__(self, *args: Any, lazy_commands: dict[str, str], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.lazy_commands = lazy_commands

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(self.lazy_commands)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = self.lazy_commands.get(cmd_name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)
