"""MATLAB (level 5 and 7.3) and netCDF-4/HDF5 files read by optcal (optcal.data.containers).

The shared files (../shared/data: hassan-innalabs-m3, hassan-lis3dh-phone, divemove-tag; read each
PROVENANCE.md) are skipped when absent; generated files cover both orientations, several variables,
ambiguity refused with the flag named, and a missing h5py.
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from scipy.io import savemat

from helpers.cli_run import run_args as run
from helpers.common import SHARED, rngs

from optcal.core.model import STANDARD_GRAVITY
from optcal.data import load, load_recording
from optcal.data.containers import MAT5, MAT73, container_type
from optcal.data.decisions import decide, gather_evidence
from optcal.data.readers import read_source
from optcal.data.units import decide_units
from optcal.errors import InputError

h5py = pytest.importorskip("h5py")

INNALABS = SHARED / "data" / "hassan-innalabs-m3"
PHONE = SHARED / "data" / "hassan-lis3dh-phone" / "MobileAccData30orientationRawSample01.mat"
DIVEMOVE = SHARED / "data" / "divemove-tag" / "magnt_accel_calib.nc"


def need(path):
    if not path.exists():
        pytest.skip(f"shared data not available: {path}")
    return path


def one_line_error(code: int, err: str) -> str:
    assert code == 2, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    return lines[0]


def poses_g(n: int, seed: int = 0) -> np.ndarray:
    """``n`` static poses of a slightly miscalibrated accelerometer, in g, (n, 3)."""
    directions, noise = rngs(seed)
    u = directions.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    T = np.array([[1.01, 0.002, -0.001], [0.0, 0.99, 0.003], [0.0, 0.0, 1.005]])
    return u @ T.T + np.array([0.01, -0.02, 0.005]) + noise.normal(scale=2e-4, size=(n, 3))


def recording_g(rate: float = 100.0, seed: int = 1) -> np.ndarray:
    """A raw recording in g: 12 rests of 4 s joined by 1 s turns, (n, 3)."""
    targets = poses_g(12, seed)
    per_rest, per_move = int(4 * rate), int(1 * rate)
    parts = []
    for a, b in zip(targets[:-1], targets[1:]):
        parts.append(np.repeat(a[None], per_rest, axis=0))
        w = np.linspace(0, 1, per_move)[:, None]
        parts.append((1 - w) * a + w * b)
    parts.append(np.repeat(targets[-1][None], per_rest, axis=0))
    _, noise = rngs(seed + 10)
    acc = np.concatenate(parts)
    return acc + noise.normal(scale=1e-3, size=acc.shape)


# ----------------------------------------------------------------------------- shared files
@pytest.mark.parametrize("name, n_poses", [
    ("CalibrationOfLowCostTriaxialInertialSensors.mat", 24),    # 3 x 24: poses as columns
    ("CalibrationOfLowCostTriaxialInertialSensors30.mat", 31),  # 31 x 3: poses as rows
    ("CalibrationOfLowCostTriaxialInertialSensors50.mat", 49),  # 3 x 49
])
def test_innalabs_mat_files_calibrate_as_pose_tables(name, n_poses, capsys):
    path = need(INNALABS / name)
    code, out, err = run(capsys, "calibrate", str(path), "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["n_poses"] == n_poses and d["data"]["kind"] == "pose table" and d["data"]["units"] == "g"
    assert d["data"]["decisions"]["layout"].startswith(f"{MAT5}, variable '{path.stem}'")
    assert d["rms_norm_residual_g"] < 3e-3  # an ellipsoid fit of the 49: about 0.84 mg (PROVENANCE.md)


def test_phone_mat_is_a_raw_recording_at_the_given_rate(capsys):
    path = need(PHONE)
    rec = load_recording(path, rate=50.0)
    assert rec.acc.shape == (8042, 3) and rec.rate_hz == 50.0 and rec.units == "m/s^2"
    assert rec.decisions.rate.reason == "--rate"
    code, out, err = run(capsys, "calibrate", str(path))
    line = one_line_error(code, err)
    assert "no time column and no sampling rate; pass --rate HZ" in line


def test_divemove_nc_is_a_recording_at_its_stated_rate_in_g_despite_its_units_attribute():
    path = need(DIVEMOVE)
    src = read_source(path)
    assert src.file_type == "netCDF-4" and src.n_rows == 44550
    assert src.column_map == {"ax": "acceleration(:,1)", "ay": "acceleration(:,2)", "az": "acceleration(:,3)"}
    assert src.rate_hint == 100.0 and "sampling_rate" in src.rate_reason
    assert "skipped 1 magnetometer variable(s)" in src.layout and "magnetic_density" in src.layout
    decisions = decide(src, gather_evidence(src))
    assert decisions.kind.value == "raw recording" and "sampling_rate" in decisions.kind.reason
    assert decisions.rate.value == 100.0
    # the attribute says m/s2, the data are in g (median |a| 0.996): the data are trusted, and it says so
    assert decisions.units.value == "g"
    assert "units attribute 'm/s2'" in decisions.units.reason and "contradict" in decisions.units.reason
    assert any("the data are trusted" in line for line in decisions.lines())


# ----------------------------------------------------------------------------- MATLAB level 5
@pytest.mark.parametrize("transpose", [False, True])
def test_mat5_pose_matrix_in_either_orientation(tmp_path, transpose):
    acc = poses_g(20)
    path = tmp_path / "poses.mat"
    savemat(path, {"M": acc.T if transpose else acc})
    assert container_type(path) == MAT5
    table = load(path)
    assert table.source == "pose table" and table.n == 20 and table.units == "g"
    np.testing.assert_allclose(table.acc, acc)
    assert table.decisions.layout.endswith(f"one per {'column' if transpose else 'row'})")


def test_mat5_square_matrix_is_refused_naming_the_orientation_flag(tmp_path, capsys):
    path = tmp_path / "square.mat"
    savemat(path, {"M": poses_g(3)})
    code, out, err = run(capsys, "calibrate", str(path))
    line = one_line_error(code, err)
    assert "--topic M:rows" in line and "--topic M:columns" in line
    src = read_source(path, topic="M:columns")
    np.testing.assert_allclose(src.column("ax"), poses_g(3)[0])


def test_mat5_variables_by_name_gyro_time_temperature_rate_and_a_skipped_magnetometer(tmp_path):
    acc = recording_g() * STANDARD_GRAVITY
    n = len(acc)
    gyro = np.random.default_rng(3).normal(scale=0.01, size=(n, 3))
    path = tmp_path / "log.mat"
    savemat(path, {"accel": acc, "gyro": gyro.T, "time_ms": np.arange(n) * 10.0, "temperature": np.full(n, 25.0),
                   "mag": np.ones((n, 3)), "imu": {"fs": 100.0}, "note": "bench run"})
    src = read_source(path)
    assert src.has("ax", "ay", "az", "gx", "gy", "gz", "t", "temp")
    np.testing.assert_allclose(src.column("gy"), gyro[:, 1])
    assert src.time_unit == "ms" and src.column("t")[1] == pytest.approx(0.01)  # in seconds
    assert src.rate_hint == 100.0 and "imu.fs" in src.rate_reason
    assert "skipped 1 magnetometer variable(s)" in src.layout and "mag" in src.ignored_columns
    assert "note" in src.ignored_columns
    rec = load_recording(path)
    assert rec.units == "m/s^2" and rec.rate_hz == pytest.approx(100.0)


def test_mat5_four_axes_time_first_and_columns_by_position(tmp_path):
    acc = recording_g()
    t = np.arange(len(acc)) / 100.0
    path = tmp_path / "t_acc.mat"
    savemat(path, {"data": np.column_stack([t, acc]).T})  # 4 x n: one sample per column
    src = read_source(path)
    np.testing.assert_allclose(src.column("t"), t)
    np.testing.assert_allclose(src.column("az"), acc[:, 2])
    # the time last: not the 4-axis layout, so the axes are refused until mapped
    savemat(path, {"data": np.column_stack([acc, t])})
    with pytest.raises(InputError, match="first does not increase.*--columns"):
        read_source(path)
    src = read_source(path, columns="ax=1,ay=2,az=3,t=4")
    np.testing.assert_allclose(src.column("t"), t)


def test_several_candidate_matrices_are_refused_naming_them_and_topic(tmp_path, capsys):
    path = tmp_path / "two.mat"
    savemat(path, {"first": poses_g(20, 1), "second": poses_g(20, 2).T})
    code, out, err = run(capsys, "calibrate", str(path))
    line = one_line_error(code, err)
    assert "first (20 × 3)" in line and "second (3 × 20)" in line and "--topic NAME" in line
    np.testing.assert_allclose(load(path, topic="second").acc, poses_g(20, 2))


def test_a_magnetometer_alone_is_not_an_accelerometer(tmp_path):
    path = tmp_path / "mag.mat"
    savemat(path, {"magnetic_field": poses_g(20) * 48.0})
    with pytest.raises(InputError, match="no accelerometer matrix.*magnetic_field .20 × 3, magnetometer"):
        read_source(path)
    with pytest.raises(InputError, match="is a magnetometer's"):
        read_source(path, topic="magnetic_field")


def test_a_text_file_named_mat_is_still_text(tmp_path):
    path = tmp_path / "xsens_acc.mat"  # imu_tk's text files end in .mat
    np.savetxt(path, poses_g(20), fmt="%.6f")
    assert container_type(path) is None
    assert read_source(path).file_type == "csv"


# ----------------------------------------------------------------------------- HDF5: MATLAB 7.3 and netCDF-4
def write_mat73(path, variables: dict[str, np.ndarray], struct: dict[str, np.ndarray] | None = None) -> None:
    """A MATLAB 7.3-like file: a 512-byte MATLAB header, then HDF5 holding arrays column-major (transposed)."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            ds = f.create_dataset(name, data=np.asarray(value).T)
            ds.attrs["MATLAB_class"] = np.bytes_("double")
        group = f.create_group("imu") if struct else None
        for name, value in (struct or {}).items():
            group.create_dataset(name, data=np.asarray(value).T).attrs["MATLAB_class"] = np.bytes_("double")
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    with open(path, "r+b") as fh:
        fh.write(header.ljust(128, b" "))


def test_mat73_is_read_in_matlabs_orientation_with_struct_fields(tmp_path):
    acc = recording_g()
    path = tmp_path / "v73.mat"
    write_mat73(path, {"label_counts": np.arange(7.0).reshape(1, 7)}, struct={"acc": acc, "t": np.arange(len(acc)) / 100.0})
    assert container_type(path) == MAT73
    src = read_source(path)
    assert src.file_type == MAT73 and src.column_map["ax"] == "imu.acc(:,1)" and src.column_map["t"] == "imu.t"
    np.testing.assert_allclose(src.column("ay"), acc[:, 1])
    rec = load_recording(path)
    assert rec.units == "g" and rec.rate_hz == pytest.approx(100.0)


def write_netcdf_like(path, acc, units="m/s2", extra: dict[str, np.ndarray] | None = None, rate=50.0) -> None:
    """A netCDF-4-like HDF5 file: _NCProperties, bare dimensions, variables with units and a global sampling rate."""
    n = len(acc)
    with h5py.File(path, "w") as f:
        f.attrs["_NCProperties"] = np.bytes_("version=2,netcdf=4.7.4,hdf5=1.12.0,")
        f.attrs["sampling_rate"] = np.array([rate])
        f.attrs["sampling_rate_units"] = np.bytes_("Hz")
        for dim, size in (("sample", n), ("axis", 3)):
            d = f.create_dataset(dim, shape=(size,), dtype="f4")
            d.attrs["CLASS"] = np.bytes_("DIMENSION_SCALE")
            d.attrs["NAME"] = np.bytes_(f"This is a netCDF dimension but not a netCDF variable. {size:9d}")
        a = f.create_dataset("linear_acceleration", data=acc)
        a.attrs["units"] = np.bytes_(units)
        for name, (values, unit) in (extra or {}).items():
            f.create_dataset(name, data=values).attrs["units"] = np.bytes_(unit)


def test_netcdf_like_file_with_several_variables(tmp_path):
    acc = recording_g(rate=50.0) * STANDARD_GRAVITY
    n = len(acc)
    gyro = np.random.default_rng(4).normal(scale=0.01, size=(n, 3))
    path = tmp_path / "tag.nc"
    write_netcdf_like(path, acc, extra={
        "angular_velocity": (gyro, "rad/s"),
        "time": (np.arange(n) / 50.0, "seconds since 2021-04-30 00:00:00"),
        "magnetic_field": (np.ones((n, 3)), "uT"),
        "pressure": (np.ones((n, 2)), "hPa"),
    })
    src = read_source(path)
    assert src.file_type == "netCDF-4" and src.gyro_units == "rad/s" and src.time_unit == "s"
    np.testing.assert_allclose(src.column("gz"), gyro[:, 2])
    assert src.rate_hint == 50.0 and src.rate_reason == "attribute sampling_rate = 50 Hz of the file"
    assert "skipped 1 magnetometer variable(s)" in src.layout and "1 other variable(s) not used: pressure" in src.layout
    rec = load_recording(path)
    assert rec.units == "m/s^2" and rec.units_reason == "units attribute 'm/s2' of variable 'linear_acceleration'"


def test_a_units_attribute_the_data_contradict_without_telling_is_refused_naming_units(tmp_path, capsys):
    path = tmp_path / "odd.nc"
    write_netcdf_like(path, recording_g(rate=50.0) * 3.0)  # median |a| ≈ 3: neither g, m/s^2 nor counts
    code, out, err = run(capsys, "calibrate", str(path))
    line = one_line_error(code, err)
    assert "units attribute 'm/s2'" in line and "contradict the data" in line and "--units" in line


def test_the_units_decision_trusts_the_data_over_a_stated_unit_they_contradict():
    decision = decide_units(None, hint="m/s^2", hint_reason="unit word 'ms2' in the column names", norm=0.996)
    assert decision.units == "g" and "the file states m/s^2" in decision.reason and "data are trusted" in decision.reason
    assert decide_units(None, hint="m/s^2", norm=9.7).units == "m/s^2"
    with pytest.raises(InputError, match=r"contradict the data.*--units"):
        decide_units(None, requested="m/s^2", norm=0.996)  # the user's flag is not overruled: refused


def test_hdf5_without_h5py_asks_for_the_extra(tmp_path, capsys, monkeypatch):
    path = tmp_path / "tag.nc"
    write_netcdf_like(path, recording_g(rate=50.0))
    monkeypatch.setitem(sys.modules, "h5py", None)  # import h5py raises ImportError
    code, out, err = run(capsys, "calibrate", str(path))
    line = one_line_error(code, err)
    assert "pip install 'optcal[hdf5]'" in line


def test_a_truncated_netcdf_file_is_refused(tmp_path, capsys):
    path = tmp_path / "cut.nc"
    path.write_bytes(b"\x00" * 100)
    code, out, err = run(capsys, "calibrate", str(path))
    assert "truncated or corrupt" in one_line_error(code, err)
