"""The type checker and the documentation build, as tests: run inside ``pytest -n auto`` they share the cores with
the other tests instead of running alone after them (two single-process minutes of CI's fifteen on 2 cores).  Each
is started first (``tests/conftest.py`` moves them to the front of the collection) and skips where its tool is not
installed (the ``test`` extra has mypy, the ``docs`` extra mkdocs)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.static_check
def test_the_package_type_checks_clean() -> None:
    """``python -m mypy`` over optcal/ (its configuration in pyproject.toml) reports no error."""
    if importlib.util.find_spec("mypy") is None:
        pytest.skip("mypy is not installed (pip install -e '.[test]')")
    done = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


@pytest.mark.static_check
def test_the_documentation_builds_with_warnings_as_errors(tmp_path: Path) -> None:
    """``mkdocs build --strict`` (a malformed numpydoc docstring, a broken link or a page missing from the nav fails
    it) into a temporary folder, never into the repository."""
    if importlib.util.find_spec("mkdocs") is None:
        pytest.skip("mkdocs is not installed (pip install -e '.[docs]')")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
