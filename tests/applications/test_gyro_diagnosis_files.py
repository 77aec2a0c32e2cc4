"""The gyroscope's diagnosis end to end on planted FILES (issue 39): each effect written into a copy of the real
recording's file, and the command (``optcal diagnose FILE --imu --json``) reads, segments, calibrates and diagnoses it
as a user's file, the findings read from its JSON -- what the held-out checks do.  ``test_gyro_diagnosis_sizes.py``
plants into the moves rebuilt on the unplanted recording's rests (no second read or segmentation); here a plant that
moves the rests' means (a temperature bias, a g-sensitivity) also meets the rest model and the segmentation.

Sizes follow the issue's rule, measured as in ``test_gyro_diagnosis_sizes.py`` (the paper's model's χ² over the
moves rises by 4-5 of its SDs; a time offset: the shift over its inside-move standard error); the accelerometer's
candidates are left out (``--effects none``) and the band is not simulated (``--simulations 0``): what these cases
test is the gyro's part of the pipeline (about 5 s CPU on mikoff's imu0, 12 s on the Xsens log).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from helpers.common import SHARED

MIKOFF = SHARED / "data" / "mikoff-mpu9150" / "imu0.log"
XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
MIKOFF_COLUMNS = ["ax", "ay", "az", "gx", "gy", "gz"]


def warming(t: np.ndarray, rise_c: float = 10.0) -> np.ndarray:
    """A board's temperature after power-on (°C): 25 °C rising by ``rise_c`` with a time constant of a third of the
    session (self-heating; the bias changes fastest in the first moves)."""
    span = float(t[-1] - t[0])
    return 25.0 + rise_c * (1.0 - np.exp(-(t - t[0]) / (span / 3.0)))


def run_diagnose(path: Path, *extra: str, capsys: pytest.CaptureFixture[str]) -> dict:
    """``optcal diagnose PATH --imu --json`` with the gyro's part only; its JSON."""
    from optcal.cli.main import main

    code = main(["diagnose", str(path), "--imu", "--json", "--effects", "none", "--simulations", "0", *extra])
    assert code in (0, None)
    return json.loads(capsys.readouterr().out)


def gyro_findings(result: dict) -> dict[tuple[str, str], float]:
    """(effect, axis) → estimate in SI of each gyroscope finding (``-`` and ``dt_s`` for a time offset)."""
    out = {}
    for f in result["findings"]:
        if f["sensor"] == "gyroscope":
            for axis, value in f["estimate"].items():
                out[(f["effect"], "-" if axis == "dt_s" else axis)] = value
    return out


@pytest.fixture(scope="module")
def mikoff_raw() -> pd.DataFrame:
    if not MIKOFF.exists():
        pytest.skip("../shared/data/mikoff-mpu9150 is not present")
    return pd.read_csv(MIKOFF, sep=r"\s+", header=None, names=MIKOFF_COLUMNS)


def test_a_warming_bias_written_into_imu0s_file_is_named(mikoff_raw, tmp_path, capsys):
    """mikoff's imu0 (MPU-9150, 100 Hz, gyro in rad/s, no temperature column) with a temperature column added (a
    10 °C warming after power-on) and its x bias following it by 0.76 mrad/s per °C: 4.2 SDs of the moves' rise
    (measured with the sizes test's rule), named on x within 40 %, beside the log's own time offset (about 15 ms late)
    and nothing else; the same 22 rests.  Before the held-out moves were compared by their angles rather than the
    angles' squares, it was missed (the warming improves the first two moves most: t 1.58 on squares, 2.01 on angles
    against 1.72), though its likelihood ratio was 197."""
    c = 7.6e-4  # rad/s per °C (the gyro's scale is 1 within 2 %: a plant in rad/s is one in the calibrated rate)
    raw = mikoff_raw.copy()
    t = np.arange(len(raw)) / 100.0
    raw["temp"] = warming(t)
    raw["gx"] += c * (raw["temp"] - raw["temp"].mean())
    path = tmp_path / "imu0_warm.csv"
    raw.to_csv(path, index=False, float_format="%.5f")  # the log's own resolution
    result = run_diagnose(path, "--rate", "100", capsys=capsys)
    assert result["n_poses"] == 22  # the plant moves the rests' means, not the rests
    found = gyro_findings(result)
    assert set(found) == {("gyro_temperature_bias", "x"), ("time_offset", "-")}, result["gyroscope"]["steps"]
    assert found[("gyro_temperature_bias", "x")] == pytest.approx(c, rel=0.4)
    assert 0.010 < found[("time_offset", "-")] < 0.020
    assert result["gyroscope"]["gain"] > 1.2
    # the time offset says what it measures: the streams' offset as the file holds them, its own included
    offset = next(f for f in result["findings"] if f["effect"] == "time_offset")
    assert "as the file holds them" in offset["measures"] and 0 < offset["stderr"]["dt_s"] < 0.005
    assert result["gyroscope"]["time_offset"]["measures"] == offset["measures"]


def test_an_offset_not_named_is_printed_with_what_it_measures():
    """A shift written into a file adds to the one the file had: 3.5 ms late on the Xsens log (its gyro 2.3 ms
    early) leaves about +1.4 ms between the streams, below the family-wise t; the report prints the measured offset
    (a user who shifted a stream reads the total), not nothing."""
    from optcal.applications.diagnosis.gyro_diagnosis import GyroDiagnosis
    from optcal.applications.diagnosis.gyro_problem import GyroParams

    offset = {"tested": True, "dt_s": 1.42e-3, "se_s": 0.53e-3, "t": 2.7, "critical_t": 3.08, "heldout_ratio": 1.0,
              "significant": False}
    diag = GyroDiagnosis([], [], np.array([0.2] * 9), np.array([1.0] * 9), np.array([0.2] * 9), 0.3, 0.3, offset,
                         ["time_offset"], {}, GyroParams(np.eye(3), np.zeros(3), (), ()), [], {})
    text = "\n".join(diag.report_lines())
    assert "time offset between the streams: +1.42 ± 0.53 ms (gyro late when positive; t 2.7 against 3.1" in text
    assert "not named" in text
    offset["significant"] = True
    assert "time offset between the streams" not in "\n".join(diag.report_lines())


def test_a_shift_written_into_the_xsens_file_is_named_with_its_own(tmp_path, capsys):
    """imu_tk's Xsens log (gyro in counts, 100 Hz stamps) with its gyro samples written 2.5 ms earlier (each column
    interpolated at t + 2.5 ms and rounded to counts): 4.5 standard errors of the inside-move estimate.  The same 38
    rests; the log's own g-sensitivity (all three axes) still named; the offset between the streams named as the
    log's own (its gyro about 2 ms early) plus the shift."""
    if not XSENS.exists():
        pytest.skip("../shared/data/imutk-xsens is not present")
    raw = pd.read_csv(XSENS)
    t = raw["t_s"].to_numpy(float)
    shift = -2.5e-3  # the gyro's samples early: each stamp holds the rate 2.5 ms later
    for c in ("gyro_x_counts", "gyro_y_counts", "gyro_z_counts"):
        raw[c] = np.round(np.interp(t - shift, t, raw[c].to_numpy(float))).astype(int)
    path = tmp_path / "xsens_early.csv"
    raw.to_csv(path, index=False, float_format="%.6f")
    result = run_diagnose(path, capsys=capsys)
    assert result["n_poses"] == 38 and len(result["gyroscope"]["moves"]) == 37
    found = gyro_findings(result)
    assert {a for e, a in found if e == "g_sensitivity"} == {"x", "y", "z"}
    assert {e for e, _ in found} == {"g_sensitivity", "time_offset"}
    # its own offset is −2.0 to −2.3 ms (test_gyro_diagnosis_sizes: within −3 and −1.4 ms); with the shift, 40 % of it
    assert -3e-3 + 1.4 * shift < found[("time_offset", "-")] < -1.4e-3 + 0.6 * shift


def test_the_held_out_rule_is_stated_and_overridden(mikoff_raw, capsys):
    """Every gyro finding needs a paired gain on the held-out moves beyond its standard error; the report states the
    gain, its standard error and t.  imu0's own offset (about 14 ms late) gains 0.044 ± 0.013° per held-out move (t
    3.3, named at the default 1 standard error); asked for 4 (``--gyro-heldout-se 4``) it is measured and printed but
    not named.  The option needs --imu: one error line, exit 2."""
    from optcal.cli.main import main

    code = main(["diagnose", str(MIKOFF), "--rate", "100", "--imu", "--effects", "none", "--simulations", "0",
                 "--gyro-heldout-se", "4"])
    text = capsys.readouterr().out
    assert code in (0, None)
    line = next(s for s in text.splitlines() if "time offset between the streams" in s)
    assert "held-out moves' rms inside-move misfit +0.04" in line and "against 4.00): not named" in line, line
    t = float(line.split("better per move, t ")[1].split()[0])
    assert 1.0 < t < 4.0  # named at the default, not at 4
    code = main(["diagnose", str(MIKOFF), "--rate", "100", "--gyro-heldout-se", "1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: --gyro-heldout-se applies with --imu"), err


def test_a_datasheet_g_sensitivity_is_confirmed_by_the_moves_response(mikoff_raw, tmp_path, capsys):
    """0.1 °/s per g (a MEMS gyro's datasheet g-sensitivity) written into imu0's file: z's rate error follows the
    specific force along x.  The rests measure it; the moves see it only integrated over each move, and the paired
    gain of their angles, second order in so small a change, is noise (t about −0.4 against 1.72): missed before.
    Their response to it, linear in their noise, is about 0.6 ± 0.14 (t about 4): named, its row's x term within
    20 %, beside the log's own time offset.  With ``--gyro-g-evidence angles`` (the rule before) it is measured, not
    named; the flag without ``--imu`` is one error line, exit 2.  (A bias that follows the pose in the rests alone
    responds about 0.2 ± 0.3 and stays unnamed: ``test_gyro_diagnosis_sizes.py``.)"""
    from optcal.cli.main import main

    k = np.radians(0.1) / 9.80665  # rad/s per m/s²: 0.1 °/s per g
    raw = mikoff_raw.copy()
    raw["gz"] += k * raw["ax"]  # imu0's accelerometer in m/s², its gyro in rad/s (scales 1 within 2 %)
    path = tmp_path / "imu0_gsens.csv"
    raw.to_csv(path, index=False, float_format="%.5f")
    result = run_diagnose(path, "--rate", "100", capsys=capsys)
    assert result["n_poses"] == 22
    assert set(gyro_findings(result)) == {("g_sensitivity", "z"), ("time_offset", "-")}, result["gyroscope"]["steps"]
    finding = next(f for f in result["findings"] if f["effect"] == "g_sensitivity")
    assert finding["row_rad_s_per_m_s2"]["z"][0] == pytest.approx(k, rel=0.2)
    ev = finding["evidence"]
    assert ev["heldout_moves_t"] <= ev["heldout_moves_critical_t"] < ev["moves_response_t"]
    moves_only = run_diagnose(path, "--rate", "100", "--gyro-g-evidence", "angles", capsys=capsys)
    assert set(gyro_findings(moves_only)) == {("time_offset", "-")}
    tried = next(s for s in moves_only["gyroscope"]["steps"] if s["term"] == "g_sensitivity(z)")
    assert not tried["accepted"] and tried["moves_response_t"] == pytest.approx(ev["moves_response_t"])
    code = main(["diagnose", str(path), "--rate", "100", "--gyro-g-evidence", "angles"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: --gyro-g-evidence applies with --imu"), err
