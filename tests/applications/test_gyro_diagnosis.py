"""The gyroscope's diagnosis (``optcal diagnose --imu``, issue 39) from the command line: the JSON contract, ``-o``
and ``check`` with the saved calibration.  The recordings' own effects and the planted ones, sized by the issue's
rule, are in ``test_gyro_diagnosis_sizes.py`` (one read of each recording for all its cases).
"""

from __future__ import annotations

import json

import pytest

from helpers.common import SHARED

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"


def test_diagnose_imu_from_the_command_line(tmp_path, capsys):
    from optcal.cli.main import main

    if not XSENS.exists():
        pytest.skip("../shared/data/imutk-xsens is not present")
    out = tmp_path / "imu.json"
    code = main(["diagnose", str(XSENS), "--imu", "--simulations", "0", "--json", "-o", str(out)])
    result = json.loads(capsys.readouterr().out)
    assert code in (0, None)
    gyro = [f for f in result["findings"] if f["sensor"] == "gyroscope"]
    assert gyro and all(set(f) >= {"sensor", "effect", "axes", "estimate"} for f in gyro)
    assert all(f["sensor"] == "accelerometer" for f in result["findings"] if f not in gyro)
    assert result["gain"] == pytest.approx(result["gyroscope"]["gain"]) and result["gain"] > 2.0
    assert len(result["gyroscope"]["moves"]) == 37
    saved = json.loads(out.read_text())
    assert saved["cal_type"] == "imu"
    # the saved calibration's g-sensitivity carries the gravity prediction the diagnosis found
    code = main(["check", str(out), str(XSENS), "--json"])
    check = json.loads(capsys.readouterr().out)
    assert check["gravity_prediction"]["rms_deg_after"] < 0.2
