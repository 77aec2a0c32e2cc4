"""``optcal allan`` runs BLAS on one thread (its products are of tall, thin matrices beside its own threads), set
before numpy is imported, unless the user set the thread count; never changed in a process that imported numpy."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np  # noqa: F401  (this process has numpy: one_blas_thread must leave it alone)

from optcal.cli.main import BLAS_THREAD_VARIABLES, one_blas_thread


def _fresh(code: str, **env: str) -> str:
    base = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env={**base, **env})
    return done.stdout.strip()


def test_one_blas_thread_for_allan_in_a_fresh_process_only():
    probe = ("import os, sys; from optcal.cli.main import one_blas_thread; done = one_blas_thread(sys.argv[1]); "
             "import numpy; print(done, os.environ.get('OPENBLAS_NUM_THREADS'), len(os.listdir('/proc/self/task')))")
    allan = _fresh(probe.replace("sys.argv[1]", "'allan'")).split()
    assert allan[:2] == ["True", "1"] and (not os.path.isdir("/proc/self/task") or allan[2] == "1")  # no BLAS pool
    assert _fresh(probe.replace("sys.argv[1]", "'calibrate'")).split()[:2] == ["False", "None"]
    assert _fresh(probe.replace("sys.argv[1]", "'allan'"), OPENBLAS_NUM_THREADS="2").split()[:2] == ["True", "2"]
    before = {k: os.environ.get(k) for k in BLAS_THREAD_VARIABLES}
    assert not one_blas_thread("allan") and {k: os.environ.get(k) for k in BLAS_THREAD_VARIABLES} == before
