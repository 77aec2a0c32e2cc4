"""``optcal reproduce NAME``: reproduce a source paper's results."""

from __future__ import annotations

import click

from optcal.cli.lazy_group import LazyGroup

#: reproduction name -> "module:attribute" of its click command.  One line each.
REPRODUCTIONS: dict[str, str] = {
    "lu2017": "optcal.applications.papers.lu2017:command",
    "yin2014": "optcal.applications.papers.yin2014.reproduce:command",
    "sun2011": "optcal.applications.papers.sun2011.reproduce:command",
    "solvers": "optcal.applications.papers.solver_study:command",
}


@click.group(cls=LazyGroup, lazy_commands=REPRODUCTIONS)
def reproduce() -> None:
    """Reproduce a source paper (lu2017, yin2014, sun2011) or the solver comparison."""
