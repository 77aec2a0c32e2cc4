"""Other tools' calibrations: imucal's JSON and imu_tk's .calib read, applied, checked, diagnosed; imucal's written.

The acceptance runs against the real ``imucal`` package (the test extra): its Ferraris calibration
of its own example session, made here with its own ``FerrarisCalibration`` and the session's
section list, is applied by ``optcal apply`` to 1e-9 of imucal's own ``calibrate_df``; optcal's
``export --format imucal`` is loaded by ``imucal.management.load_calibration_info`` and applied to
1e-9 of ``optcal apply``.  imu_tk is C++ and not on the package index: its ``.calib`` pair is written
here in the layout of ``CalibratedTriad_::save`` (Kyle-ak/imu_tk, ``include/imu_tk/calibration.h``)
from imu_tk's own result of the Xsens recording (``imutk-xsens/IMUTK_REFERENCE.md``), and its
residual is re-computed with imu_tk's equation ``X' = T K (X − B)`` in a few lines.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from optcal.families import calibration_files
from optcal.families.caltypes.peer import PeerCalibration
from optcal.families.peer_files import parse_imutk
from tests.helpers.cli_run import run_args

imucal = pytest.importorskip("imucal")
pd = pytest.importorskip("pandas")

#: Agreement asked of optcal's application of a peer's calibration with the peer's own (m/s², deg/s).
EXACT: float = 1e-9


# ----------------------------------------------------------------------------------- fixtures
@pytest.fixture
def imucal_session(shared_data: Path) -> tuple[Path, object, object]:
    """imucal's example session, imucal's Ferraris calibration of it (imucal's own code) and its output."""
    from imucal import FerrarisCalibration, ferraris_regions_from_section_list

    folder = shared_data / "imucal-ferraris"
    data = pd.read_csv(folder / "example_ferraris_session.csv", header=0, index_col=0)
    sections = pd.read_json(folder / "example_ferraris_session_list.json").T  # imucal's examples/basic_ferraris.py
    regions = ferraris_regions_from_section_list(data, sections)
    info = FerrarisCalibration().compute(regions, sampling_rate_hz=102.4, from_acc_unit="m/s^2", from_gyr_unit="deg/s")
    return folder / "example_ferraris_session.csv", info, info.calibrate_df(data, "m/s^2", "deg/s")


def imutk_reference(shared_data: Path) -> dict[str, np.ndarray | float]:
    """imu_tk's own result of the Xsens recording, read from IMUTK_REFERENCE.md (T, K, b of each sensor, g, rms)."""
    text = (shared_data / "imutk-xsens" / "IMUTK_REFERENCE.md").read_text()
    acc, gyro = text.split("## Gyroscope")[0].split("## Accelerometer")[1], text.split("## Gyroscope")[1]

    def numbers(block: str, name: str) -> np.ndarray:
        line = next(ln for ln in block.splitlines() if ln.startswith(f"- {name} "))
        value = line.split("=", 1)[1].strip().removeprefix("diag")
        value = value[: value.index("]]") + 2] if value.startswith("[[") else value[: value.index(")") + 1]
        return np.array([float(v.replace("−", "-")) for v in re.findall(r"[−-]?\d+\.?\d*(?:e[−-]?\d+)?", value)])

    out: dict[str, np.ndarray | float] = {}
    for sensor, block in (("acc", acc), ("gyro", gyro)):
        out[f"{sensor}_T"] = numbers(block, "T").reshape(3, 3)
        out[f"{sensor}_K"] = np.diag(numbers(block, "K"))
        out[f"{sensor}_b"] = numbers(block, "b")
    out["g"] = float(re.search(r"g = ([0-9.]+) m/s²", text).group(1))
    out["rms_mg"] = float(re.search(r"interval means of \|a\|/g − 1: ([0-9.]+) mg", text).group(1))
    return out


def save_calib(path: Path, T: np.ndarray, K: np.ndarray, B: np.ndarray) -> None:
    """imu_tk's ``CalibratedTriad_::save``: ``file << mis_mat_ << endl << endl << scale_mat_ ...`` (Eigen's
    default format: a matrix row per line, the stream's 6 significant digits)."""
    def block(M: np.ndarray) -> str:
        return "\n".join(" ".join(f"{v:g}" for v in np.atleast_1d(row)) for row in M)

    path.write_text(f"{block(T)}\n\n{block(K)}\n\n{block(B.reshape(3, 1))}\n\n")


@pytest.fixture
def imutk_pair(shared_data: Path, tmp_path: Path) -> tuple[Path, dict]:
    ref = imutk_reference(shared_data)
    folder = tmp_path / "imutk"
    folder.mkdir()
    save_calib(folder / "test_imu_acc.calib", ref["acc_T"], ref["acc_K"], ref["acc_b"])  # names of apps/test_imu_calib.cpp
    save_calib(folder / "test_imu_gyro.calib", ref["gyro_T"], ref["gyro_K"], ref["gyro_b"])
    return folder / "test_imu_acc.calib", ref


# ----------------------------------------------------------------------------------- imucal
def test_imucal_calibration_applied_as_imucal_applies_it(imucal_session, tmp_path, capsys):
    data, info, expected = imucal_session
    cal_file = tmp_path / "ferraris.json"
    info.to_json_file(cal_file)
    cal = calibration_files.load(cal_file)
    assert isinstance(cal, PeerCalibration) and cal.label == "imucal Ferraris" and cal.units == "m/s^2"
    out = tmp_path / "applied.csv"
    code, stdout, _ = run_args(capsys, "apply", str(cal_file), str(data), "--rate", "102.4", "--units", "m/s^2", "-o", str(out))
    assert code == 0, stdout
    assert "read as imucal's calibration JSON (cal_type Ferraris" in stdout
    got = pd.read_csv(out)
    acc = got[["ax_m_s2", "ay_m_s2", "az_m_s2"]].to_numpy()
    gyr = np.degrees(got[["gx_rad_s", "gy_rad_s", "gz_rad_s"]].to_numpy())
    assert np.max(np.abs(acc - expected[["acc_x", "acc_y", "acc_z"]].to_numpy())) < EXACT
    assert np.max(np.abs(gyr - expected[["gyr_x", "gyr_y", "gyr_z"]].to_numpy())) < EXACT


def test_turntable_and_units_of_imucal_files(imucal_session):
    _, info, _ = imucal_session
    d = json.loads(info.to_json())
    d["cal_type"] = "Turntable"  # imucal's TurntableCalibrationInfo: the same equations
    cal = calibration_files.load(d)
    assert cal.label == "imucal Turntable"
    d.update(from_acc_unit="a.u.", from_gyr_unit="a.u.")  # imucal's docstring's raw units
    cal = calibration_files.load(d, gravity=9.80665)
    assert (cal.units, cal.gyro_units, cal.gravity_m_s2, cal.gravity_reason) == ("counts", "counts", 9.80665, "given")
    d["_format_version"] = "3.0.0"
    with pytest.raises(Exception, match="imucal's format 2.x"):
        calibration_files.load(d)


def test_optcal_export_loaded_and_applied_by_imucal(shared_data, tmp_path, capsys):
    from imucal.management import load_calibration_info

    data = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    cal = tmp_path / "imu.json"
    code, out, _ = run_args(capsys, "calibrate", str(data), "--imu", "--g-sensitivity", "-o", str(cal))
    assert code == 0, out
    exported = tmp_path / "imucal.json"
    code, out, _ = run_args(capsys, "export", str(cal), "--format", "imucal", "-o", str(exported))
    assert code == 0 and "G_g / g -> K_ga" in out
    applied = tmp_path / "applied.csv"
    assert run_args(capsys, "apply", str(cal), str(data), "--units", "m/s^2", "-o", str(applied))[0] == 0
    info = load_calibration_info(exported)
    raw = pd.read_csv(data)
    acc, gyr = info.calibrate(raw.iloc[:, 1:4].to_numpy(float), raw.iloc[:, 4:7].to_numpy(float), "counts", "counts")
    ours = pd.read_csv(applied)
    assert np.max(np.abs(acc - ours[["ax_m_s2", "ay_m_s2", "az_m_s2"]].to_numpy())) < EXACT
    assert np.max(np.abs(np.radians(gyr) - ours[["gx_rad_s", "gy_rad_s", "gz_rad_s"]].to_numpy())) < EXACT
    # read back by optcal: the same calibration (the g is stated in the comment)
    back = calibration_files.load(exported)
    assert back.gravity_reason == "stated in the file's comment"
    probe = np.array([[33000.0, 33500.0, 36000.0], [29000.0, 33300.0, 32300.0]])
    original = calibration_files.load(cal)
    assert np.max(np.abs(back.correct(probe) - original.correct(probe))) < 1e-12


# ----------------------------------------------------------------------------------- imu_tk
def test_imutk_calib_checked_on_its_recording_gives_imutk_residual(shared_data, imutk_pair, capsys):
    from optcal.data import load

    acc_file, ref = imutk_pair
    data = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    code, out, _ = run_args(capsys, "check", str(acc_file), str(data), "--peer-gravity", str(ref["g"]), "--json")
    assert code == 0, out
    result = json.loads(out)
    assert result["calibration"]["peer"]["tool"] == "imu_tk"
    assert "test_imu_gyro.calib found next to it" in result["calibration"]["peer"]["read_as"]
    # imu_tk's own equation on the same poses (calibration.h, unbiasNormalize: X' = T K (X - B); the residual of
    # src/calibration.cpp, MultiPosAccResidual: g_mag - |X'|), from the numbers as the .calib file holds them
    T, K, B = parse_imutk(acc_file.read_text())
    poses = load(data)
    calibrated = (poses.acc - B) @ (T @ K).T
    imutk_rms = float(np.sqrt(np.mean((np.linalg.norm(calibrated, axis=1) / ref["g"] - 1.0) ** 2)))
    assert result["rms_after_g"] == pytest.approx(imutk_rms, rel=1e-12)
    assert result["n_poses"] == 38
    assert abs(result["rms_after_g"] * 1e3 - ref["rms_mg"]) <= 0.0005  # imu_tk's figure, printed to 3 decimals
    # next to optcal's own fit of the same poses
    comparison = result["peer_comparison"]
    assert comparison["peer"] == "imu_tk multi-position"
    assert comparison["own_in_sample"]["rms_g"] <= imutk_rms  # the maximum-likelihood fit of these poses
    assert comparison["own_heldout"]["rms_g"] > comparison["own_in_sample"]["rms_g"]
    assert set(comparison["peer_rms_g_with_own"]) == {"bias", "scale", "axis angles"}
    # the gyro pair is checked too (the gravity predicted across the moves)
    assert result["gravity_prediction"]["n_moves"] > 30


def test_imutk_pair_found_from_either_file_and_refused_when_broken(imutk_pair, tmp_path):
    acc_file, _ = imutk_pair
    from_gyro = calibration_files.load(acc_file.with_name("test_imu_gyro.calib"))
    from_acc = calibration_files.load(acc_file)
    assert from_gyro.has_gyro and np.array_equal(from_gyro.W, from_acc.W)
    assert "accelerometer's test_imu_acc.calib found next to it" in from_gyro.read_as
    alone = tmp_path / "acc.calib"
    alone.write_text(acc_file.read_text())
    assert not calibration_files.load(alone).has_gyro  # no gyro.calib next to it: the accelerometer only
    assert calibration_files.load(alone, gyro=acc_file.with_name("test_imu_gyro.calib")).has_gyro
    broken = tmp_path / "x.calib"
    broken.write_text("1 2 3\n")
    assert parse_imutk(broken.read_text()) is None
    with pytest.raises(Exception, match="not a JSON calibration file"):
        calibration_files.load(broken)


def test_check_text_and_html_show_the_peer_next_to_optcal(shared_data, imutk_pair, tmp_path, capsys):
    acc_file, ref = imutk_pair
    data = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    report = tmp_path / "check.html"
    code, out, _ = run_args(capsys, "check", str(acc_file), str(data), "--peer-gravity", str(ref["g"]), "--report", str(report))
    assert code == 0
    assert "imu_tk multi-position next to optcal's own calibration on DATA's 38 poses" in out
    assert "what imu_tk multi-position misses" in out and "what optcal's own misses" in out
    assert "imu_tk multi-position next to optcal" in report.read_text()


def test_diagnose_with_a_peer_baseline(shared_data, imutk_pair, tmp_path, capsys):
    acc_file, ref = imutk_pair
    data = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    args = ["diagnose", str(data), "--baseline", str(acc_file), "--peer-gravity", str(ref["g"]), "--simulations", "20",
            "--effects", "none", "--quiet"]
    code, out, _ = run_args(capsys, *args, "--json")
    assert code == 0, out
    result = json.loads(out)
    assert result["baseline"]["calibration"] == "the given imu_tk multi-position calibration"
    peer = result["peer_comparison"]
    assert peer["peer"] == "imu_tk multi-position" and peer["own_heldout_folds"] == 10
    assert peer["peer_after"]["rms_g"] == pytest.approx(result["baseline"]["given_rms_g"], rel=1e-6)
    report = tmp_path / "diagnose.html"
    code, out, _ = run_args(capsys, *args, "--report", str(report))
    assert code == 0 and "The given calibration next to optcal's" in out
    assert "imu_tk multi-position next to optcal" in report.read_text()


def test_plan_prior_from_a_peer(imucal_session, tmp_path, capsys):
    _, info, _ = imucal_session
    cal_file = tmp_path / "ferraris.json"
    info.to_json_file(cal_file)
    code, out, _ = run_args(capsys, "plan", "--poses", "9", "--prior", str(cal_file), "--grid", "300")
    assert code == 0, out
    assert "imucal Ferraris calibration" in out and "planned for through its lumped part" in out


def test_peer_calibration_file_round_trip(imucal_session, tmp_path):
    _, info, _ = imucal_session
    cal = calibration_files.load(json.loads(info.to_json()))
    path = tmp_path / "peer.json"
    cal.save(path)
    again = calibration_files.load(path)
    assert again == cal and again.describe() == cal.describe()


def test_old_imucal_file_refused_in_one_line(imucal_session, tmp_path, capsys):
    _, info, _ = imucal_session
    d = json.loads(info.to_json())
    d.pop("_format_version")
    path = tmp_path / "old.json"
    path.write_text(json.dumps(d))
    code, out, err = run_args(capsys, "check", str(path), str(path))
    assert code == 2 and "imucal.legacy" in err and "Traceback" not in err
