"""A unit decided from the data is checked against the World Magnetic Model's field at ``--location``.

gregoriomarchesini/Magnetometer-calibration's ``mag_batch.mat`` (Stockholm, 2021-03-18, in its logger's "µT", 0.15-µT
steps) reads a field of 134.8: outside 25-65 µT by more than the factor 1.9 in µT, inside it in mgauss, so it was read
as mgauss (13.5 µT), and with ``--location`` the comparison said −74 %.  Against the WMM's 51.6 µT there, µT (2.6
times it) is the nearer unit (mgauss: 3.8 times below): it is now read in µT, its logger's unit, the line saying why,
and the comparison says +161 % (the peer's own fit finds a scale of about 2).  The control: a field in mgauss at the
place keeps its unit and its reason."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("pygeomag")

from helpers.cli_run import run  # noqa: E402

STOCKHOLM = ["--location", "59.351,18.073", "--date", "2021-03-18"]  # the WMM's field there: 51.6 µT


def _write(path, field: float, hard_iron, step: float, n: int = 2000, seed: int = 8) -> None:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    m = np.asarray(hard_iron) + field * u / np.linalg.norm(u, axis=1, keepdims=True) + rng.normal(scale=0.5, size=(n, 3))
    m = step * np.rint(m / step)
    path.write_text("mx,my,mz\n" + "\n".join(f"{x:.2f},{y:.2f},{z:.2f}" for x, y, z in m) + "\n")


def _units(path, capsys, *extra):
    code, out, err = run(["calibrate", str(path), "--sensor", "mag", "--json", *extra], capsys)
    assert code == 0, err
    return json.loads(out), err


def test_the_unit_nearest_the_field_at_the_place_is_read(tmp_path, capsys):
    path = tmp_path / "mag_batch.csv"
    _write(path, 134.8, (22.0, -28.8, -40.9), 0.15)
    cal, err = _units(path, capsys)
    assert cal["units"]["input"] == "mgauss"  # without the place: the magnitude's one unit, as before
    cal, err = _units(path, capsys, *STOCKHOLM)
    assert cal["units"]["input"] == "uT"
    assert "from the data and the place" in err and "--mag-units" in err
    assert 1.5 < cal["wmm"]["field_difference_relative"] < 1.7


def test_a_field_in_its_unit_at_the_place_keeps_it(tmp_path, capsys):
    path = tmp_path / "hmc.csv"
    _write(path, 505.0, (120.0, -60.0, 300.0), 0.92)  # an HMC5883L at ±1.3 Ga (0.92 mG per count) in Stockholm
    cal, err = _units(path, capsys, *STOCKHOLM)
    assert cal["units"]["input"] == "mgauss"
    assert "from the data and the place" not in err
    assert abs(cal["wmm"]["field_difference_relative"]) < 0.05
