"""Ferraris' calibration (optcal.families.ferraris) against imucal's own, on imucal's example sessions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from optcal.data import load_with_segmentation
from optcal.data.sections import read_section_list
from optcal.errors import InputError
from optcal.families.ferraris import ferraris_fit, find_regions, regions_from_labels, regions_from_section_list
from optcal.families.ferraris.method import FerrarisInputs, ferraris_equations
from tests.helpers.cli_run import run_args

#: imucal's ``grav`` (m/s² per g): its K_a and K_ga are per m/s², optcal's per g.
IMUCAL_GRAV = 9.81
#: imucal's rms of |a|−1 on the six faces of its example session (issue 28), mg.
IMUCAL_FACE_RMS_MG = 0.040


def _session(shared_data: Path) -> Path:
    d = shared_data / "imucal-ferraris"
    if not d.is_dir():
        pytest.skip("imucal-ferraris data not present")
    return d


def test_equations_recover_a_known_sensor() -> None:
    """Six exact faces and three exact turns of a sensor with known M, b, gyro: the equations give them back."""
    rng = np.random.default_rng(4)
    R_a = np.eye(3) + 0.01 * rng.standard_normal((3, 3))
    R_a /= np.linalg.norm(R_a, axis=1, keepdims=True)
    K_a = np.diag([980.0, 1010.0, 1003.0])
    b_a = np.array([12.0, -7.0, 3.0])
    M = K_a @ R_a  # raw per g
    R_g = np.eye(3) + 0.01 * rng.standard_normal((3, 3))
    R_g /= np.linalg.norm(R_g, axis=1, keepdims=True)
    K_g = np.diag([1.02, 0.98, 1.0])
    b_g = np.array([0.3, -0.2, 0.1])
    K_ga = 0.001 * rng.standard_normal((3, 3))
    acc_p, acc_n = M + b_a[:, None], -M + b_a[:, None]
    gyr_p, gyr_n = b_g[:, None] + K_ga, b_g[:, None] - K_ga
    # each turn: 360° about axis i in 10 s, gravity along that axis (+1 g) throughout
    T = 10.0
    turn_g = np.column_stack([K_g @ R_g @ (-360.0 * np.eye(3)[i]) + (b_g + K_ga[:, i]) * T for i in range(3)])
    turn_a = np.column_stack([(M[:, i] + b_a) * T for i in range(3)])
    x = FerrarisInputs(acc_p, acc_n, gyr_p, gyr_n, np.full(6, 100.0), turn_g, turn_a, np.full(3, T))
    m = ferraris_equations(x, np.full(3, -360.0))
    np.testing.assert_allclose(m.b_a, b_a, atol=1e-9)
    np.testing.assert_allclose(m.K_a, K_a, rtol=1e-12)
    np.testing.assert_allclose(m.R_a, R_a, atol=1e-12)
    np.testing.assert_allclose(m.b_g, b_g, atol=1e-12)
    np.testing.assert_allclose(m.K_ga, K_ga, atol=1e-12)
    np.testing.assert_allclose(m.K_g, K_g, rtol=1e-12)
    np.testing.assert_allclose(m.R_g, R_g, atol=1e-12)


def test_section_list_formats(tmp_path: Path) -> None:
    """imucal's JSON (one object per section), pandas' column-wise JSON and its CSV all read the same."""
    rows = {"x_p": (540, 1271), "z_rot": (9205, 9512)}
    a = tmp_path / "a.json"
    a.write_text(json.dumps({k: {"start": s, "end": e} for k, (s, e) in rows.items()}))
    b = tmp_path / "b.json"
    b.write_text(json.dumps({"start": {k: s for k, (s, _) in rows.items()}, "end": {k: e for k, (_, e) in rows.items()}}))
    c = tmp_path / "c.csv"
    c.write_text(",start,end\n" + "".join(f"{k},{s},{e}\n" for k, (s, e) in rows.items()))
    for p in (a, b, c):
        assert read_section_list(p) == rows
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"x_p": {"start": 10, "end": 5}}))
    with pytest.raises(InputError, match="ends"):
        read_section_list(bad)
    bad.write_text(json.dumps({"w_p": {"start": 1, "end": 5}}))
    with pytest.raises(InputError, match="unknown section"):
        read_section_list(bad)


def _imucal_reference(d: Path):  # type: ignore[no-untyped-def]
    imucal = pytest.importorskip("imucal")
    import pandas as pd

    data = pd.read_csv(d / "example_ferraris_session.csv", header=0, index_col=0)
    section_list = pd.read_json(d / "example_ferraris_session_list.json").T  # imucal's examples/basic_ferraris.py
    regions = imucal.ferraris_regions_from_section_list(data, section_list)
    return imucal.FerrarisCalibration().compute(regions, 102.4, "m/s^2", "deg/s"), regions


def _assert_same_as_imucal(m, ref, grav: float) -> None:  # type: ignore[no-untyped-def]
    np.testing.assert_allclose(m.b_a, ref.b_a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(m.K_a, ref.K_a * grav, rtol=1e-9)
    np.testing.assert_allclose(m.R_a, ref.R_a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(m.b_g, ref.b_g, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(m.K_ga, ref.K_ga * grav, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(m.K_g, ref.K_g, rtol=1e-9)
    np.testing.assert_allclose(m.R_g, ref.R_g, rtol=1e-9, atol=1e-12)


def test_same_numbers_as_imucal_on_its_sections(shared_data: Path) -> None:
    """On imucal's own section list, optcal's Ferraris is imucal's FerrarisCalibration (units aside)."""
    d = _session(shared_data)
    ref, regions = _imucal_reference(d)
    loaded = load_with_segmentation(d / "example_ferraris_session.csv", rate=102.4)
    seg = loaded.segmentation
    fit = ferraris_fit(seg, regions_from_section_list(seg.recording, str(d / "example_ferraris_session_list.json"), seg))
    _assert_same_as_imucal(fit.matrices, ref, IMUCAL_GRAV)
    # the calibrated accelerometer and gyroscope, imucal's calibrate() against optcal's calibration
    acc, gyr = regions.acc_x_rot, regions.gyr_x_rot
    acc_ref, gyr_ref = ref.calibrate(acc, gyr, "m/s^2", "deg/s")
    cal = fit.calibration(seg.recording)
    np.testing.assert_allclose(cal.correct(acc) * IMUCAL_GRAV, acc_ref, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.degrees(cal.correct_gyro(gyr, acc)), gyr_ref, rtol=1e-9, atol=1e-9)


def test_found_sections_match_imucal_figures(shared_data: Path) -> None:
    """Faces and turns found by optcal: |a|−1 on the faces as imucal's, held-out rests, turns read as 360°."""
    d = _session(shared_data)
    loaded = load_with_segmentation(d / "example_ferraris_session.csv", rate=102.4)
    seg = loaded.segmentation
    fit = ferraris_fit(seg, find_regions(seg))
    assert fit.face_rms_mg <= 1.5 * IMUCAL_FACE_RMS_MG
    assert len(fit.held_out) == 6  # 12 rests (the first, 13 s by hand, one pose), 6 faces
    assert fit.held_out_rms_mg is not None and fit.held_out_rms_mg < 1.0
    for turn in fit.turns:
        assert abs(abs(turn.about_axis_deg) - 360.0) < 0.5
        assert turn.net_rotation_deg < 0.5
    se = fit.accelerometer.stderr
    assert all(np.isfinite(v) and v > 0 for v in se.values())
    assert all(np.isfinite(v) and v > 0 for v in fit.gyro_stderr.values())


def test_annotated_session_by_its_part_column(shared_data: Path) -> None:
    """imucal's annotated session (counts, a part column, a sample counter stepping back) reads and gives imucal's numbers."""
    d = _session(shared_data)
    imucal = pytest.importorskip("imucal")
    import pandas as pd

    frame = pd.read_csv(d / "annotated_session.csv", header=0, index_col=[0, 1])  # imucal's custom_calibration_info.py
    # its turns read positive (counter-clockwise): imucal's docstring says to set expected_angle to +360 for them,
    # optcal takes the sign from the reading
    ref = imucal.FerrarisCalibration(expected_angle=360).compute(imucal.ferraris_regions_from_df(frame), 204.8,
                                                                 "a.u.", "a.u.")
    loaded = load_with_segmentation(d / "annotated_session.csv", rate=204.8)
    seg = loaded.segmentation
    assert "sample counter" in loaded.decisions.time_base.reason
    fit = ferraris_fit(seg, regions_from_labels(seg.recording, "part", seg))
    _assert_same_as_imucal(fit.matrices, ref, IMUCAL_GRAV)


def test_cli_ferraris(shared_data: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    d = _session(shared_data)
    session = d / "example_ferraris_session.csv"
    code, out, err = run_args(capsys, "calibrate", str(session), "--rate", "102.4", "--method", "ferraris",
                              "-o", str(tmp_path / "cal.json"))
    assert code == 0, err
    for words in ("[[Ferraris sections: found]]", "x_rot: rows", "held out", "+/-", "closes within"):
        assert words in out
    assert "+/- nan" not in out
    code, out, err = run_args(capsys, "calibrate", str(session), "--rate", "102.4", "--method", "ferraris", "--json",
                              "--sections", str(d / "example_ferraris_session_list.json"))
    assert code == 0, err
    summary = json.loads(out)
    assert summary["ferraris"]["sections_source"] == "section list"
    assert summary["ferraris"]["face_rms_norm_residual_mg"] == pytest.approx(IMUCAL_FACE_RMS_MG, abs=0.001)
    code, out, err = run_args(capsys, "calibrate", str(session), "--rate", "102.4", "--sections",
                              str(d / "example_ferraris_session_list.json"))
    assert code == 2 and err.startswith("error: --sections")


def test_default_names_the_known_orientation_methods(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Six faces refused by the self-calibration: the refusal says which known-orientation methods apply."""
    d = _session(shared_data)
    code, _, err = run_args(capsys, "calibrate", str(d / "annotated_session.csv"), "--rate", "204.8")
    assert code == 2
    assert "--method ferraris" in err and "--method nominal" in err and "--method sixpos" in err
