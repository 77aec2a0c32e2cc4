"""What the reader says it excluded from a pose table is excluded everywhere and counted in the JSON (issue 40)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import optcal
from optcal.families.simulate.poses import simulate_poses, uniform_directions
from tests.helpers.cli_run import run


@pytest.fixture
def zero_rows_csv(tmp_path):
    """30 poses of Lu 2017's sensor (1 mg noise) and two all-zero rows (an unfilled logger buffer) among them."""
    poses = simulate_poses(optcal.lu2017_reference_model(), uniform_directions(30, 4), 0.001, rng=5)
    acc = np.insert(poses.acc, [7, 20], 0.0, axis=0)
    path = tmp_path / "poses.csv"
    np.savetxt(path, acc, delimiter=",", header="ax,ay,az", comments="", fmt="%.10g")
    clean = tmp_path / "clean.csv"
    np.savetxt(clean, poses.acc, delimiter=",", header="ax,ay,az", comments="", fmt="%.10g")
    return path, clean


def test_zero_rows_left_out_of_the_fit_and_counted(zero_rows_csv, capsys):
    path, clean = zero_rows_csv
    code, out, err = run(["calibrate", path, "--json"], capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["data"]["n_poses"] == 30
    assert sum(summary["data"]["exclusions"].values()) == 2 and "all-zero" in next(iter(summary["data"]["exclusions"]))
    code, out, err = run(["calibrate", clean, "--json"], capsys)
    assert json.loads(out)["data"]["n_poses"] == 30
    reading = optcal.load(path)
    assert reading.poses.n == 30 and reading.exclusions == summary["data"]["exclusions"]
    assert reading.poses.rows.tolist()[6:9] == [7, 9, 10]  # the file's row numbers kept for the survivors
    fit, fit_clean = optcal.calibrate(reading), optcal.calibrate(clean)
    assert np.allclose(fit.calibration.theta, fit_clean.calibration.theta, atol=1e-9)


def test_apply_marks_the_excluded_rows(zero_rows_csv, tmp_path, capsys):
    path, clean = zero_rows_csv
    optcal.calibrate(clean).save(tmp_path / "c.json")
    code, out, err = run(["apply", tmp_path / "c.json", path, "-o", tmp_path / "a.csv"], capsys)
    assert code == 0, err
    assert "excluded 2" in out.replace(",", "")
    import pandas as pd

    status = pd.read_csv(tmp_path / "a.csv")["optcal_status"]
    assert status.tolist().count("excluded") == 2 and status.iloc[7] == "excluded"
