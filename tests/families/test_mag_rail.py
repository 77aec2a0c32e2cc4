"""A magnetometer held at its converter's rail (x-io's Oscillatory log: 15.99951 G on x and y in most samples):
before, nothing looked for a rail, and the units note read the held samples' |m| as "Earth's field in µT".  Now the
accelerometer's rail model (``rails.rail_samples``, with the gyro's held-beyond-a-peak test) finds it, the samples
are left out and counted in one line, and ``calibrate --accept-mag-fit`` keeps them."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.families.mag.samples import MAG_RAIL_ROWS, read_mag

#: HMC5883L's default range, ±1.3 G, in 1/1090-G steps (its gain at that range).
RAIL_G, STEP_G = 1.3, 1 / 1090


def _turning(n: int = 4000, rate_hz: float = 100.0) -> np.ndarray:
    """A 0.5-G field seen by a sensor tumbling smoothly about a wandering axis, plus a 1.0-G hard iron on x."""
    t = np.arange(n) / rate_hz
    az, el = 0.7 * t, 0.9 * np.sin(0.23 * t)
    field = 0.5 * np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return np.round((field + [1.0, 0.0, 0.0]) / STEP_G) * STEP_G


@pytest.mark.parametrize("clipped", [True, False], ids=["clipped at ±1.3 G", "within range (control)"])
def test_a_magnetometer_rail_is_left_out_and_said(tmp_path, clipped):
    m = _turning()
    if clipped:
        m = np.clip(m, -RAIL_G, RAIL_G)
    path = tmp_path / "mag.csv"
    np.savetxt(path, m, delimiter=",", header="mag_x_gauss,mag_y_gauss,mag_z_gauss", comments="", fmt="%.6f")
    samples = read_mag(path)
    at_rail = int(np.count_nonzero(np.any(np.abs(m) >= RAIL_G, axis=1)))
    assert samples.exclusions.get(MAG_RAIL_ROWS, 0) == (at_rail if clipped else 0)
    assert samples.n == len(m) - (at_rail if clipped else 0)
    line = [n for n in samples.notes if n.startswith("magnetometer rail")]
    if clipped:
        assert at_rail > 100 and len(line) == 1 and "±1.3 gauss" in line[0] and "--accept-mag-fit" in line[0]
        assert read_mag(path, keep_rail=True).n == len(m)
    else:  # x peaks at 1.5 G, read by several equal samples as it turns: no rail
        assert at_rail > 100 and not line
