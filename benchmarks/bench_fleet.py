"""Fleet benchmarks (issue 17): a few hundred units on a local Dask cluster, batched throughput.

Run on demand: ``pytest benchmarks/bench_fleet.py`` (``OPTCAL_BENCH_QUICK=1`` for smaller sizes,
``OPTCAL_BENCH_STRICT=1`` to assert the issue's targets).

* ``test_fleet_few_hundred_units`` — ``optcal fleet`` on 300 synthetic units with planted trouble
  (2 unreadable files, an 8 % scale error, a six-face unit) on a 2-worker LocalCluster, wall time
  *including the cluster start* and the prior refit.  Target ≤ 60 s on 2 cores.
* ``test_batched_throughput`` — complete default ``mle`` fits per second of 120-pose problems
  (Lu 2017 Table 1 design), batched (:mod:`optcal.estimators.batched`) against one at a time
  measured in the same run, per second of wall time and of CPU time.  Target ≥ 2,000 batched fits/s
  on one core (asserted on the wall-time rate in strict mode: run it on an idle machine).
"""

from __future__ import annotations

import os
import time

from optcal.fleet.engine import ClusterSettings, FleetClient, run_fleet
from optcal.fleet.inputs import expand_inputs
from optcal.fleet.synthetic import write_fleet
from optcal.reproduce.solvers import table1_design, throughput

QUICK = os.environ.get("OPTCAL_BENCH_QUICK") == "1"
STRICT = os.environ.get("OPTCAL_BENCH_STRICT") == "1"


def _fleet_run(folder: str) -> dict:
    t0 = time.perf_counter()
    with FleetClient(ClusterSettings(workers=2)) as fc:
        started = time.perf_counter() - t0
        result = run_fleet(expand_inputs([folder]), fc.client, engine=fc.engine)
    return {"result": result, "cluster_start_s": started, "total_s": time.perf_counter() - t0}


def test_fleet_few_hundred_units(benchmark, tmp_path):
    n = 100 if QUICK else 300
    truth = write_fleet(tmp_path / "units", n, seed=17)
    out = benchmark.pedantic(_fleet_run, args=(str(tmp_path / "units"),), rounds=1, iterations=1)
    res = out["result"]
    benchmark.extra_info.update({"units": n, "total_s": out["total_s"], "cluster_start_s": out["cluster_start_s"],
                                 "units_per_s": n / out["total_s"]})
    print(f"\n{n} units in {out['total_s']:.1f} s (cluster start {out['cluster_start_s']:.1f} s), {res.engine}")
    assert res.count("failed") == len(truth.units("unreadable"))
    assert res.count("calibrated_with_prior") == len(truth.units("six_faces"))
    if STRICT:
        assert out["total_s"] <= 60.0


def test_batched_throughput(benchmark):
    fits = 100 if QUICK else 300
    res = benchmark.pedantic(throughput, args=(table1_design(), fits, 0, False), kwargs={"batched_fits": 10 * fits},
                             rounds=1, iterations=1)
    b = res["batched"]
    benchmark.extra_info.update({"batched_fits_per_s": b["fits_per_s"], "single_fits_per_s": res["fits_per_s"],
                                 "batched_fits_per_cpu_s": b["fits_per_cpu_s"], "single_fits_per_cpu_s": res["fits_per_cpu_s"],
                                 "speedup": b["fits_per_s"] / res["fits_per_s"],
                                 "max_deviation_from_single_in_stderr": b["max_deviation_from_single_in_stderr"]})
    print(f"\nbatched {b['fits_per_s']:.0f} fits/s ({b['fits_per_cpu_s']:.0f} per CPU second), one at a time "
          f"{res['fits_per_s']:.0f} fits/s ({res['fits_per_cpu_s']:.0f} per CPU second) "
          f"(×{b['fits_per_s'] / res['fits_per_s']:.1f}); largest difference {b['max_deviation_from_single_in_stderr']:.1e} SE")
    assert b["max_deviation_from_single_in_stderr"] < 1e-5
    if STRICT:
        assert b["fits_per_s"] >= 2000
