"""``optcal reproduce NAME``: reproduce a source paper's results."""

from __future__ import annotations

import click

from optcal.cli.lazy_group import LazyGroup
from optcal.cli.quiet import decide_progress, quiet_option

#: reproduction name -> "module:attribute" of its click command.  One line each.
REPRODUCTIONS: dict[str, str] = {
    "lu2017": "optcal.applications.papers.lu2017:command",
    "yin2014": "optcal.applications.papers.yin2014.reproduce:command",
    "sun2011": "optcal.applications.papers.sun2011.reproduce:command",
    "solvers": "optcal.applications.papers.solver_study:command",
}


# decided again on each reproduction's arguments: its own --json counts (the group's decision came before it was parsed)
@click.group(cls=LazyGroup, lazy_commands=REPRODUCTIONS, before_command=decide_progress)
@quiet_option
def reproduce() -> None:
    """Reproduce a source paper (lu2017, yin2014, sun2011) or the solver comparison."""
