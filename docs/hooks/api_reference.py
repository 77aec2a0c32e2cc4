"""MkDocs hook: the API and CLI references written from the code at build time.

Every public name of the package (``optcal.__all__``, including those imported on first use through
``optcal._LAZY``) gets one mkdocstrings block at the module that defines it, and every command of
``optcal.cli.main.COMMANDS`` one mkdocs-click block at its click object, so a name or a command added to the
code appears in the reference without editing a page, and one that cannot be imported fails the build.
"""

from __future__ import annotations

import importlib
from typing import Any

#: The CLI page's marker, replaced by one mkdocs-click block per command.
CLI_MARKER = "<!-- optcal-cli-commands -->"

#: The page whose ``<!-- optcal-public-names -->`` marker is replaced by the blocks.
MARKER = "<!-- optcal-public-names -->"


def public_blocks() -> str:
    """The mkdocstrings blocks of every name in ``optcal.__all__``, in its order.

    Returns
    -------
    str
        Markdown: one ``::: module.qualname`` block per function, class or exception, and a line for each
        plain value (``__version__``).
    """
    optcal = importlib.import_module("optcal")
    lines: list[str] = []
    for name in optcal.__all__:
        obj: Any = getattr(optcal, name)  # raises for a name in __all__ that does not exist: the build fails
        module = getattr(obj, "__module__", None)
        qualname = getattr(obj, "__qualname__", None)
        if module is None or qualname is None or isinstance(obj, str):
            lines += [f"### `optcal.{name}`", "", f"`{obj!r}`", ""]
            continue
        lines += [f"::: {module}.{qualname}", "    options:", "      heading_level: 3", ""]
    return "\n".join(lines)


def cli_blocks() -> str:
    """The mkdocs-click blocks of every command registered in ``optcal.cli.main.COMMANDS``.

    Returns
    -------
    str
        Markdown: one ``::: mkdocs-click`` block per command (its module and click object), in the order of
        ``COMMANDS``.
    """
    commands: dict[str, str] = importlib.import_module("optcal.cli.main").COMMANDS
    lines: list[str] = []
    for name, target in commands.items():
        module, attribute = target.split(":")
        importlib.import_module(module)  # a command that does not import fails the build here, by name
        lines += ["::: mkdocs-click", f"    :module: {module}", f"    :command: {attribute}",
                  f"    :prog_name: optcal {name}", "    :depth: 1", "    :style: table", ""]
    return "\n".join(lines)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Replace the markers of the API and CLI pages by their blocks (MkDocs hook)."""
    if MARKER in markdown:
        markdown = markdown.replace(MARKER, public_blocks())
    if CLI_MARKER in markdown:
        markdown = markdown.replace(CLI_MARKER, cli_blocks())
    return markdown
