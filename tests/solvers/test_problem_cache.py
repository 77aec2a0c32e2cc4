"""The problem-cache factory, and calibrations running in several threads at once.

The built problems are shared between threads (one per shape and options); each thread's result
must be exactly what the same calibration gives alone.
"""

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from optcal import calibrate
from optcal.errors import InputError
from optcal.families.accel.mle import ML_PROBLEMS, MLProblem, VectorisedMLProblem
from optcal.solvers.cache import freeze_options, problem_cache
from optcal.families.simulate.poses import simulate_poses, uniform_directions

from helpers.common import rngs


def test_cache_is_bounded_and_drops_the_least_recently_used():
    built = []
    cache = problem_cache(lambda n, options: built.append((n, options)) or object(), maxsize=2)
    a = cache.get(1, ())
    cache.get(2, ())
    assert cache.get(1, ()) is a  # 1 is now the most recently used
    cache.get(3, ())  # evicts 2
    assert len(cache) == 2 and built == [(1, ()), (2, ()), (3, ())]
    assert cache.get(1, ()) is a
    cache.get(2, ())
    assert built[-1] == (2, ())  # rebuilt after eviction


def test_cache_builds_once_when_threads_ask_together():
    calls = []
    gate = threading.Barrier(6)

    def build(key):
        calls.append(key)
        return [key]

    cache = problem_cache(build, maxsize=4)

    def ask(_):
        gate.wait()
        return cache.get("same")

    with ThreadPoolExecutor(6) as pool:
        got = list(pool.map(ask, range(6)))
    assert calls == ["same"] and all(g is got[0] for g in got)


def test_options_are_frozen_order_independently_and_must_be_hashable():
    assert freeze_options({"b": 1, "a": "x"}) == freeze_options({"a": "x", "b": 1}) == (("a", "x"), ("b", 1))
    assert freeze_options(None) == ()
    with pytest.raises(InputError, match="hashable"):
        freeze_options({"a": [1, 2]})


def test_ml_problems_are_shared_per_shape_and_options():
    a = MLProblem.get(37, "squared", {"ipopt.max_iter": 150})
    assert MLProblem.get(37, "squared", {"ipopt.max_iter": 150}) is a
    assert MLProblem.get(37, "huber", {"ipopt.max_iter": 150}) is not a
    assert ML_PROBLEMS.maxsize == 32
    assert isinstance(MLProblem.get(MLProblem.SX_LIMIT + 1), VectorisedMLProblem)
    assert not hasattr(MLProblem.get(MLProblem.SX_LIMIT + 1), "cost")  # holds no data


def _tables(lu_model):
    out = []
    for seed, n in ((1, 40), (2, 40), (3, 40), (4, 25), (5, 260), (6, 260)):
        rd, rn = rngs(seed)
        out.append(simulate_poses(lu_model, uniform_directions(n, rd), 0.003, rng=rn))
    return out


def test_concurrent_calibrations_equal_the_serial_ones(lu_model):
    """Different data, the same shared problems (mle n=40 three times, vectorised n=260 twice,
    convex, exact, gd), four threads at once, each job twice: every result equals the serial one."""
    tables = _tables(lu_model)
    jobs = [(t, "mle") for t in tables] + [(tables[0], "convex"), (tables[1], "convex"), (tables[3], "exact"),
                                          (tables[2], "gd"), (tables[2], "svd")]
    serial = [calibrate(t, method=m) for t, m in jobs]
    with ThreadPoolExecutor(4) as pool:
        parallel = list(pool.map(lambda job: calibrate(job[0], method=job[1]), jobs * 2))
    for k, result in enumerate(parallel):
        expected = serial[k % len(jobs)]
        assert result.method == expected.method
        np.testing.assert_allclose(result.params, expected.params, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(result.covariance, expected.covariance, rtol=1e-10, atol=1e-20)
        assert result.solver.iterations == expected.solver.iterations
