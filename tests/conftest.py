"""Fixtures shared by every test (plain helpers live in tests/helpers), and the opt-in CPU-time record of the run."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

#: One BLAS thread per test process (numpy's, scipy's and CasADi's OpenBLAS read this when they load, and nothing has
#: loaded numpy before this conftest).  ``pytest -n auto`` already runs one process per core, so OpenBLAS's own
#: threads only contend with the other worker: tests/families/test_solvers.py and test_random_walk_bias.py with
#: ``-n 2`` took 31.0-31.3 CPU s with OpenBLAS's default threads against 25.6-26.6 with one (load 8-10), and pass
#: alike.  The workers, the notebooks' kernel and the CLI's subprocesses inherit it; a value already set wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from helpers.common import SHARED  # noqa: E402
from optcal.core.model import LumpedModel, lu2017_reference_model  # noqa: E402

#: ``OPTCAL_TEST_CPU_DIR=DIR pytest ...`` appends one JSON line per test to ``DIR/<worker>.jsonl``: its node id, the
#: CPU seconds of its setup, call and teardown (this process's threads and the children it waited for: a CLI
#: subprocess, a notebook kernel), its wall seconds and the time it ended.  CI's budget is CPU: ``pytest -n auto`` on
#: 2 cores takes about the suite's CPU seconds over 2, while a test's wall time on a shared machine measures the
#: queue (the same run measured 1135 CPU s against 4846 wall s under a load of 5-9).  Sum it per file with
#: ``python tests/helpers/cpu_record.py DIR``.
CPU_RECORD_DIR = os.environ.get("OPTCAL_TEST_CPU_DIR")


def _cpu_seconds() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    if not CPU_RECORD_DIR:
        yield
        return
    cpu, wall = _cpu_seconds(), time.perf_counter()
    yield
    row = [item.nodeid, _cpu_seconds() - cpu, time.perf_counter() - wall, time.time()]
    os.makedirs(CPU_RECORD_DIR, exist_ok=True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    with open(os.path.join(CPU_RECORD_DIR, f"{worker}.jsonl"), "a", encoding="utf-8") as fh:
        fh.write(json.dumps(row) + "\n")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "static_check: the type checker or the docs build, started before the tests")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The static checks (tests/test_static_checks.py, a minute each in one process) first: ``pytest -n auto``
    hands them out at the start, and the other worker runs the tests meanwhile, rather than a core idling at the end."""
    items.sort(key=lambda item: item.get_closest_marker("static_check") is None)


@pytest.fixture
def lu_model() -> LumpedModel:
    return lu2017_reference_model()


@pytest.fixture
def shared_data() -> Path:
    d = SHARED / "data"
    if not d.is_dir():
        pytest.skip("../shared/data is not present")
    return d
