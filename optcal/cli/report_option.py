"""The ``--report FILE.html`` and ``--tolerance MG`` options shared by the commands that write an HTML report.

Usage in a command module::

    @report_options
    def calibrate(..., report_path: str | None, tolerance: float) -> None:
        ...
        if report_path:
            write_report(calibration_document(..., command=command_line()), report_path)
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from collections.abc import Callable
from typing import Any

import click

#: Default tolerance of the verdict, mg (kept equal to :data:`optcal.applications.quality.verdict.DEFAULT_TOLERANCE_MG`,
#: which is not imported here so that ``optcal --help`` stays light).
DEFAULT_TOLERANCE_MG: float = 1.0


def report_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding ``--report FILE.html`` and ``--tolerance MG``."""
    func = click.option("--tolerance", type=click.FloatRange(min=0, min_open=True), default=DEFAULT_TOLERANCE_MG,
                        show_default=True, metavar="MG",
                        help="Accuracy asked of the calibrated norm, mg: the verdict of --report is judged against it.")(func)
    return click.option("--report", "report_path", type=click.Path(dir_okay=False), default=None, metavar="FILE.html",
                        callback=check_report_path,
                        help="Write a self-contained HTML report with a verdict (good / usable with care / not usable).")(func)


def check_report_path(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """Refuse a report path that is not an ``.html`` file in an existing directory, before any work is done."""
    from pathlib import Path

    from optcal.errors import InputError

    if value is None:
        return None
    path = Path(value)
    if path.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"--report {value}: the report is an HTML file; give a name ending in .html")
    if not path.parent.is_dir():
        raise InputError(f"--report {value}: the directory {path.parent} does not exist")
    return value


def command_line() -> str:
    """The command line being run, as the user typed it (``optcal`` and its arguments, shell-quoted)."""
    ctx = click.get_current_context(silent=True)
    root = ctx.find_root() if ctx is not None else None
    argv = root.obj.get("argv") if root is not None and isinstance(root.obj, dict) else None
    return shlex.join(["optcal", *(sys.argv[1:] if argv is None else argv)])


def write_report(doc: Any, path: str) -> None:
    """Render ``doc`` to ``path`` and say so on standard error."""
    from optcal.report.render import write_html

    from optcal.cli.outputs import refuse_input

    refuse_input(Path(path), "--report")
    write_html(doc, path)  # whole or not at all (optcal.core.atomic)
    click.echo(f"report: {path} (verdict: {doc.verdict.level})", err=True)
