"""``optcal reproduce NAME``: reproduce a source paper's results."""

from __future__ import annotations

import importlib

import click

#: reproduction name -> "module:attribute" of its click command.  One line each.
REPRODUCTIONS: dict[str, str] = {
    "lu2017": "optcal.reproduce.lu2017:command",
    "yin2014": "optcal.reproduce.yin2014:command",
    "sun2011": "optcal.reproduce.sun2011:command",
    "solvers": "optcal.reproduce.solvers:command",
}


class _LazyReproductions(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(REPRODUCTIONS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = REPRODUCTIONS.get(cmd_name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)


@click.group(cls=_LazyReproductions)
def reproduce() -> None:
    """Reproduce a source paper (lu2017, yin2014, sun2011) or the solver comparison."""
