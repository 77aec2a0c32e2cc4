"""A magnetometer row of exactly 0, 0, 0 is a logger's placeholder (the sensor had not answered), not a field: counted
and excluded, as the accelerometer's readers count theirs; a file of nothing else is refused.  Maskul93's MIMU
tutorial (``mag_sphere.mat``, 239 such rows of 72,000) read 2.11 % with them, 1.63 % without."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from optcal.cli.main import main
from optcal.families.mag.samples import ZERO_ROWS


def sphere_csv(path: Path, zeros: int, every: bool = False) -> Path:
    rng = np.random.default_rng(0)
    u = rng.normal(size=(2000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    m = 48.0 * u * [1.03, 0.98, 1.0] + [12.0, -7.0, 3.0] + rng.normal(0, 0.2, u.shape)
    m[:zeros] = 0.0
    if every:
        m[:] = 0.0
    np.savetxt(path, np.column_stack([np.arange(2000) / 50.0, m]), delimiter=",", header="t,mx,my,mz", comments="",
               fmt="%.5f")
    return path


def test_zero_rows_are_excluded_and_counted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", str(sphere_csv(tmp_path / "m.csv", 40)), "--sensor", "mag", "--mag-units", "uT",
                 "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["n_samples"] == 1960 and result["exclusions"][ZERO_ROWS] == 40
    assert result["rms_norm_residual"] < 0.01  # 40 zero rows kept would read 20 % of the field each


def test_a_file_of_zero_rows_is_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", str(sphere_csv(tmp_path / "z.csv", 0, every=True)), "--sensor", "mag"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "every magnetometer row reads 0, 0, 0" in err[-1] and "--columns" in err[-1]
