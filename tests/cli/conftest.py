"""Fixtures of the command-line tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import simulate_poses, tilted_sweeps

from tests.helpers.cli_run import run


@pytest.fixture
def pose_csv(tmp_path: Path, lu_model: LumpedModel) -> Path:
    """A pose table (``ax,ay,az`` in g) of Lu 2017's sensor on ten tilted sweeps, 2 mg noise."""
    poses = simulate_poses(lu_model, tilted_sweeps(10), 0.002, rng=np.random.default_rng(3))
    path = tmp_path / "poses.csv"
    lines = ["ax,ay,az"] + [",".join(f"{v:.10g}" for v in row) for row in poses.acc]
    path.write_text("\n".join(lines) + "\n")
    return path


#: The text ``optcal calibrate`` saved, per pose table: the same table gives the same file, so a test process runs
#: the command once per table (speed only: most command-line tests ask for :func:`cal_json`).
_SAVED_CALIBRATIONS: dict[str, str] = {}


@pytest.fixture
def cal_json(tmp_path: Path, pose_csv: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    """A lumped calibration saved by ``optcal calibrate`` from :func:`pose_csv` (into this test's ``tmp_path``)."""
    path = tmp_path / "cal.json"
    table = pose_csv.read_text()
    if table not in _SAVED_CALIBRATIONS:
        code, _, err = run(["calibrate", pose_csv, "-o", path], capsys)
        assert code == 0, err
        _SAVED_CALIBRATIONS[table] = path.read_text()
    else:
        path.write_text(_SAVED_CALIBRATIONS[table])
    return path
