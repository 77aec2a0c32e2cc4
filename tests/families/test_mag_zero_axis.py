"""A magnetometer's axis at 0 counts is a reading, not a rail, and an axis that never changes is refused in one line.

jremington/magcal_2D's sample (a 2-axis compass, ``x,y``) given a third column of zeros, as a 2-axis logger writes it,
was refused as "139 of 139 samples hold an axis at ±0 mgauss, the converter's full scale": an unsigned 16-bit
converter's 0 (``rails.INTEGER_RAILS``) was taken for a rail of a signed field's axis.  Past it, the sphere's normal
equations were singular: a traceback (``numpy.linalg.LinAlgError``), with or without ``--allow-degenerate``.  Now a
level at the zero is no rail of a magnetometer (a converter's full scale lies beyond its zero), and an axis that reads
one value while the others turn is refused naming ``--columns``.  The same rail rule keeps a 3-axis log whose hard iron
puts an axis's minimum at exactly 0 counts: those samples were left out as "at the rail" before."""

from __future__ import annotations

import json

import numpy as np

from helpers.cli_run import run

FIELD_COUNTS = 430.0  # an HMC5883L at ±1.3 Ga (1090 LSB/G) in a 0.4-G field, whole counts


def _turned(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def test_a_two_axis_log_with_a_zero_column_is_refused_without_a_traceback(tmp_path, capsys):
    """A compass turned in its plane, ``mz`` written 0, a 3-D form asked for: one line naming the column and
    ``--columns``, exit 2 (by default the planar form calibrates it: tests/families/test_mag_planar.py)."""
    t = np.linspace(0.0, 4 * np.pi, 400)
    xy = np.c_[-110 + 104 * np.cos(t), 64 + 91 * np.sin(t)]
    path = tmp_path / "mag2d.csv"
    path.write_text("mx,my,mz\n" + "\n".join(f"{x:.0f},{y:.0f},0" for x, y in xy) + "\n")
    for extra in (["--mag-form", "full"], ["--mag-form", "offsets", "--allow-degenerate"]):
        code, out, err = run(["calibrate", str(path), "--sensor", "mag", *extra], capsys)
        assert code == 2, err
        last = err.strip().splitlines()[-1]
        assert last.startswith("error:") and "mz" in last and "--columns" in last and "rail" not in last
        assert "Traceback" not in err


def test_an_axis_whose_minimum_is_zero_counts_is_not_a_rail(tmp_path, capsys):
    """A hard iron of one field along x puts x's minimum at 0 counts, read by several samples: all are kept."""
    # turned through every direction, then slowly about z (a turn through −x, 0.7° a sample)
    t = np.linspace(0.0, 2 * np.pi, 500, endpoint=False)
    u = np.r_[_turned(3000, seed=11), np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]]
    # the hard iron along x a field and 0.4 count: the samples within 3.7° of −x round to 0, none below it
    m = np.rint(np.array([FIELD_COUNTS + 0.4, -60.0, 25.0]) + FIELD_COUNTS * u)
    assert m[:, 0].min() == 0.0 and np.count_nonzero(m[:, 0] == 0.0) >= 2
    path = tmp_path / "hmc.csv"
    path.write_text("mx,my,mz\n" + "\n".join(f"{x:.0f},{y:.0f},{z:.0f}" for x, y, z in m) + "\n")
    code, out, err = run(["calibrate", str(path), "--sensor", "mag", "--mag-units", "counts", "--json"], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert "rail" not in err
    assert cal["n_samples"] == m.shape[0]
    assert abs(cal["field_strength"] - FIELD_COUNTS) < 0.01 * FIELD_COUNTS


def test_a_two_column_compass_log_is_read_as_two_axes(tmp_path, capsys):
    """jremington/magcal_2D's layout (``x,y``, and its copy without a header): read as a 2-axis compass's log, ``mz``
    0, and calibrated by the planar form (before stranger16: "no magnetometer columns … map them with --columns", and
    "2 unnamed columns fit no common layout", whose example ``--columns mx=1,my=2,mz=3`` names a third column the file
    does not have; until the second sweep, refused as having "no 2-D form yet")."""
    t = np.linspace(0.0, 4 * np.pi, 140)
    rows = [f"{-110 + 104 * np.cos(a):.0f},{64 + 91 * np.sin(a):.0f}" for a in t]
    for name, head in (("mag2d_raw_header.csv", "x,y\n"), ("mag2d_raw_noheader.csv", "")):
        path = tmp_path / name
        path.write_text(head + "\r\n".join(rows) + "\r\n")
        code, out, err = run(["calibrate", str(path), "--sensor", "mag", "--json"], capsys)
        assert code == 0, err
        assert "2-axis compass" in err and "Traceback" not in err
        cal = json.loads(out)
        assert cal["form"] == "planar"
        assert abs(cal["field_strength"] - np.sqrt(104 * 91)) < 0.02 * 97.3  # jremington's ellipse: 97.46
