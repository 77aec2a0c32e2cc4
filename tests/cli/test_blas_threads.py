"""``optcal allan`` runs BLAS on one thread (its products are of tall, thin matrices beside its own threads), set
before numpy is imported, unless the user set the thread count; never changed in a process that imported numpy."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np  # noqa: F401  (this process has numpy: one_blas_thread must leave it alone)

from optcal.cli.main import BLAS_THREAD_VARIABLES, one_blas_thread


def test_one_blas_thread_for_allan_in_a_fresh_process_only(monkeypatch):
    before = {k: os.environ.get(k) for k in BLAS_THREAD_VARIABLES}
    assert not one_blas_thread("allan") and {k: os.environ.get(k) for k in BLAS_THREAD_VARIABLES} == before
    # as in a fresh process (numpy not imported yet; monkeypatch puts numpy and the variables back)
    monkeypatch.delitem(sys.modules, "numpy")
    for name in BLAS_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    assert not one_blas_thread("calibrate") and not any(os.environ.get(k) for k in BLAS_THREAD_VARIABLES)
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")  # the user's setting wins
    assert one_blas_thread("allan") and os.environ["OPENBLAS_NUM_THREADS"] == "2" and os.environ["MKL_NUM_THREADS"] == "1"
    # and in a real fresh process BLAS then starts no thread of its own
    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    probe = ("import os; from optcal.cli.main import one_blas_thread; done = one_blas_thread('allan'); import numpy; "
             "numpy.ones((300, 300)) @ numpy.ones((300, 300)); "
             "print(done, os.environ['OPENBLAS_NUM_THREADS'], len(os.listdir('/proc/self/task')) if "
             "os.path.isdir('/proc/self/task') else 1)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, env=env).stdout
    assert out.split() == ["True", "1", "1"]
