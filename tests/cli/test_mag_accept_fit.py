"""``--accept-mag-fit`` on every command that reads a magnetometer: the rail line of ``read_mag`` named
``calibrate --accept-mag-fit`` while ``diagnose --sensor mag``, ``check``, ``plan --sensor mag`` and ``apply`` had no
such flag.  Each now keeps the rail's samples with it, says so, and a command reading no magnetometer refuses it."""

from __future__ import annotations

import numpy as np

from helpers.cli_run import run_args

#: HMC5883L's default range, ±1.3 G, in 1/1090-G steps (its gain at that range), as tests/families/test_mag_rail.py.
RAIL_G, STEP_G = 1.3, 1 / 1090


def _clipped_turns(path, n: int = 3000, rate_hz: float = 100.0) -> int:
    """A 0.5-G field seen by a sensor tumbling about a wandering axis, a 1.0-G hard iron on x, clipped at ±1.3 G;
    returns how many samples hold an axis at the rail."""
    t = np.arange(n) / rate_hz
    az, el = 0.7 * t, 0.9 * np.sin(0.23 * t)
    field = 0.5 * np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    m = np.clip(np.round((field + [1.0, 0.0, 0.0]) / STEP_G) * STEP_G, -RAIL_G, RAIL_G)
    np.savetxt(path, m, delimiter=",", header="mag_x_gauss,mag_y_gauss,mag_z_gauss", comments="", fmt="%.6f")
    return int(np.count_nonzero(np.any(np.abs(m) >= RAIL_G, axis=1)))


def test_every_command_reading_a_magnetometer_keeps_its_rail_with_the_flag(tmp_path, capsys):
    data, cal = tmp_path / "mag.csv", tmp_path / "mag.json"
    at_rail = _clipped_turns(data)
    code, out, _ = run_args(capsys, "calibrate", data, "--sensor", "mag", "--mag-form", "offsets", "-o", cal)
    assert code == 0 and f"magnetometer rail: {at_rail} of 3000" in out and "calibrate --accept-mag-fit" not in out
    kept = f"{at_rail} magnetometer samples at a rail kept (--accept-mag-fit)"
    for argv in (("check", cal, data), ("plan", "--sensor", "mag", "--next", data),
                 ("diagnose", data, "--sensor", "mag"), ("apply", cal, data, "-o", tmp_path / "out.csv")):
        code, out, err = run_args(capsys, *argv, "--accept-mag-fit")
        assert code == 0 and kept in out, (argv, err)
    assert len(np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)) == 3000  # every row written
    code, out, err = run_args(capsys, "plan", "--poses", "6", "--accept-mag-fit")
    assert code == 2 and err.strip() == "error: --accept-mag-fit applies with --sensor mag"
