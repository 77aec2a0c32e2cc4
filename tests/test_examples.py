"""The scripts of ``examples/`` run as a user runs them: each in its own interpreter, from the repository's root.

Without arguments each example simulates its data (it must run without ../shared); the test checks
exit code 0 and the line that says the example did its job, with the figure that shows it was done
right where the simulation knows the truth.  Each is short (< 60 lines) and says how to run it.
One example also runs on a shared recording, when ../shared is present.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

#: example -> a pattern its output must hold when run with no argument (its simulated data), and the
#: largest value allowed of the pattern's group "x" where the simulation knows the truth.
KEY_OUTPUT: dict[str, tuple[str, float | None]] = {
    "calibrate_raw_log.py": (r"poses: 40\n(.|\n)*saved and read back: calibration\.json", None),
    # gravity carried across each move within 0.1° once the gyro is calibrated (2.5° with its bias alone)
    "calibrate_imu.py": (r"poses: 30; gyro units: deg/s(.|\n)*, (?P<x>[0-9.]+) deg calibrated", 0.1),
    "diagnose.py": (r"named: temperature_bias\(z\);", None),
    "export_firmware.py": (r"CAL_ACC0_XSCALE\t(.|\n)*INS_ACCSCAL_X,", None),
    # the planted 0.33-gauss hard iron within 1 mgauss (the noise is 2 mgauss per sample, 3,000 samples)
    "calibrate_magnetometer.py": (r"offset error against the planted one: (?P<x>[0-9.]+) mgauss", 1.0),
}


def run_example(name: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)


def test_every_example_is_listed_short_and_says_how_to_run_it() -> None:
    scripts = sorted(p.name for p in EXAMPLES.glob("*.py"))
    assert scripts == sorted(KEY_OUTPUT)
    for name in scripts:
        text = (EXAMPLES / name).read_text(encoding="utf-8")
        assert len(text.splitlines()) < 60, name
        doc = ast.get_docstring(ast.parse(text)) or ""
        assert f"python examples/{name}" in doc and "Run::" in doc, name


@pytest.mark.parametrize("name", sorted(KEY_OUTPUT))
def test_example_runs_on_its_simulated_data(name: str) -> None:
    done = run_example(name)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    pattern, largest = KEY_OUTPUT[name]
    found = re.search(pattern, done.stdout)
    assert found is not None, done.stdout[-2000:]
    if largest is not None:
        assert float(found.group("x")) < largest, found.group(0)


def test_the_raw_log_example_on_the_xsens_recording(shared_data: Path) -> None:
    done = run_example("calibrate_raw_log.py", str(shared_data / "imutk-xsens" / "xsens_imutk.csv"))
    assert done.returncode == 0, done.stderr[-2000:]
    assert "poses: 38" in done.stdout and "units: counts" in done.stdout, done.stdout


def test_the_export_example_refuses_counts_without_a_sensitivity_in_one_line(shared_data: Path) -> None:
    done = run_example("export_firmware.py", str(shared_data / "imutk-xsens" / "xsens_imutk.csv"))
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert done.stderr.strip().startswith("error: ") and "counts_per_g" in done.stderr
