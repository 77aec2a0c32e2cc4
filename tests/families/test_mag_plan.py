"""``optcal plan --sensor mag``: the field directions a magnetometer session has not reached (issue 38)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from optcal.families.mag.coverage_plan import plan_coverage
from optcal.families.mag.fit import COVERAGE_CAP_DEG, COVERAGE_DIRECTIONS, coverage

from helpers.cli_run import run
from helpers.common import SHARED

CKEXPLORER = SHARED / "data" / "ckexplorer-holds" / "acc_mag_log.csv"


def test_without_a_recording_the_plan_is_the_26_directions_faces_first() -> None:
    planned = plan_coverage(None)
    assert len(planned) == 26 and len({p.name for p in planned}) == 26
    assert all(np.count_nonzero(np.round(p.vector, 6)) == 1 for p in planned[:6])
    assert all(np.count_nonzero(np.round(p.vector, 6)) == 3 for p in planned[-8:])


def test_a_hemisphere_plans_the_other_one_the_largest_gap_first() -> None:
    rng = np.random.default_rng(1)
    u = rng.standard_normal((20_000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    upper = u[u[:, 2] > 0.1]
    planned = plan_coverage(coverage(upper))
    assert planned[0].name == "-z" and planned[0].gap_deg > 90.0
    assert all(p.vector[2] < 0 for p in planned)
    gaps = [p.gap_deg for p in planned]
    assert all(g > COVERAGE_CAP_DEG for g in gaps)
    # the samples and the planned directions together leave no direction uncovered
    assert not coverage(np.vstack([upper, np.array([p.vector for p in planned])])).missing
    assert plan_coverage(coverage(u)) == []


def test_plan_sensor_mag_on_a_recording_missing_its_lower_half(tmp_path, capsys) -> None:
    if not CKEXPLORER.exists():
        pytest.skip("ckexplorer-holds absent")
    frame = pd.read_csv(CKEXPLORER)
    from optcal.families.mag.calibration import calibrate_mag
    from optcal.families.mag.samples import read_mag

    cal = calibrate_mag(read_mag(str(CKEXPLORER))).calibration
    unit = cal.correct(frame[["mx", "my", "mz"]].to_numpy(float))
    half = frame[unit[:, 2] > 0.2]
    half.to_csv(tmp_path / "half.csv", index=False)
    code, out, err = run(["plan", "--sensor", "mag", "--next", tmp_path / "half.csv", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["sensor"] == "magnetometer" and d["missing"] and d["plan"]
    assert set(p["direction"] for p in d["plan"]) <= set(d["missing"])
    assert all(np.asarray(p["vector"])[2] < 0.5 for p in d["plan"])
    code, out, _ = run(["plan", "--sensor", "mag", "--next", CKEXPLORER], capsys)
    assert code == 0 and "nothing to add" in out


def test_plan_sensor_mag_refuses_the_accelerometers_options(capsys) -> None:
    for argv, expected in ((["plan", "--sensor", "mag", "--poses", "6", "--turntable"], "--turntable"),
                           (["plan", "--sensor", "mag", "--poses", "30"], "K from 1 to 26")):
        code, _, err = run(argv, capsys)
        assert code == 2 and expected in err and err.count("\n") == 1, err
    code, out, _ = run(["plan", "--sensor", "mag", "--poses", "6", "--json"], capsys)
    assert code == 0 and [p["direction"] for p in json.loads(out)["plan"]] == [p.name for p in plan_coverage(None)[:6]]
    assert np.allclose(np.abs([p["vector"] for p in json.loads(out)["plan"]]).sum(axis=1), 1.0)
    assert COVERAGE_DIRECTIONS.shape == (26, 3)
