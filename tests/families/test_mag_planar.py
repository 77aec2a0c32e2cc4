"""The planar (heading) magnetometer calibration: a turn in one plane calibrated, not refused.

Seven of twelve public magnetometer recordings (a compass turned flat, a robot turning on the floor, a phone turned
about one axis) turn in one plane; ``calibrate --sensor mag`` refused them all.  Generated here in those layouts:
a board mounted 2° off the turn's plane with hard and soft iron (recovered within its stated error, and a better
heading than the circle's), jremington/magcal_2D's ``x,y`` with a zero ``z`` (its published Halír–Flusser ellipse as
the truth), a phone turned about its y axis; the JSON that ``apply``, ``check`` and the exporters read.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli_run import run
from optcal.families.mag.planar import fit_planar


def _rot(axis: int, a: np.ndarray) -> np.ndarray:
    """Rotations by angles ``a`` (n,) about sensor ``axis``, shape (n, 3, 3)."""
    c, s = np.cos(a), np.sin(a)
    i, j = [k for k in range(3) if k != axis]
    R = np.zeros((len(a), 3, 3))
    R[:, axis, axis] = 1.0
    R[:, i, i], R[:, i, j], R[:, j, i], R[:, j, j] = c, s, -s, c
    return R


def _turned_board(n: int = 1500, seed: int = 0, axis: int = 2, tilt_deg: float = 2.0):
    """A board turned twice about its ``axis``, mounted ``tilt_deg`` off the turn's plane: the Earth's 48 µT at 60°
    dip, a soft iron with cross-coupling, a hard iron, 0.5 % white noise.  Returns m, the heading (rad), and the
    ellipse's true centre in 3-D: the hard iron plus the soft iron's image of the turn's mean field (the vertical field,
    constant through the turn, which no turn in the plane tells from a hard iron; both move the heading alike)."""
    rng = np.random.default_rng(seed)
    yaw = np.linspace(0.0, 4 * np.pi, n) + rng.normal(scale=0.005, size=n)
    b = 48.0 * np.array([np.cos(np.radians(60.0)), 0.0, -np.sin(np.radians(60.0))])
    b = np.roll(b, axis - 2)  # the field's vertical along the turn's axis
    mount = _rot((axis + 1) % 3, np.array([np.radians(tilt_deg)]))[0]
    field = np.einsum("ij,njk,k->ni", mount, _rot(axis, yaw), b)
    S = np.array([[1.09, 0.04, 0.02], [0.04, 0.93, -0.03], [0.02, -0.03, 1.01]])
    o = np.array([12.0, -31.0, 44.0])
    centre = o + S @ np.einsum("ij,j->i", mount, b * (np.arange(3) == axis))
    return field @ S.T + o + rng.normal(scale=0.24, size=(n, 3)), yaw, centre


def _heading_error_deg(m: np.ndarray, fit, yaw: np.ndarray) -> float:
    """rms of the calibrated heading's error after the constant offset (the plane's axes are not the truth's); the
    turn's sense is the data's, so the better of ±heading is taken."""
    v = (m @ fit.basis.T - fit.c) @ fit.T2.T
    h = np.arctan2(v[:, 1], v[:, 0])
    best = np.inf
    for sign in (1.0, -1.0):
        d = np.angle(np.exp(1j * (sign * h - yaw)))
        d = np.angle(np.exp(1j * (d - np.angle(np.mean(np.exp(1j * d))))))
        best = min(best, float(np.degrees(np.sqrt(np.mean(d ** 2)))))
    return best


def test_a_planar_turn_is_recovered_within_its_stated_error():
    """The ellipse's centre within 3 standard errors of the truth's (the hard iron along the normal is undetermined),
    the ellipse kept held out, and a heading error near the noise's (0.24 µT across a 24 µT field in the plane:
    0.57° rms; 1.25 times that allowed) where the circle leaves the soft iron's (3.6°)."""
    m, yaw, centre = _turned_board()
    fit = fit_planar(m)
    assert fit.form == "ellipse", fit.reason
    assert abs(abs(fit.normal[2]) - np.cos(np.radians(2.0))) < 0.01
    se = np.array([fit.stderr["c_0"], fit.stderr["c_1"]])
    assert np.all(np.abs(fit.c - fit.basis @ centre) < 3 * se), (fit.c, fit.basis @ centre, se)
    assert fit.o @ fit.normal == pytest.approx(0.0, abs=1e-9)
    circle = fit_planar(m, "circle")
    e_ellipse, e_circle = _heading_error_deg(m, fit, yaw), _heading_error_deg(m, circle, yaw)
    assert e_ellipse < 1.25 * np.degrees(0.24 / 24.0) and e_circle > 3 * e_ellipse, (e_ellipse, e_circle)
    # the 3-D embedding: invertible, det(T)^(-1/3) the field in the plane, the normal component passed through
    assert np.linalg.det(fit.T) ** (-1 / 3) == pytest.approx(fit.horizontal_field, rel=1e-9)
    out = fit.horizontal_field * (m - fit.o) @ fit.T.T
    assert np.allclose(out @ fit.normal, m @ fit.normal, rtol=1e-9)


def _jremington_xyz0(path) -> tuple[np.ndarray, np.ndarray]:
    """jremington/magcal_2D's layout (``x,y`` whole counts, here as ``mx,my`` with a zero ``mz`` as a 2-axis logger writes it),
    generated from its published Halír–Flusser ellipse: centre (−109.6, 64.5), semi-axes 103.8 and 91.5 (stranger16);
    the axes turned 20°, 139 samples over two turns, the counts' rounding the only noise."""
    t = np.linspace(0.0, 4 * np.pi, 139)
    a, b, phi = 103.8, 91.5, np.radians(20.0)
    R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    xy = np.rint(np.array([-109.6, 64.5]) + np.c_[a * np.cos(t), b * np.sin(t)] @ R.T)
    path.write_text("mx,my,mz\n" + "\n".join(f"{x:.0f},{y:.0f},0" for x, y in xy) + "\n")
    return xy, t


def test_a_two_axis_compass_with_a_zero_z_is_calibrated_applied_and_checked(tmp_path, capsys):
    """``calibrate`` picks the planar form (normal z, the ellipse), the centre within 3 standard errors of the
    generating one and the field in the plane its √(ab); the JSON says what is undetermined; ``apply`` writes the
    in-plane field on the circle and z unchanged; ``check`` reads the in-plane norm."""
    path = tmp_path / "mag2d.csv"
    xy, _ = _jremington_xyz0(path)
    cal_path = tmp_path / "cal.json"
    code, out, err = run(["calibrate", path, "--sensor", "mag", "--json", "-o", cal_path], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert cal["form"] == "planar" and np.allclose(np.abs(cal["plane_normal"]), [0, 0, 1])
    p = cal["planar"]
    assert p["form"] == "ellipse" and p["normal_offset"]["determined"] is False
    se = np.array([cal["stderr"]["c_0"], cal["stderr"]["c_1"]])
    assert np.all(np.abs(np.array(p["c"]) - [-109.6, 64.5]) < 3 * se), (p["c"], se)
    assert p["horizontal_field"] == pytest.approx(np.sqrt(103.8 * 91.5), rel=3 * cal["rms_norm_residual"])
    assert cal["field_strength"] == pytest.approx(p["horizontal_field"])
    assert "one plane" in cal["form_reason"] and "--mag-form planar-circle" in cal["form_reason"]  # evidence, override
    code, out, err = run(["apply", cal_path, path, "-o", tmp_path / "out.csv"], capsys)
    assert code == 0, err
    table = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)
    assert np.allclose(table[:, 2], 0.0)  # z, the normal: passed through (0 here)
    H = cal["field_strength"]
    assert np.sqrt(np.mean((np.hypot(table[:, 0], table[:, 1]) / H - 1) ** 2)) < 0.01
    assert np.allclose(table[:, 3], np.hypot(table[:, 0], table[:, 1]) / H)
    code, out, err = run(["check", cal_path, path, "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["rms_norm_residual"] == pytest.approx(cal["rms_norm_residual"], rel=1e-6)


def test_a_phone_turned_about_its_y_axis_and_the_exporters(tmp_path, capsys):
    """A phone (µT, phyphox's column names) turned about its y axis: planar, normal ±y.  A 3-D form asked for stays
    refused naming --allow-degenerate; ArduPilot refuses the planar file in one line naming --accept-planar (which
    writes it, the tilt's heading error stated); the C header holds T and o exactly."""
    m, _, _ = _turned_board(n=800, seed=4, axis=1, tilt_deg=1.0)
    path = tmp_path / "phone.csv"
    head = '"Time (s)","Magnetic field x (µT)","Magnetic field y (µT)","Magnetic field z (µT)"'
    path.write_text(head + "\n" + "\n".join(f"{0.01 * k:.3f},{x:.4f},{y:.4f},{z:.4f}" for k, (x, y, z) in enumerate(m)),
                    encoding="utf-8")
    cal_path = tmp_path / "cal.json"
    code, out, err = run(["calibrate", path, "--sensor", "mag", "-o", cal_path], capsys)
    assert code == 0, err
    cal = json.loads(cal_path.read_text())
    assert cal["form"] == "planar" and abs(abs(cal["plane_normal"][1]) - 1) < 0.01
    code, out, err = run(["calibrate", path, "--sensor", "mag", "--mag-form", "full"], capsys)
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(errors) == 1 and "--allow-degenerate" in errors[0] and "--mag-form planar" in errors[0]
    code, out, err = run(["export", cal_path, "--format", "ardupilot"], capsys)
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(errors) == 1 and "--accept-planar" in errors[0] and "ε sin θ / H" in errors[0], err
    code, out, err = run(["export", cal_path, "--format", "ardupilot", "--accept-planar"], capsys)
    assert code == 0 and "COMPASS_DIA_X" in out and "undetermined" in out, err
    code, out, err = run(["export", cal_path, "--format", "c"], capsys)
    assert code == 0, err
    T = np.array(json.loads(out.split("OPTCAL_MAG_T[3][3] = ")[1].split(";")[0].replace("{", "[").replace("}", "]")))
    o = np.array(json.loads(out.split("OPTCAL_MAG_O[3] = ")[1].split(";")[0].replace("{", "[").replace("}", "]")))
    assert np.array_equal(T, np.array(cal["T"])) and np.array_equal(o, np.array(cal["o"]))
    assert "OPTCAL_MAG_PLANE_NORMAL" in out


def test_a_planar_band_of_a_real_recording_agrees_with_its_3d_calibration(shared_data):
    """ckexplorer's samples whose field (by the full 3-D calibration of the whole log) lies within 3° of the sensor's
    xy plane, calibrated alone: planar by default, its heading within 1 % of a radian-per-field (0.57°, the relevant
    share the 3-D forms use, fit.RELEVANT_SHARE) of the 3-D calibration's, its field in the plane within 1 % of the
    3-D field (the band keeps at least cos 3° of it); a hard iron planted in the real samples moves the centre by its
    part in the plane, within 3 standard errors."""
    from optcal.families.mag.calibration import calibrate_mag
    from optcal.families.mag.fit import RELEVANT_SHARE
    from optcal.families.mag.samples import read_mag

    samples = read_mag(shared_data / "ckexplorer-holds" / "acc_mag_log.csv")
    full = calibrate_mag(samples).calibration
    u = full.correct(samples.m)
    samples.m = samples.m[np.abs(u[:, 2] / np.linalg.norm(u, axis=1)) < 0.05]
    samples.acc = None
    result = calibrate_mag(samples)
    assert result.calibration.info["form"] == "planar" and result.planar is not None
    pf = result.planar
    assert pf.horizontal_field == pytest.approx(full.field_strength, rel=RELEVANT_SHARE)
    v = (samples.m @ pf.basis.T - pf.c) @ pf.T2.T
    u3 = full.correct(samples.m)
    d = np.angle(np.exp(1j * (np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(u3[:, 1], u3[:, 0]))))
    d = np.angle(np.exp(1j * (d - np.angle(np.mean(np.exp(1j * d))))))
    assert np.sqrt(np.mean(d ** 2)) < RELEVANT_SHARE, np.degrees(np.sqrt(np.mean(d ** 2)))
    planted = np.array([0.05, -0.03, 0.2])  # gauss: a fifth of the field in the plane, two thirds of it along the normal
    moved = fit_planar(samples.m + planted)
    se = np.array([moved.stderr["c_0"], moved.stderr["c_1"]])
    assert np.all(np.abs(moved.c - pf.c - pf.basis @ planted) < 3 * se), (moved.c - pf.c, pf.basis @ planted, se)
