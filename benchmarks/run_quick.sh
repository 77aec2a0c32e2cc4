#!/usr/bin/env bash
# Solver benchmarks in quick mode (what CI runs): smaller Monte Carlo, 10⁵ instead of 10⁶ poses,
# targets reported but not asserted.  Full run: pytest benchmarks/bench_solvers.py
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python}"
# single-threaded BLAS: on a shared machine OpenBLAS threads contend with other jobs (README)
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
OPTCAL_BENCH_QUICK=1 "$PYTHON" -m pytest benchmarks/bench_solvers.py -q -p no:cacheprovider \
    --benchmark-min-rounds=5 --benchmark-max-time=0.5 --benchmark-columns=min,median,max,rounds "$@"
# issue 40: optcal allan end to end against pandas' parse of the same file, a 20-minute log (about 10 s)
OPTCAL_BENCH_QUICK=1 "$PYTHON" -m pytest benchmarks/bench_allan.py -k pandas -q -s -p no:cacheprovider
