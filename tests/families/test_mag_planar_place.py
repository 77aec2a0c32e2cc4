"""A planar calibration's unit, its vertical-field heading error and its ``check`` on another plane.

A turn in one plane shows the field in that plane (``H``), a lower bound on the total: its unit is decided from the
planar fit's ``H``, not from the median ``|m|`` (which holds the hard iron, and misses the normal component on a
2-axis log).  A tilt of the plane brings the vertical field in, ``tan(dip)`` degrees of heading per degree, stated for
the place's dip with ``--location``.  ``check`` of a planar calibration on a recording turned in another plane says
so instead of a bare residual.  All on generated files (a level turn of a 2-axis compass; a board turned about two
different axes).
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from helpers.cli_run import run


def _two_axis_turn(path, H: float, centre: tuple[float, float], n: int = 400, seed: int = 0) -> None:
    """A level 2-axis compass (``mx,my`` and a zero ``mz``) turned twice: an ellipse of ``H`` (axes ×1.06 and ×0.95
    turned 25°) about ``centre``, 0.5 % noise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 4 * np.pi, n)
    phi = np.radians(25.0)
    R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    xy = np.array(centre) + np.c_[1.06 * H * np.cos(t), 0.95 * H * np.sin(t)] @ R.T + rng.normal(scale=0.005 * H, size=(n, 2))
    path.write_text("mx,my,mz\n" + "\n".join(f"{x:.3f},{y:.3f},0" for x, y in xy) + "\n")


@pytest.mark.parametrize("H, centre, units", [
    (20.0, (-140.0, 60.0), "uT"),  # a board's magnet 7.6 H: |m| ≈ 150, mgauss's 13-124 µT; H is 20 µT only in µT
    (110.0, (-9.0, 6.0), "mgauss"),  # a dip of 78° (H 11 µT), 2-axis: |m| ≈ 110 reads µT; H is 11 µT only in mgauss
])
def test_a_planar_turns_unit_is_decided_from_its_field_in_the_plane(tmp_path, capsys, H, centre, units):
    """The unit is the one in which the planar fit's H is 5-65 µT, said with --mag-units; apply and check read the
    same recording in it."""
    path = tmp_path / "turn.csv"
    _two_axis_turn(path, H, centre)
    cal_path = tmp_path / "cal.json"
    code, out, err = run(["calibrate", path, "--sensor", "mag", "--json", "-o", cal_path], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert cal["form"] == "planar" and cal["units"]["input"] == units, (cal["units"], err)
    line = [s for s in err.splitlines() if s.startswith("magnetometer units, after the planar fit:") and "field in the plane" in s]
    assert line and "--mag-units" in line[-1] and "5-65 µT" in line[-1], err
    assert cal["field_strength"] == pytest.approx(H, rel=0.05)
    code, _, err = run(["apply", cal_path, path, "-o", tmp_path / "out.csv"], capsys)
    assert code == 0, err
    code, out, err = run(["calibrate", path, "--sensor", "mag", "--json", "--mag-units", "nT"], capsys)
    assert code == 0 and json.loads(out)["units"]["input"] == "nT", err  # the override


def _board(axis: int, n: int = 600, seed: int = 1) -> np.ndarray:
    """A board (48 µT at 60° dip, a hard iron, 0.5 % noise) turned twice about its sensor ``axis``."""
    rng = np.random.default_rng(seed)
    yaw = np.linspace(0.0, 4 * np.pi, n)
    b = np.roll(48.0 * np.array([np.cos(np.radians(60.0)), 0.0, -np.sin(np.radians(60.0))]), axis - 2)
    c, s = np.cos(yaw), np.sin(yaw)
    i, j = [k for k in range(3) if k != axis]
    f = np.repeat(b[None, :], n, axis=0)
    f[:, i], f[:, j] = c * b[i] + s * b[j], -s * b[i] + c * b[j]
    return f + np.array([12.0, -31.0, 44.0]) + rng.normal(scale=0.24, size=(n, 3))


def _write(path, m: np.ndarray) -> None:
    path.write_text("mx_ut,my_ut,mz_ut\n" + "\n".join(f"{x:.4f},{y:.4f},{z:.4f}" for x, y, z in m) + "\n")


def test_check_of_a_planar_calibration_says_whether_data_turns_in_its_plane(tmp_path, capsys):
    """Calibrated turned about z, checked on a turn about z (in its plane) and on one about x (another plane): the
    second is said to leave the plane, with its tilt, in the text and the JSON."""
    about_z, about_x = tmp_path / "z.csv", tmp_path / "x.csv"
    _write(about_z, _board(2))
    _write(about_x, _board(0, seed=2))
    cal_path = tmp_path / "cal.json"
    code, _, err = run(["calibrate", about_z, "--sensor", "mag", "-o", cal_path], capsys)
    assert code == 0, err
    code, out, err = run(["check", cal_path, about_z, "--json"], capsys)
    assert code == 0 and json.loads(out)["plane"]["in_plane"] is True, err
    code, out, err = run(["check", cal_path, about_x, "--json"], capsys)
    plane = json.loads(out)["plane"]
    assert code == 0 and plane["in_plane"] is False and plane["tilt_deg"] > 60, plane
    code, out, err = run(["check", cal_path, about_x], capsys)
    lines = [s for s in out.splitlines() if s.startswith("plane: DATA is not turned in the calibration's plane")]
    assert code == 0 and len(lines) == 1, out


def test_the_vertical_fields_heading_error_is_stated_for_the_dips_and_at_the_place(tmp_path, capsys):
    """Without --location the vertical field's share is stated for a range of dips (tan 60° = 1.7 among them); with
    it, tan of the World Magnetic Model's dip there, in the JSON beside tilt_heading_error."""
    path = tmp_path / "z.csv"
    _write(path, _board(2))
    code, out, err = run(["calibrate", path, "--sensor", "mag", "--json"], capsys)
    assert code == 0, err
    p = json.loads(out)["planar"]
    assert "tilt_heading_error" in p and "1.7 at a dip of 60°" in p["vertical_field_heading_error"]
    pytest.importorskip("pygeomag")
    import datetime as dt

    from optcal.families.mag.wmm import Location, wmm_reference

    ref = wmm_reference(Location.parse("60,25"), dt.date(2026, 3, 1))
    code, out, err = run(["calibrate", path, "--sensor", "mag", "--json", "--location", "60,25", "--date", "2026-03-01"],
                         capsys)
    assert code == 0, err
    text = json.loads(out)["planar"]["vertical_field_heading_error"]
    per = float(re.search(r"([0-9.]+)° per degree at --location", text).group(1))
    assert per == pytest.approx(np.tan(np.radians(ref.inclination_deg)), rel=2e-3), text


def test_the_html_report_of_a_planar_turn_shows_its_heading_sectors(tmp_path, capsys):
    """``--report`` of a turn that misses about 60° of heading: the figure is the headings' (not the sphere's), and
    the verdict names the heading sectors not reached."""
    path = tmp_path / "turn.csv"
    _two_axis_turn(path, 20.0, (-14.0, 6.0))
    rows = path.read_text().splitlines()
    t = np.linspace(0.0, 4 * np.pi, len(rows) - 1)
    path.write_text("\n".join([rows[0]] + [r for r, a in zip(rows[1:], t) if a % (2 * np.pi) < np.radians(300)]) + "\n")
    report = tmp_path / "r.html"
    code, _, err = run(["calibrate", path, "--sensor", "mag", "--report", report], capsys)
    assert code == 0, err
    html = report.read_text()
    assert "headings in the plane of the turn" in html and "directions on the sphere" not in html
    missing = re.search(r"(\d+) heading sector\(s\) not reached: heading", html)
    assert missing and 1 <= int(missing.group(1)) <= 3, re.findall(r"not reached[^<]*", html)
