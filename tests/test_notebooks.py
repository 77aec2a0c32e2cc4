"""Every study in ``studies/`` is a notebook: paired with its percent script, committed executed, and run here.

The studies are discovered by glob (every ``studies/*.py`` with a jupytext header), so a new study is
covered as soon as it is added.  Each one is executed in quick mode (``OPTCAL_STUDY_QUICK=1``; with
``OPTCAL_STUDY_REUSE=1`` a study that saves its full run redraws from it) with nbclient from its
script: a notebook that fails, fails this test.

The studies a test process runs share one kernel (speed only: starting a kernel and importing optcal, numpy,
pandas, matplotlib, cvxpy and CasADi into it costs about 3 CPU s, a sixth to a third of a quick study), reset
before each study to what a fresh kernel gives it: an empty namespace (``%reset -f``: a name a study uses but
does not define or import fails as it would alone), the folder ``studies/``, the ``sys.path`` the kernel started
with, the modules of ``studies/`` and ``tests/`` imported afresh, matplotlib's figures closed and its settings
the defaults.  A study that fails takes its kernel with it; the next study starts a new one.  (In a CPU record,
``OPTCAL_TEST_CPU_DIR``, the kernel's CPU time appears on the last study of its process, when it is shut down.)
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")
nbformat = pytest.importorskip("nbformat")

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


#: Run in the shared kernel before each study: what a new kernel would give it (module docstring).  The kernel's
#: own ``sys.path`` is kept at its start in ``sys._optcal_study_path``.
RESET_SOURCE = f"""
import os as _os, sys as _sys
import matplotlib as _mpl
import matplotlib.pyplot as _plt
_plt.close("all")
_mpl.rcdefaults()
_os.chdir({str(STUDIES)!r})
if not hasattr(_sys, "_optcal_study_path"):
    _sys._optcal_study_path = list(_sys.path)
_sys.path[:] = _sys._optcal_study_path
for _name, _module in list(_sys.modules.items()):
    _file = getattr(_module, "__file__", None) or ""
    if _file.startswith(({str(STUDIES) + os.sep!r}, {str(STUDIES.parent / "tests") + os.sep!r})):
        del _sys.modules[_name]
get_ipython().run_line_magic("reset", "-f")
"""


class StudyKernel:
    """One Jupyter kernel for the studies of one test process (started on first use, replaced after a failure)."""

    def __init__(self) -> None:
        self.manager: Any = None

    def ready(self) -> Any:
        """The kernel manager, its kernel started in quick mode or reset to a new kernel's state."""
        if self.manager is None:
            from jupyter_client.manager import KernelManager

            env = dict(os.environ)
            env["OPTCAL_STUDY_QUICK"] = "1"
            env["OPTCAL_STUDY_REUSE"] = "1"  # studies with a saved full run redraw from it (solver_comparison)
            env.setdefault("OPENBLAS_NUM_THREADS", "1")
            root = str(STUDIES.parent)
            env["PYTHONPATH"] = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)
            self.manager = KernelManager(kernel_name="python3")
            self.manager.start_kernel(cwd=str(STUDIES), env=env)
        self.execute(nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(RESET_SOURCE)]))
        return self.manager

    def execute(self, nb: Any) -> Any:
        """Execute every cell of ``nb`` in the kernel (CellExecutionError when one fails: the kernel is then shut
        down, so that the next study gets a new one)."""
        client = nbclient.NotebookClient(nb, km=self.manager, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                         resources={"metadata": {"path": str(STUDIES)}})
        try:
            client.execute()
        except BaseException:
            self.close()
            raise
        finally:
            if client.kc is not None:
                client.kc.stop_channels()
        return nb

    def close(self) -> None:
        if self.manager is not None:
            self.manager.shutdown_kernel(now=True)
            self.manager = None


@pytest.fixture(scope="module")
def study_kernel() -> Iterator[StudyKernel]:
    kernel = StudyKernel()
    yield kernel
    kernel.close()


@pytest.mark.parametrize("script", studies(), ids=lambda p: p.stem)
def test_study_runs_in_quick_mode(script: Path, study_kernel: StudyKernel) -> None:
    nb = jupytext.read(script)
    study_kernel.ready()
    study_kernel.execute(nb)  # raises CellExecutionError (with the cell and traceback) when a cell fails
    assert all(c.get("execution_count") for c in nb.cells if c.cell_type == "code")
