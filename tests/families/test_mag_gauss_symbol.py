"""x-io's x-IMU exports (xioTechnologies' Gait-Tracking and Oscillatory-Motion-Tracking ``*_CalInertialAndMag.csv``)
write the magnetometer as ``Magnetometer X (G)``: G is the gauss's symbol, but ``g`` was taken for an acceleration's
word only, so the columns were not found ("no magnetometer columns ... map them with --columns"). After a
magnetometer's own name an acceleration's unit cannot be meant: ``G`` and ``mG`` are read as gauss and milligauss
there, and nowhere else (``ax_g`` stays an accelerometer's, a short ``m_x_g`` is not read as a magnetometer's)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli_run import run

FIELD_GAUSS = 0.48  # the Earth's field in England (x-io's home), gauss
HARD_IRON_GAUSS = (0.05, -0.12, 0.2)


def _write_ximu(path, mag_unit: str, scale: float, n: int = 2000, seed: int = 3) -> None:
    """x-IMU's calibrated export: a packet number, the gyro in °/s, the accelerometer in g, the magnetometer in
    ``mag_unit`` (``scale`` of them a gauss), turned through every direction, 0.3 % noise."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    m = (np.asarray(HARD_IRON_GAUSS) + FIELD_GAUSS * u / np.linalg.norm(u, axis=1, keepdims=True)
         + rng.normal(scale=0.0015, size=(n, 3))) * scale
    rows = [f"{2 * i + 3},0.0625,-0.25,0.125,0.01,0.02,0.99,{x:.6f},{y:.6f},{z:.6f}" for i, (x, y, z) in enumerate(m)]
    head = ("Packet number,Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),Accelerometer X (g),"
            "Accelerometer Y (g),Accelerometer Z (g),"
            f"Magnetometer X ({mag_unit}),Magnetometer Y ({mag_unit}),Magnetometer Z ({mag_unit})")
    path.write_text(head + "\n" + "\n".join(rows) + "\n")


@pytest.mark.parametrize(("mag_unit", "scale", "unit"), [("G", 1.0, "gauss"), ("mG", 1000.0, "mgauss")])
def test_a_magnetometer_in_G_is_read_in_gauss(tmp_path, capsys, mag_unit, scale, unit):
    """Read without a flag, the unit said as stated by the column names, the field and hard iron recovered."""
    path = tmp_path / "LoggedData_CalInertialAndMag.csv"
    _write_ximu(path, mag_unit, scale)
    code, out, err = run(["calibrate", str(path), "--sensor", "mag", "--json"], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert cal["units"]["input"] == unit
    assert abs(cal["field_strength"] - FIELD_GAUSS * scale) < 0.01 * FIELD_GAUSS * scale
    assert np.allclose(cal["o"], np.asarray(HARD_IRON_GAUSS) * scale, atol=0.01 * FIELD_GAUSS * scale)


def test_g_after_a_short_name_is_not_a_magnetometer(tmp_path, capsys):
    """The control: ``m_x (g)`` could be any quantity's letter in g; not read as a magnetometer's."""
    from optcal.families.mag.samples import _strip_mag_unit

    assert _strip_mag_unit("m_x_g") == ("m_x_g", None)
    assert _strip_mag_unit("accelerometer_x_g") == ("accelerometer_x_g", None)
    assert _strip_mag_unit("imu_magnetometer_x_g") == ("imu_magnetometer_x", "gauss")
