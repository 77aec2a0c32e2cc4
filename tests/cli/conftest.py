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


@pytest.fixture
def cal_json(tmp_path: Path, pose_csv: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    """A lumped calibration saved by ``optcal calibrate`` from :func:`pose_csv`."""
    path = tmp_path / "cal.json"
    code, _, err = run(["calibrate", pose_csv, "-o", path], capsys)
    assert code == 0, err
    return path
