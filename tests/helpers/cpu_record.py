"""The CPU-time record of a test run (``OPTCAL_TEST_CPU_DIR``, tests/conftest.py), summed per file and per test.

    OPTCAL_TEST_CPU_DIR=/tmp/cpu pytest -q -n 2
    python tests/helpers/cpu_record.py /tmp/cpu [--tests 20] [--files 30]

Prints the run's CPU seconds (the wall time ``-n 2`` needs on an idle 2-core machine is about half of it), the
costliest files and the costliest tests (each with its CPU and wall seconds).
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path


def read_record(folder: Path) -> list[tuple[str, float, float]]:
    """(node id, CPU s, wall s) of every test recorded in ``folder``'s ``*.jsonl``."""
    rows = []
    for path in sorted(folder.glob("*.jsonl")):
        for line in path.read_text(encoding="utf-8").splitlines():
            node, cpu, wall, _ = json.loads(line)
            rows.append((node, float(cpu), float(wall)))
    return rows


def by_file(rows: list[tuple[str, float, float]]) -> list[tuple[str, float, float, int]]:
    """(file, CPU s, wall s, tests) per test file, costliest first."""
    sums: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0.0])
    for node, cpu, wall in rows:
        s = sums[node.split("::")[0]]
        s[0] += cpu
        s[1] += wall
        s[2] += 1
    return sorted(((f, s[0], s[1], int(s[2])) for f, s in sums.items()), key=lambda r: -r[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--files", type=int, default=30)
    parser.add_argument("--tests", type=int, default=20)
    args = parser.parse_args()
    rows = read_record(args.folder)
    print(f"{len(rows)} tests, {sum(r[1] for r in rows):.0f} CPU s, {sum(r[2] for r in rows):.0f} wall s")
    print("\n   CPU s   wall s  tests  file")
    for f, cpu, wall, n in by_file(rows)[:args.files]:
        print(f"{cpu:8.1f} {wall:8.1f} {n:6d}  {f}")
    print("\n   CPU s   wall s  test")
    for node, cpu, wall in sorted(rows, key=lambda r: -r[1])[:args.tests]:
        print(f"{cpu:8.1f} {wall:8.1f}  {node}")


if __name__ == "__main__":
    main()
