"""Runtime targets of the Sun 2011 reproduction (run on demand: ``pytest benchmarks/bench_sun2011.py``).

* ``optcal reproduce sun2011`` with its defaults (1000 Monte Carlo runs, 100 static-ML fits): ≤ 60 s.
* The ten-position scheme (10 positions × 60 s of alignment filtering) for one Monte Carlo run:
  well under a second.
"""

from __future__ import annotations

from optcal.applications.papers.sun2011.alignment import FilterTuning
from optcal.applications.papers.sun2011.reproduce import DEFAULT_RUNS, run
from optcal.applications.papers.sun2011.tenposition import run_scheme
from optcal.applications.papers.sun2011.turntable import SimulationSettings, TurntableRun


def test_reproduction_default_run_within_60_s(benchmark) -> None:
    res = benchmark.pedantic(run, kwargs={"runs": DEFAULT_RUNS, "seed": 0}, rounds=1, iterations=1)
    assert res["runs"] == DEFAULT_RUNS
    assert benchmark.stats.stats.max <= 60.0


def test_scheme_for_one_monte_carlo_run_well_under_a_second(benchmark) -> None:
    settings = SimulationSettings()
    tuning = FilterTuning.paper(settings.gravity)

    def one_run() -> None:
        session = TurntableRun.start(settings, 1, seed=0)
        run_scheme(session, tuning)

    benchmark.pedantic(one_run, rounds=20, iterations=1, warmup_rounds=1)
    assert benchmark.stats.stats.median <= 0.25
