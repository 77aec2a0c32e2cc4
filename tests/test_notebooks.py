"""Every study in ``studies/`` is a notebook: paired with its percent script, committed executed, and run here.

The studies are discovered by glob (every ``studies/*.py`` with a jupytext header), so a new study is
covered as soon as it is added.  Each one is executed in quick mode (``OPTCAL_STUDY_QUICK=1``; with
``OPTCAL_STUDY_REUSE=1`` a study that saves its full run redraws from it) with nbclient from its
script: a notebook that fails, fails this test.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")

STUDIES = Path(__file__).resolve().parents[1] / "studies"
#: Longest a notebook cell may run in quick mode, seconds.
CELL_TIMEOUT_S = 300


def studies() -> list[Path]:
    """The percent scripts of the studies (those with a jupytext header)."""
    return sorted(p for p in STUDIES.glob("*.py") if p.read_text(encoding="utf-8").startswith("# ---\n# jupyter:"))


def code_sources(nb: object) -> list[str]:
    return [c.source.strip() for c in nb.cells if c.cell_type == "code"]  # type: ignore[attr-defined]


def test_there_are_at_least_five_studies() -> None:
    assert len(studies()) >= 5


@pytest.mark.parametrize("script", studies(), ids=lambda p: p.stem)
def test_study_is_paired_and_committed_executed(script: Path) -> None:
    text = script.read_text(encoding="utf-8")
    assert "formats: ipynb,py:percent" in text, f"{script.name}: pair it with `jupytext --set-formats ipynb,py:percent`"
    notebook = script.with_suffix(".ipynb")
    assert notebook.exists(), f"{notebook.name} missing: run `jupytext --sync {script}` and execute it"
    nb = jupytext.read(notebook)
    assert code_sources(nb) == code_sources(jupytext.read(script)), f"{notebook.name} is out of sync with {script.name}"
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert all(c.get("execution_count") for c in code), f"{notebook.name} is not fully executed"
    assert not [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert f"studies/{notebook.name}" in (STUDIES / "README.md").read_text(encoding="utf-8")


@pytest.mark.parametrize("script", studies(), ids=lambda p: p.stem)
def test_study_runs_in_quick_mode(script: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OPTCAL_STUDY_QUICK", "1")
    monkeypatch.setenv("OPTCAL_STUDY_REUSE", "1")  # studies with a saved full run redraw from it (solver_comparison)
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", os.environ.get("OPENBLAS_NUM_THREADS", "1"))
    root = str(STUDIES.parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
    nb = jupytext.read(script)
    client = nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                     resources={"metadata": {"path": str(STUDIES)}})
    client.execute()  # raises CellExecutionError (with the cell and traceback) when a cell fails
    assert all(c.get("execution_count") for c in nb.cells if c.cell_type == "code")
