"""Start-up and whole-process time of this checkout against a baseline commit, in the same run.

Issue 25 (the layered package) must not make ``optcal --help`` or ``optcal calibrate`` on the
Xsens log slower.  Both are whole processes, so this benchmark runs them as processes: the
baseline commit is checked out into a temporary ``git worktree`` and imported through
``PYTHONPATH`` with the same interpreter, and the two trees are timed alternately (ABAB...) so
that a change in the machine's load touches both equally.

Run::

    python benchmarks/bench_layout.py                       # baseline: the commit before the layering
    python benchmarks/bench_layout.py --baseline HEAD~5 --repeats 15
    OPTCAL_BENCH_STRICT=1 python benchmarks/bench_layout.py # exit 1 when this tree is slower

"Slower" is judged on the median of the per-pair ratios (this / baseline) against
``1 + --slack`` (default 0.05: a 5 % allowance, below the run-to-run spread of a 2-core machine
that other jobs share); the ratios' 10th-90th percentile range is printed with it.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
XSENS = REPO.parent / "shared" / "data" / "imutk-xsens" / "xsens_imutk.csv"
#: The last commit before the modules moved into layers (issue 25).
DEFAULT_BASELINE = "f6b5faa"
CLI = "import sys; from optcal.cli.main import main; sys.exit(main())"


def timed(tree: Path, args: list[str]) -> float:
    """Wall time of one ``optcal ARGS`` process importing optcal from ``tree``, seconds."""
    env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # as installed, with byte-code: the warm-up run writes it for both trees
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CLI, *args], env=env, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"optcal {' '.join(args)} failed in {tree} (exit {done.returncode}): {done.stderr.strip()[-300:]}")
    return elapsed


def compare(name: str, args: list[str], this: Path, baseline: Path, repeats: int, slack: float) -> bool:
    """Time ``args`` alternately in both trees; print medians and the ratio; True when not slower."""
    timed(this, args), timed(baseline, args)  # warm the file cache and the byte-code of both trees
    ours, theirs = [], []
    for _ in range(repeats):
        ours.append(timed(this, args))
        theirs.append(timed(baseline, args))
    ratios = sorted(a / b for a, b in zip(ours, theirs))
    ratio = statistics.median(ratios)
    low, high = ratios[len(ratios) // 10], ratios[-1 - len(ratios) // 10]
    ok = ratio <= 1 + slack
    print(f"{name:<28s} this {statistics.median(ours) * 1e3:8.1f} ms   baseline {statistics.median(theirs) * 1e3:8.1f} ms   "
          f"ratio {ratio:.3f} ({low:.3f}-{high:.3f}, {repeats} pairs)   {'ok' if ok else 'SLOWER'}")
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default=DEFAULT_BASELINE, help="git ref of the baseline tree")
    parser.add_argument("--repeats", type=int, default=9, help="pairs of runs per command")
    parser.add_argument("--slack", type=float, default=0.05, help="allowed median slowdown, as a fraction")
    options = parser.parse_args()
    workdir = Path(tempfile.mkdtemp(prefix="optcal-baseline-"))
    baseline = workdir / "tree"
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-f", str(baseline), options.baseline],
                   check=True, capture_output=True)
    try:
        print(f"baseline {options.baseline} in {baseline}; this tree {REPO}")
        ok = compare("optcal --help", ["--help"], REPO, baseline, options.repeats, options.slack)
        if XSENS.is_file():
            ok &= compare("optcal calibrate (Xsens)", ["calibrate", str(XSENS), "--json"], REPO, baseline,
                          options.repeats, options.slack)
        else:
            print(f"skipped the Xsens calibration: {XSENS} not found")
    finally:
        subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(baseline)], capture_output=True)
        shutil.rmtree(workdir, ignore_errors=True)
    return 0 if ok or not os.environ.get("OPTCAL_BENCH_STRICT") else 1


if __name__ == "__main__":
    sys.exit(main())
