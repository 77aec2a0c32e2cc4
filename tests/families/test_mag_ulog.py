"""The magnetometer of a PX4 ULog file where ``sensor_mag`` is not logged (pyulog's ``test/sample.ulg``: an older
PX4 logs the magnetometer in ``sensor_combined.magnetometer_ga``; newer ones in ``vehicle_magnetometer``): refused
before ("no ULog topic sensor_mag instance 0"); now the calibrated topic is read, said with what it means, and a
missing topic's refusal lists the magnetometer topics logged."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from optcal.data.writers import _ULOG_MAGIC, _ulog_message
from optcal.errors import InputError
from optcal.families.mag.calibration import calibrate_mag
from optcal.families.mag.samples import read_mag

FIELD_GAUSS = 0.5
HARD_IRON_GAUSS = (0.08, -0.05, 0.12)
_FORMATS = {
    "sensor_mag": "sensor_mag:uint64_t timestamp;float x;float y;float z;float temperature;",
    "vehicle_magnetometer": "vehicle_magnetometer:uint64_t timestamp;float[3] magnetometer_ga;",
    "sensor_combined": ("sensor_combined:uint64_t timestamp;int32_t magnetometer_timestamp_relative;"
                        "float[3] magnetometer_ga;"),
}


def _write(path, topic: str, n: int = 1500, seed: int = 4) -> None:
    """A magnetometer turned through every direction at 50 Hz, logged in ``topic`` only."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    m = (np.asarray(HARD_IRON_GAUSS) + FIELD_GAUSS * u / np.linalg.norm(u, axis=1, keepdims=True)
         + rng.normal(scale=0.001, size=(n, 3))).astype(np.float32)
    t_us = 10**6 + np.arange(n) * 20_000
    out = bytearray(_ULOG_MAGIC + struct.pack("<B", 1) + struct.pack("<Q", int(t_us[0])))
    out += _ulog_message(b"B", bytes(8) + bytes(8) + struct.pack("<3Q", 0, 0, 0))
    out += _ulog_message(b"F", _FORMATS[topic].encode())
    out += _ulog_message(b"A", struct.pack("<BH", 0, 0) + topic.encode())
    for i in range(n):
        payload = {"sensor_mag": lambda: struct.pack("<Q3ff", int(t_us[i]), *m[i], 30.0),
                   "vehicle_magnetometer": lambda: struct.pack("<Q3f", int(t_us[i]), *m[i]),
                   "sensor_combined": lambda: struct.pack("<Qi3f", int(t_us[i]), 0, *m[i])}[topic]()
        out += _ulog_message(b"D", struct.pack("<H", 0) + payload)
    path.write_bytes(bytes(out))


@pytest.mark.parametrize("topic", ["vehicle_magnetometer", "sensor_combined", "sensor_mag"])
def test_a_px4_magnetometer_is_read_from_the_topic_logged(tmp_path, topic):
    path = tmp_path / "mag.ulg"
    _write(path, topic)
    samples = read_mag(path)
    assert samples.n == 1500 and samples.units.units == "gauss"
    calibrated = topic != "sensor_mag"
    assert any("CAL_MAG" in note for note in samples.notes) == calibrated
    cal = calibrate_mag(samples).calibration
    assert abs(cal.field_strength - FIELD_GAUSS) < 0.005
    assert np.allclose(cal.o, HARD_IRON_GAUSS, atol=0.005)
    if calibrated:  # the raw topic asked for: refused, listing what is logged
        with pytest.raises(InputError, match=rf"logged: {topic}:0\)"):
            read_mag(path, topic="sensor_mag")
