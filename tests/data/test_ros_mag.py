"""A ROS magnetometer (``sensor_msgs/MagneticField``, tesla: REP 145) read by ``optcal calibrate --sensor mag``:
from a rosbag2 written in the test by the ``rosbags`` library (the IMU topic joined at the nearest stamps, the
samples without one counted) and from a ``rostopic echo -p`` CSV export (columns ``field.magnetic_field.x``).
The samples are generated: a field of 50 µT seen from many orientations through a known hard and soft iron."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from optcal.core.rotations import exponential_map

FIELD_T = 50e-6
O_T = np.array([12e-6, -7e-6, 4e-6])
A_SOFT = np.array([[1.05, 0.02, -0.01], [0.02, 0.97, 0.015], [-0.01, 0.015, 1.01]])


def _session(n: int = 1200, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps (s), raw field (T) and specific force (m/s²) of a sensor turned through many orientations."""
    rng = np.random.default_rng(seed)
    h = FIELD_T * np.array([np.cos(np.radians(60)), 0.0, -np.sin(np.radians(60))])  # dip 60°
    g = np.array([0.0, 0.0, 9.81])
    R = [exponential_map(v) for v in rng.normal(size=(n, 3))]
    b = np.array([r.T @ h for r in R])
    a = np.array([r.T @ g for r in R])
    m = b @ A_SOFT.T + O_T + rng.normal(scale=5e-8, size=(n, 3))
    t = 100.0 + np.arange(n) * 0.02
    return t, m, a


def _write_bag(path, t, m, a, imu_t=None):
    rosbags = pytest.importorskip("rosbags")  # noqa: F841
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    ty = ts.types
    Header, Time, Vector3 = ty["std_msgs/msg/Header"], ty["builtin_interfaces/msg/Time"], ty["geometry_msgs/msg/Vector3"]
    Mag, Imu, Quaternion = ty["sensor_msgs/msg/MagneticField"], ty["sensor_msgs/msg/Imu"], ty["geometry_msgs/msg/Quaternion"]
    z9 = np.zeros(9)

    def header(sec: float):
        ns = int(round(sec * 1e9))
        return ns, Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id="imu")

    imu_t = t if imu_t is None else imu_t
    with Writer(path, version=9) as w:
        cm = w.add_connection("/imu/mag", "sensor_msgs/msg/MagneticField", typestore=ts)
        ci = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        for k in range(t.size):
            ns, hd = header(t[k])
            msg = Mag(header=hd, magnetic_field=Vector3(x=m[k, 0], y=m[k, 1], z=m[k, 2]), magnetic_field_covariance=z9)
            w.write(cm, ns, ts.serialize_cdr(msg, "sensor_msgs/msg/MagneticField"))
        for k in range(imu_t.size):
            ns, hd = header(imu_t[k])
            msg = Imu(header=hd, orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=z9,
                      angular_velocity=Vector3(x=0.0, y=0.0, z=0.0), angular_velocity_covariance=z9,
                      linear_acceleration=Vector3(x=a[k, 0], y=a[k, 1], z=a[k, 2]), linear_acceleration_covariance=z9)
            w.write(ci, ns, ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


def test_a_rosbag2_magnetic_field_is_read_in_tesla_with_the_imu_joined(tmp_path):
    from optcal.families.mag.calibration import calibrate_mag
    from optcal.families.mag.samples import read_mag

    t, m, a = _session()
    gap = (t > 110.0) & (t < 112.0)  # the IMU's stream drops for 2 s: 99 magnetometer samples have no IMU sample
    _write_bag(tmp_path / "bag", t, m, a[~gap], imu_t=t[~gap])
    s = read_mag(tmp_path / "bag")
    assert s.units.units == "T" and s.n == t.size
    assert np.allclose(s.m, m) and np.allclose(s.t, t)
    assert s.acc is not None and np.isnan(s.acc[gap]).all() and np.allclose(s.acc[~gap], a[~gap])
    assert any(f"{int(gap.sum())} of {t.size} magnetometer samples without an IMU sample" in n for n in s.notes)
    res = calibrate_mag(s)
    assert abs(res.calibration.field_strength - FIELD_T) < 0.02 * FIELD_T
    assert np.allclose(res.calibration.o, O_T, atol=0.01 * FIELD_T)
    assert res.dip is not None and abs(res.dip.dip_deg - 60.0) < 0.5


def test_calibrate_sensor_mag_reads_the_bag_on_the_command_line(tmp_path, capsys):
    import json

    from optcal.cli.main import main

    t, m, a = _session(600)
    _write_bag(tmp_path / "bag", t, m, a)
    assert main(["calibrate", str(tmp_path / "bag"), "--sensor", "mag", "--json"]) in (0, None)
    out = json.loads(capsys.readouterr().out)
    assert out["sensor"] == "magnetometer" and out["n_samples"] == 600
    assert abs(out["field_strength"] - FIELD_T) < 0.02 * FIELD_T and "dip_deg" in out


def test_a_bag_without_magnetic_field_is_one_line(tmp_path):
    pytest.importorskip("rosbags")
    from optcal.data.writers import write_rosbag
    from optcal.errors import InputError
    from optcal.families.mag.samples import read_mag

    t, _, a = _session(50)
    write_rosbag(pd.DataFrame({"t": t, "ax": a[:, 0], "ay": a[:, 1], "az": a[:, 2]}), tmp_path / "imu", version=2)
    with pytest.raises(InputError, match=r"no sensor_msgs/MagneticField topic in the bag \(topics: /imu/data"):
        read_mag(tmp_path / "imu")


@pytest.mark.parametrize("prefix", ["field.", ""])
def test_a_rostopic_csv_export_is_read_as_a_magnetometer(tmp_path, prefix):
    # `rostopic echo -p /imu/mag` writes field.header.seq, field.header.stamp, field.header.frame_id,
    # field.magnetic_field.x, ... after "%time" (ROS 1's rostopic, _str_plot_fields: the header starts with "%", a
    # comment mark to the text reader, taken as the header because it names the magnetometer's columns); ros2 bag
    # exports drop the "field." prefix
    from optcal.families.mag.samples import read_mag

    t, m, _ = _session(300)
    frame = pd.DataFrame({"%time": (t * 1e9).astype(np.int64), f"{prefix}header.stamp": (t * 1e9).astype(np.int64),
                          f"{prefix}header.frame_id": "imu",
                          **{f"{prefix}magnetic_field.{a}": m[:, j] for j, a in enumerate("xyz")}})
    frame.to_csv(tmp_path / "mag.csv", index=False, float_format="%.9g")
    s = read_mag(tmp_path / "mag.csv")
    assert s.columns["mx"] == f"{prefix}magnetic_field.x" and s.units.units == "T" and s.columns["t"] == "time"
    assert np.allclose(s.m, m, rtol=1e-6)
