"""Fleet benchmarks (issue 17): a few hundred units on a local Dask cluster, batched throughput.

Run on demand: ``pytest benchmarks/bench_fleet.py`` (``OPTCAL_BENCH_QUICK=1`` for smaller sizes,
``OPTCAL_BENCH_STRICT=1`` to assert the issue's targets).

* ``test_fleet_few_hundred_units`` — ``optcal fleet`` on 300 synthetic units with planted trouble
  (2 unreadable files, an 8 % scale error, a six-face unit) on a 2-worker LocalCluster, wall time
  *including the cluster start* and the prior refit.  Target ≤ 60 s on 2 cores.
* ``test_fit_stage_batched_against_single`` — the fleet's fit stage in one process (no Dask) on
  the same read tables: ``fit_units`` (a task's units in batched IPOPT problems) against
  ``fit_unit`` one at a time (the baseline, measured in the same run), CPU ms per unit.
* ``test_batched_throughput`` — complete default ``mle`` fits per second of 120-pose problems
  (Lu 2017 Table 1 design), batched (:mod:`optcal.families.accel.batched`) against one at a time
  measured in the same run, per second of wall time and of CPU time.  Target ≥ 2,000 batched fits/s
  on one core (asserted on the wall-time rate in strict mode: run it on an idle machine).
"""

from __future__ import annotations

import os
import time

from optcal.applications.fleet.engine import ClusterSettings, FleetClient, run_fleet
from optcal.applications.fleet.inputs import expand_inputs
from optcal.applications.fleet.synthetic import write_fleet
from optcal.applications.papers.solver_study import table1_design, throughput

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


def test_fit_stage_batched_against_single(benchmark, tmp_path):
    import numpy as np

    from optcal.core.identifiability import parameter_full_scale
    from optcal.applications.fleet.unit import fit_unit, fit_units, read_unit

    n = 128 if QUICK else 512
    write_fleet(tmp_path / "units", n, seed=18, scale_error_units=1, six_face_units=1, unreadable_units=1)
    units = expand_inputs([str(tmp_path / "units")])
    data = [read_unit(u, {}) for u in units]
    fit_units(units[:8], data[:8])  # builds the problems
    [fit_unit(u, d) for u, d in zip(units[:2], data[:2])]

    def stage() -> dict:
        c0 = time.process_time()
        single = [fit_unit(u, d) for u, d in zip(units, data)]
        c1 = time.process_time()
        together = fit_units(units, data)
        c2 = time.process_time()
        return {"single_ms": (c1 - c0) / n * 1e3, "batched_ms": (c2 - c1) / n * 1e3, "single": single, "together": together}

    out = benchmark.pedantic(stage, rounds=1, iterations=1)
    worst = max(float(np.max(np.abs(b.theta - s.theta) / parameter_full_scale(s.theta)))
                for b, s in zip(out["together"], out["single"]) if s.theta is not None)
    benchmark.extra_info.update({"units": n, "single_cpu_ms_per_unit": out["single_ms"],
                                 "batched_cpu_ms_per_unit": out["batched_ms"], "max_deviation_full_scale": worst})
    print(f"\nfit stage, {n} units: one at a time {out['single_ms']:.2f} CPU ms/unit, batched {out['batched_ms']:.2f} "
          f"(×{out['single_ms'] / out['batched_ms']:.1f}); largest difference {worst:.1e} of full scale")
    assert [b.status for b in out["together"]] == [s.status for s in out["single"]]
    assert worst < 5e-10


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
    assert b["max_deviation_from_single_in_stderr"] < 1e-6
    assert b["max_deviation_from_single_full_scale"] < 5e-10
    if STRICT:
        assert b["fits_per_s"] >= 2000
