"""The README is a front page a newcomer reads in two minutes, and its two commands are what CI runs.

The README's test command must be exactly the command ``.ci/run`` runs (so the README cannot promise a check CI
skips), its install command must install and run ``optcal demo``, and the page stays short: everything else
lives in the documentation site (``docs/``), whose pages the README's links must name.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The README's size limit, characters: a page read in about two minutes (issue 40).
README_MAX_CHARS = 8000


def readme() -> str:
    return (ROOT / "README.md").read_text(encoding="utf-8")


def bash_blocks(text: str) -> list[str]:
    """The contents of the ```bash fenced blocks of a Markdown text, stripped."""
    return [block.strip() for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S)]


def ci_command() -> str:
    """The one command line of ``.ci/run`` after its preamble (comments, ``set``, ``cd``)."""
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()]
    commands = [line for line in lines if line and not line.startswith(("#", "set ", "cd "))]
    assert len(commands) == 1, f".ci/run should run one command line, found {commands}"
    return commands[0]


def test_readme_is_at_most_8000_characters() -> None:
    assert len(readme()) <= README_MAX_CHARS, f"README.md has {len(readme())} characters (at most {README_MAX_CHARS})"


def test_readme_test_command_is_exactly_what_ci_runs() -> None:
    blocks = bash_blocks(readme())
    assert ci_command() in blocks, "the README's test command differs from .ci/run's"


def test_readme_install_command_runs_the_demo_and_ci_builds_the_docs() -> None:
    first = bash_blocks(readme())[0]
    assert first.startswith("python3 -m venv .venv") and first.endswith(".venv/bin/optcal demo")
    # CI builds the docs with warnings as errors and type-checks among the tests it runs (tests/test_static_checks.py)
    assert "pytest" in ci_command()
    checks = (ROOT / "tests" / "test_static_checks.py").read_text(encoding="utf-8")
    assert '"mkdocs", "build", "--strict"' in checks and '"-m", "mypy"' in checks


def test_readme_links_point_to_existing_files() -> None:
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme())
    local = [t for t in targets if not t.startswith(("http://", "https://"))]
    assert local, "the README should link into the documentation"
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, f"README links to missing files: {missing}"


def test_readme_python_quick_start_runs_and_equals_the_command_line(shared_data, tmp_path, monkeypatch) -> None:
    """The README's Python block, run as written in a folder holding the Xsens log it names: the saved calibration is
    the one the command line saves with the same flag (issue 40: the main job in five lines, shown and tested)."""
    import json
    import os

    from optcal.cli.main import main

    blocks = re.findall(r"```python\n(.*?)```", readme(), flags=re.S)
    assert blocks, "the README has no Python quick start"
    os.symlink(shared_data / "imutk-xsens" / "xsens_imutk.csv", tmp_path / "xsens_imutk.csv")
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[0], "README.md", "exec"), {})  # noqa: S102 - the README's own code
    saved = json.loads((tmp_path / "c.json").read_text())
    assert main(["calibrate", "xsens_imutk.csv", "--rate", "100", "-o", "cli.json"]) == 0
    cli = json.loads((tmp_path / "cli.json").read_text())
    assert saved["T"] == cli["T"] and saved["o"] == cli["o"]
