"""A command or reader whose extra is not installed says so in one line, with the pip install that fixes it (issue 40).

Each case runs optcal in a fresh interpreter with the extra's module blocked (``sys.modules[name] = None``:
``import name`` then raises ModuleNotFoundError, as in a virtual environment without it).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from optcal.core.model import lu2017_reference_model
from optcal.families.simulate.recording import synthesize_recording
from optcal.families.simulate.poses import uniform_directions
from optcal.data.writers import write_recording

ROOT = Path(__file__).resolve().parents[2]


def optcal_without(modules: list[str], *argv: str) -> subprocess.CompletedProcess:
    """``optcal ARGV`` in a new interpreter in which ``modules`` cannot be imported."""
    code = ("import sys\n"
            f"for name in {modules!r}:\n    sys.modules[name] = None\n"
            "from optcal.cli.main import main\n"
            f"sys.exit(main({list(argv)!r}))\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "HOME": str(ROOT)})


@pytest.fixture(scope="module")
def recording_frame():
    model = lu2017_reference_model()
    return synthesize_recording(model, uniform_directions(8, rng=3), dwell_s=2.0, transition_s=1.0, sigma=0.002,
                                gyro_units="rad/s", rng=4, t0=1000.0).frame


CASES = {
    "parquet": (["pyarrow"], "parquet", "rec.parquet"),
    "ros": (["rosbags"], "ros1", "rec.bag"),
    "px4": (["pyulog"], "ulog", "rec.ulg"),
}


@pytest.mark.parametrize("extra", sorted(CASES))
def test_a_reader_without_its_extra_is_one_line(extra, recording_frame, tmp_path):
    modules, fmt, name = CASES[extra]
    path = write_recording(recording_frame, tmp_path / name, fmt)
    done = optcal_without(modules, "segment", str(path))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in done.stderr
    assert f"pip install 'optcal[{extra}]'" in lines[0]


def test_hdf5_reader_without_its_extra_is_one_line(shared_data):
    path = shared_data / "divemove-tag" / "magnt_accel_calib.nc"
    done = optcal_without(["h5py"], "segment", str(path))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "optcal[hdf5]" in lines[0] and "Traceback" not in done.stderr


def test_fleet_without_dask_is_one_line(tmp_path):
    data = tmp_path / "u.csv"
    np.savetxt(data, uniform_directions(12, 1), delimiter=",", header="ax,ay,az", comments="")
    done = optcal_without(["dask", "distributed"], "fleet", str(data), "-o", str(tmp_path / "r.parquet"))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "optcal[fleet]" in lines[0] and "Traceback" not in done.stderr
    assert not (tmp_path / "r.parquet").exists()


def test_apply_to_parquet_without_pyarrow_is_one_line(tmp_path):
    data = tmp_path / "p.csv"
    np.savetxt(data, uniform_directions(12, 1), delimiter=",", header="ax,ay,az", comments="")
    cal = tmp_path / "c.json"
    made = optcal_without([], "calibrate", str(data), "--method", "svd", "-o", str(cal))
    assert made.returncode == 0, made.stderr
    done = optcal_without(["pyarrow"], "apply", str(cal), str(data), "-o", str(tmp_path / "a.parquet"))
    assert done.returncode == 2, done.stderr
    assert "optcal[parquet]" in done.stderr and "Traceback" not in done.stderr
    assert [p.name for p in tmp_path.iterdir()] and not (tmp_path / "a.parquet").exists()
