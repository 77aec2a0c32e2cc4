"""PX4 ULog files as PX4 writes them by default (pyulog's own sample logs, PX4/pyulog ``test/*.ulg``): the vehicle's
IMU in ``sensor_combined`` at the IMU's rate, and ``sensor_accel`` at the logger profile's 1 Hz or not at all.
Before, optcal read ``sensor_accel`` only: at 1 Hz it found "no static interval in 6 samples", and where the topic
was not logged it said "logged: none" though the file held ``sensor_combined``.  Now ``sensor_combined`` is read
when the raw topic is absent or too slow to show a rest, the decision said with ``--topic sensor_accel``."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from optcal.data import load, load_recording
from optcal.data.recording import SATURATED
from optcal.data.writers import _ACCEL_FORMAT, _ULOG_MAGIC, _ulog_message, write_ulog
from optcal.errors import InputError
from optcal.families.simulate.poses import uniform_directions
from optcal.families.simulate.recording import synthesize_recording
from optcal.core.model import LumpedModel

#: PX4's sensor_combined (msg/SensorCombined.msg, v1.12 on: the clipping bitfields).
_COMBINED_FORMAT = ("sensor_combined:uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;"
                    "int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2;"
                    "uint32_t accelerometer_integral_dt;uint8_t accelerometer_clipping;uint8_t gyro_clipping;")


def ms2_model() -> LumpedModel:
    """A sensor in m/s² (the PX4 convention), as test_data_readers' recording."""
    return LumpedModel.from_physical([9.70, 9.90, 9.80], 0.01, -0.01, 0.02, [0.10, -0.20, 0.30])


@pytest.fixture(scope="module")
def recording():
    """12 poses of 3 s at 100 Hz, m/s² and rad/s, temperature."""
    return synthesize_recording(ms2_model(), uniform_directions(12, rng=3), dwell_s=3.0, transition_s=1.5,
                                sigma=0.02, gyro_units="rad/s", temperature=(30.0, 0.02), rng=4, units="m/s^2", t0=1000.0)


def _write_px4(frame, path, raw_every: int | None, clipped=()) -> None:
    """sensor_combined every row (accelerometer stamped 1 ms after the gyro), and sensor_accel every
    ``raw_every``-th row (PX4's 1-Hz logger profile), or not logged (None)."""
    t_us = np.round(frame["t"].to_numpy(float) * 1e6).astype(np.int64)
    acc, gyro = frame[["ax", "ay", "az"]].to_numpy(np.float32), frame[["gx", "gy", "gz"]].to_numpy(np.float32)
    out = bytearray(_ULOG_MAGIC + struct.pack("<B", 1) + struct.pack("<Q", int(t_us[0])))
    out += _ulog_message(b"B", bytes(8) + bytes(8) + struct.pack("<3Q", 0, 0, 0))
    out += _ulog_message(b"F", _COMBINED_FORMAT.encode()) + _ulog_message(b"F", _ACCEL_FORMAT.encode())
    out += _ulog_message(b"A", struct.pack("<BH", 0, 0) + b"sensor_combined")
    if raw_every:
        out += _ulog_message(b"A", struct.pack("<BH", 0, 1) + b"sensor_accel")
    comb, raw = struct.Struct("<HQ3fIi3fIBB"), struct.Struct("<HQQIffffI3BB")
    for i in range(len(frame)):
        clip = 0b010 if i in clipped else 0
        out += _ulog_message(b"D", comb.pack(0, int(t_us[i]) - 1000, *gyro[i], 5000, 1000, *acc[i], 5000, clip, 0))
        if raw_every and i % raw_every == 0:
            out += _ulog_message(b"D", raw.pack(1, int(t_us[i]), int(t_us[i]), 1, *acc[i], 30.0, 0, 0, 0, 0, 1))
    path.write_bytes(bytes(out))


@pytest.mark.parametrize("raw_every", [100, None], ids=["sensor_accel at 1 Hz", "sensor_accel not logged"])
def test_sensor_combined_is_read_where_the_raw_topic_cannot_show_a_rest(recording, tmp_path, raw_every):
    path = tmp_path / "px4.ulg"
    _write_px4(recording.frame, path, raw_every, clipped={100, 101})
    loaded = load(path)
    assert loaded.n == len(recording.dwells)
    assert np.allclose(loaded.acc,
                       [np.mean(recording.frame[["ax", "ay", "az"]].to_numpy()[a:b], axis=0)
                        for a, b in recording.dwells], atol=0.02)
    note = " ".join(loaded.meta["notes"])
    assert "topic sensor_combined:0 read" in note and "--topic sensor_accel" in note
    assert ("logged at 1 Hz" if raw_every else "sensor_accel is not logged") in note
    rec = load_recording(path)
    assert rec.exclusions[SATURATED] == 2  # the accelerometer_clipping bits
    assert rec.gyro_units == "rad/s"
    if raw_every:  # the override: the raw topic, 1 sample a second
        assert load_recording(path, topic="sensor_accel").n == -(-len(recording.frame) // raw_every)
    else:  # the refusal lists what is logged (before: "logged: none")
        with pytest.raises(InputError, match=r"logged: sensor_combined:0\)"):
            load(path, topic="sensor_accel")


def test_a_raw_topic_at_the_imus_rate_is_still_read(recording, tmp_path):
    """The control: PX4's sensor_accel logged at full rate is what is read, without a note of another topic."""
    write_ulog(recording.frame, tmp_path / "raw.ulg")
    loaded = load(tmp_path / "raw.ulg")
    assert loaded.n == len(recording.dwells)
    assert not any("sensor_combined" in n for n in loaded.meta["notes"])


def test_a_dataflash_log_without_an_imu_is_refused_in_one_line(tmp_path, capsys):
    """ArduPilot's .bin is read natively now (tests/data/test_dataflash.py); one holding no IMU or compass message
    (only its FMT messages) is refused with one line that names --topic."""
    from helpers.cli_run import run

    path = tmp_path / "00000044.BIN"
    fmt = struct.pack("<BB", 128, 89) + b"FMT\x00" + b"BBnNZ".ljust(16, b"\x00") + b"Type,Length,Name,Format,Columns"
    path.write_bytes(b"\xa3\x95\x80" + fmt.ljust(86, b"\x00") * 3)
    for args, what in ((["segment", str(path)], "IMU"), (["calibrate", str(path), "--sensor", "mag"], "MAG")):
        code, out, err = run(args, capsys)
        assert code == 2 and err.count("\n") == 1
        assert f"no DataFlash {what} instance 0" in err and "--topic" in err
