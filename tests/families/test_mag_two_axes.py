"""Logs of two field columns, and a MAT buffer of a time and three axes, read as their loggers wrote them.

Strangers' recordings (the second magnetometer sweep, docs/magnetometer.md):

* sebkm/sensor_fusion's ``experiments/mag/mag_bug_fixed.csv`` (a Pmod NAV's compass turned flat, its ``x, y`` in
  gauss, no header: ``index, time (ms), x, y``) was read as ``t mx my mz`` with the time in ``mx`` and refused as "one
  heading only" (a false reason); a file of two columns was refused as "optcal has no 2-D form yet", which the planar
  form (mag2d) no longer makes true.  A 2-axis compass's log is now read as ``mx, my`` with ``mz = 0`` (its plane's
  normal, unmeasured) and calibrated by the planar form, said in one line with ``--columns`` to change it.
* sunsided/sensor-fusion's ``hmc5883l_compass.mat`` (a variable ``compassBuffer``, 4 × 8190: time, x, y, z) was refused
  as "no magnetometer variable (by its name or units)" although its name says compass, and ``--topic`` could not
  help: only 3-wide variables were read.  A 4-wide variable whose first (or last) column increases is now a time and
  the three axes, as a headerless text file of 4 columns is read.

All on generated files of those shapes (the recordings are not committed: no licence for the first one's data is
needed here, the second's is EUPL; neither is copied)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli_run import run

H_GAUSS = 0.233  # the horizontal field of sebkm's log (a compass turned flat, read in gauss)
CENTRE = (0.0246, 0.0282)  # its hard iron in the plane, gauss
AXES = (1.06, 0.95)  # a soft iron of ±5 % along the plane's axes


def _level_turn(n: int, seed: int) -> np.ndarray:
    """``x, y`` of a compass turned twice about its normal at a slowly varying rate, 0.5-mgauss noise."""
    rng = np.random.default_rng(seed)
    heading = np.cumsum(rng.uniform(0.2, 1.6, n)) * (4 * np.pi / n)
    xy = np.c_[CENTRE[0] + AXES[0] * H_GAUSS * np.cos(heading), CENTRE[1] + AXES[1] * H_GAUSS * np.sin(heading)]
    return xy + rng.normal(0.0, 5e-4, xy.shape)


@pytest.mark.parametrize("layout", ["index_time_x_y", "x_y"])
def test_a_two_axis_log_is_calibrated_in_its_plane(tmp_path, capsys, layout):
    """``index, time, x, y`` (an index with one dropped row, an Erlang-style negative millisecond clock) and bare
    ``x, y``: the planar form, the field in the plane within 1 % of the generated one; before, the first was refused
    as "one heading only" (the clock read as ``mx``), the second as having no 2-D form."""
    xy = _level_turn(300, 1)
    n = xy.shape[0]
    index = np.arange(1, n + 1) + (np.arange(n) >= 120)  # one row dropped, as in sebkm's log
    clock = -576458301540 + np.cumsum(np.full(n, 111))
    rows = (np.c_[index, clock, xy] if layout == "index_time_x_y" else xy)
    path = tmp_path / "mag_bug_fixed.csv"
    path.write_text("\n".join(",".join(f"{v:.10g}" for v in r) for r in rows) + "\n")
    code, out, err = run(["calibrate", str(path), "--sensor", "mag", "--json"], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert cal["form"] == "planar"
    assert "2-axis compass" in err and "--columns" in err
    assert cal["n_samples"] == n
    H = cal["field_strength"]
    assert abs(H - H_GAUSS * np.sqrt(AXES[0] * AXES[1])) < 0.01 * H_GAUSS, H
    if layout == "index_time_x_y":
        assert "column 2 increases (the time)" in err and "column 1 increases (an index" in err


def test_a_mat_buffer_of_time_and_three_axes_is_read(tmp_path, capsys):
    """``compassBuffer`` 4 × n (time in s, then x, y, z in gauss): read with its time, calibrated; before, refused as
    "no magnetometer variable", with or without ``--topic compassBuffer``."""
    from scipy.io import savemat

    rng = np.random.default_rng(3)
    n = 2000
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    m = u * 0.53 * np.array([1.05, 0.97, 1.0]) + np.array([-0.006, -0.105, 0.020]) + rng.normal(0, 0.001, (n, 3))
    t = np.cumsum(rng.uniform(0.002, 0.02, n))
    path = tmp_path / "hmc5883l_compass.mat"
    savemat(path, {"compassBuffer": np.column_stack([t, m]).T})  # one sample per column, as sunsided's
    code, out, err = run(["calibrate", str(path), "--sensor", "mag", "--json"], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert cal["n_samples"] == n
    assert "compassBuffer(:,2)" in err and "a time" in err
    assert np.allclose(cal["o"], [-0.006, -0.105, 0.020], atol=0.002)
    assert abs(cal["field_strength"] - 0.53) < 0.01
