"""Rendering a :class:`~optcal.report.document.ReportDocument` as one self-contained HTML file.

The page is the Jinja2 template ``templates/report.html.j2`` (package data) with its
stylesheet inlined, figures inline (SVG or base64 PNG), no script and a Content-Security-Policy
that forbids every network request, so it opens offline, on a phone and in print.
"""

from __future__ import annotations

from pathlib import Path

from optcal.errors import InputError
from optcal.report.document import ReportDocument


def render_html(doc: ReportDocument) -> str:
    """The HTML text of ``doc``."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("optcal.report", "templates"),
        autoescape=jinja2.select_autoescape(("html", "j2")),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    return env.get_template("report.html.j2").render(doc=doc)


def write_html(doc: ReportDocument, path: str | Path) -> Path:
    """Write ``doc`` to ``path`` (a ``.html`` file); return the path."""
    p = Path(path)
    if p.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"report path {str(p)!r} must end in .html")
    if p.parent and not p.parent.exists():
        raise InputError(f"report path {str(p)!r}: the directory {str(p.parent)!r} does not exist")
    from optcal.core.atomic import write_text_atomic

    write_text_atomic(p, render_html(doc))  # whole or not at all
    return p
