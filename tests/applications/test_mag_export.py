"""The magnetometer's firmware files: loaded by pymavlink / read as QGroundControl writes them, and passed
through the firmware's own equation on the recording's samples."""

from __future__ import annotations

import io
from contextlib import redirect_stdout

import numpy as np
import pytest

from helpers.cli_run import run_args
from optcal.families.calibration_files import load
from optcal.families.mag.samples import read_mag

#: The firmware's file must reproduce optcal's calibrated field to this share of the field strength on every sample.
MAX_SHARE = 0.005


@pytest.fixture
def ckexplorer(shared_data, tmp_path, capsys):
    path = shared_data / "ckexplorer-holds" / "acc_mag_log.csv"
    code, _, err = run_args(capsys, "calibrate", str(path), "--sensor", "mag", "-o", str(tmp_path / "mag.json"))
    assert code == 0, err
    return read_mag(path), load(tmp_path / "mag.json"), tmp_path


def test_ardupilot_file_in_pymavlink_and_ardupilot_equation(ckexplorer, capsys):
    samples, cal, tmp = ckexplorer
    code, _, err = run_args(capsys, "export", str(tmp / "mag.json"), "--format", "ardupilot", "--device-id", "97539",
                            "--instance", "1", "-o", str(tmp / "mag.param"))
    assert code == 0, err
    mavparm = pytest.importorskip("pymavlink.mavparm")
    p = mavparm.MAVParmDict()
    with redirect_stdout(io.StringIO()):
        assert p.load(str(tmp / "mag.param"))
    assert p["COMPASS_DEV_ID2"] == 97539
    # AP_Compass_Backend.cpp, AP_Compass_Backend::correct_field: field += offsets; field = mat * field, with
    # mat = [[dia.x, odi.x, odi.y], [odi.x, dia.y, odi.z], [odi.y, odi.z, dia.z]], field in milligauss
    ofs = np.array([p[f"COMPASS_OFS2_{a}"] for a in "XYZ"])
    dia = [p[f"COMPASS_DIA2_{a}"] for a in "XYZ"]
    odi = [p[f"COMPASS_ODI2_{a}"] for a in "XYZ"]
    mat = np.array([[dia[0], odi[0], odi[1]], [odi[0], dia[1], odi[2]], [odi[1], odi[2], dia[2]]])
    raw_mg = samples.m * 1000.0  # gauss → milligauss, the driver's units
    firmware = (raw_mg + ofs) @ mat.T
    optcal_mg = cal.field(samples.m) * 1000.0
    field_mg = cal.field_strength * 1000.0
    assert np.max(np.linalg.norm(firmware - optcal_mg, axis=1)) <= MAX_SHARE * field_mg


def test_px4_qgc_file_and_px4_equation(ckexplorer, capsys):
    samples, cal, tmp = ckexplorer
    code, _, err = run_args(capsys, "export", str(tmp / "mag.json"), "--format", "px4", "--device-id", "97539",
                            "-o", str(tmp / "mag.params"))
    assert code == 0, err
    # QGroundControl's file (ParameterManager::writeParametersToStream): tab-separated vehicle, component, name, value, type
    p = {}
    for line in (tmp / "mag.params").read_text().splitlines():
        if line and not line.startswith("#"):
            fields = line.split("\t")
            assert len(fields) == 5
            p[fields[2]] = float(fields[3])
    assert p["CAL_MAG0_ID"] == 97539
    # src/lib/sensor_calibration/Magnetometer.cpp: Correct = _rotation * (_scale * (data - _offset)), gauss, with
    # set_offdiagonal filling _scale = [[xs, xo, yo], [xo, ys, zo], [yo, zo, zs]]
    off = np.array([p[f"CAL_MAG0_{a}OFF"] for a in "XYZ"])
    s = [p[f"CAL_MAG0_{a}SCALE"] for a in "XYZ"]
    od = [p[f"CAL_MAG0_{a}ODIAG"] for a in "XYZ"]
    S = np.array([[s[0], od[0], od[1]], [od[0], s[1], od[2]], [od[1], od[2], s[2]]])
    firmware = (samples.m - off) @ S.T
    assert np.max(np.linalg.norm(firmware - cal.field(samples.m), axis=1)) <= MAX_SHARE * cal.field_strength


@pytest.mark.parametrize("fmt", ["kalibr", "imucal", "imutk"])
def test_formats_without_a_magnetometer_refuse_in_one_line(ckexplorer, capsys, fmt):
    _, _, tmp = ckexplorer
    code, out, err = run_args(capsys, "export", str(tmp / "mag.json"), "--format", fmt, "-o", str(tmp / "x"))
    assert code == 2 and "holds no magnetometer calibration" in err and "Traceback" not in err


def test_calibration_in_counts_is_refused_naming_mag_units(shared_data, tmp_path, capsys):
    path = shared_data / "ckexplorer-holds" / "acc_mag_log.csv"
    code, _, err = run_args(capsys, "calibrate", str(path), "--sensor", "mag", "--mag-units", "counts",
                            "-o", str(tmp_path / "c.json"))
    assert code == 0, err
    code, _, err = run_args(capsys, "export", str(tmp_path / "c.json"), "--format", "px4", "-o", str(tmp_path / "x"))
    assert code == 2 and "--mag-units" in err


def test_apply_writes_the_calibrated_field(ckexplorer, capsys):
    samples, cal, tmp = ckexplorer
    code, out, err = run_args(capsys, "apply", str(tmp / "mag.json"), str(samples.path), "-o", str(tmp / "out.csv"))
    assert code == 0, err
    table = np.loadtxt(tmp / "out.csv", delimiter=",", skiprows=1)
    assert table.shape == (samples.n, 4)
    assert np.allclose(table[:, :3], cal.field(samples.m), rtol=1e-8, atol=1e-9)
    assert np.sqrt(np.mean((table[:, 3] - 1) ** 2)) == pytest.approx(cal.info["rms_norm_residual"], rel=1e-6)


C_MAIN = """#include <stdio.h>
#include "mag.h"
int main(void)
{
    double m[3], out[3];
    while (scanf("%lf %lf %lf", &m[0], &m[1], &m[2]) == 3) {
        optcal_apply_mag_field(m, out);
        printf("%.17g %.17g %.17g\\n", out[0], out[1], out[2]);
    }
    return 0;
}
"""


def test_c_header_applies_the_calibration_as_optcal_apply(ckexplorer, capsys):
    """The header of the ckexplorer calibration, compiled: ``optcal_apply_mag_field`` gives on every 20th sample
    the field ``optcal apply`` writes (``field_strength · T (m − o)``)."""
    import shutil
    import subprocess

    if shutil.which("cc") is None:
        pytest.skip("no C compiler (cc) on this machine")
    samples, cal, tmp = ckexplorer
    code, _, err = run_args(capsys, "export", str(tmp / "mag.json"), "--format", "c", "-o", str(tmp / "mag.h"))
    assert code == 0, err
    header = (tmp / "mag.h").read_text()
    assert "gauss" in header and "OPTCAL_MAG_TEST_RAW" in header
    (tmp / "main.c").write_text(C_MAIN)
    subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-pedantic", "-o", str(tmp / "apply"), str(tmp / "main.c")],
                   check=True, cwd=tmp)
    m = samples.m[::20]
    stdin = "\n".join(" ".join(repr(float(v)) for v in row) for row in m)
    out = np.loadtxt(subprocess.run([str(tmp / "apply")], input=stdin, capture_output=True, text=True,
                                    check=True).stdout.splitlines())
    np.testing.assert_allclose(out, cal.field(m), rtol=0, atol=1e-12 * cal.field_strength)


def test_html_report_shows_the_sphere_before_and_after(shared_data, tmp_path, capsys):
    path = shared_data / "ckexplorer-holds" / "acc_mag_log.csv"
    code, _, err = run_args(capsys, "calibrate", str(path), "--sensor", "mag", "--report", str(tmp_path / "r.html"))
    assert code == 0, err
    html = (tmp_path / "r.html").read_text()
    assert "Magnetometer calibration" in html and html.count("<svg") >= 1
    assert "before: m − mean" in html or "before: m \u2212 mean" in html
    assert "verdict: good" in err  # 1.25 % rms of the field, every direction reached


def test_check_reads_the_magnetometer_samples(ckexplorer, capsys):
    import json

    samples, cal, tmp = ckexplorer
    code, out, err = run_args(capsys, "check", str(tmp / "mag.json"), str(samples.path), "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["sensor"] == "magnetometer" and result["data"]["n_samples"] == samples.n
    assert result["rms_norm_residual"] == pytest.approx(cal.info["rms_norm_residual"], rel=1e-9)
