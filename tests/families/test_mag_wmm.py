"""The magnetometer's field and dip against the World Magnetic Model (issue 38: ``--location``, ``--date``).

The model is pygeomag's (the ``mag`` extra); it is checked here against NOAA's own published WMM2025 test values
(WMM2025_TestValues, NOAA/NCEI 2025: https://www.ncei.noaa.gov/sites/default/files/2025-02/WMM2025testvalues.pdf),
from which the total intensity and inclination are computed in the test.
"""

from __future__ import annotations

import datetime as dt
import json
import sys

import numpy as np
import pytest

from optcal.errors import InputError
from optcal.families.mag.wmm import Location, compare_with_wmm, decimal_year, parse_date, wmm_reference

from helpers.cli_run import run
from helpers.common import SHARED

pytest.importorskip("pygeomag")

CKEXPLORER = SHARED / "data" / "ckexplorer-holds" / "acc_mag_log.csv"

#: NOAA's WMM2025 test values: decimal year, height km, latitude, longitude, X, Y, Z (nT), declination (deg).
NOAA_WMM2025 = [
    (2025.0, 0.0, 80.0, 0.0, 6521.6, 145.9, 54791.5, 1.28),
    (2025.0, 0.0, 0.0, 120.0, 39677.8, -109.6, -10580.2, -0.16),
    (2025.0, 0.0, -80.0, 240.0, 6117.5, 15751.9, -52022.5, 68.78),
    (2025.0, 100.0, 80.0, 0.0, 6216.0, 92.4, 52598.8, 0.85),
]


@pytest.mark.parametrize("year,height_km,lat,lon,x,y,z,declination", NOAA_WMM2025)
def test_the_model_meets_noaas_test_values(year, height_km, lat, lon, x, y, z, declination) -> None:
    ref = wmm_reference(Location.parse(f"{lat},{lon},{height_km * 1000.0}"), dt.date(int(year), 1, 1))
    total = float(np.sqrt(x * x + y * y + z * z))
    inclination = float(np.degrees(np.arctan2(z, np.hypot(x, y))))
    assert ref.total_nT == pytest.approx(total, abs=1.0)
    assert ref.inclination_deg == pytest.approx(inclination, abs=0.01)
    assert ref.declination_deg == pytest.approx(declination, abs=0.01)
    assert "2025" in ref.model and not ref.outside_lifespan


def test_location_and_date_are_read_or_refused_naming_the_flag() -> None:
    assert Location.parse("52.2, 0.12") == Location(52.2, 0.12, 0.0)
    assert Location.parse("-33.9,151.2,40") == Location(-33.9, 151.2, 40.0)
    assert Location.parse("10,270").lon_deg == -90.0
    for bad in ("52.2", "a,b", "95,0", "0,0,1e9", "nan,0"):
        with pytest.raises(InputError, match="--location"):
            Location.parse(bad)
    assert parse_date("2026-11-28") == (dt.date(2026, 11, 28), "--date")
    day, reason = parse_date(None)
    assert day == dt.date.today() and "today" in reason and "--date" in reason
    with pytest.raises(InputError, match="--date"):
        parse_date("28/11/2026")
    assert decimal_year(dt.date(2025, 7, 2)) == pytest.approx(2025.5, abs=0.002)


def test_the_comparison_says_each_difference_in_the_models_uncertainty() -> None:
    ref = wmm_reference(Location(45.0, -75.0), dt.date(2026, 1, 1))
    # a field measured in µT equal to the model's, and a dip 0.5° off with a 0.1° standard error
    same = compare_with_wmm(ref, ref.total_nT / 1000.0, "uT", ref.inclination_deg + 0.5, 0.1)
    assert same["field_difference_nT"] == pytest.approx(0.0, abs=1e-9)
    assert same["dip_difference_deg"] == pytest.approx(0.5)
    assert same["dip_difference_sigmas"] == pytest.approx(0.5 / np.hypot(0.21, 0.1))
    in_gauss = compare_with_wmm(ref, 1.1 * ref.total_nT / 1e5, "gauss")
    assert in_gauss["field_difference_relative"] == pytest.approx(0.1)
    assert "measured_dip_deg" not in in_gauss
    counts = compare_with_wmm(ref, 400.0, "counts", ref.inclination_deg)
    assert "measured_field_nT" not in counts and "measured_dip_deg" in counts


def test_calibrate_with_a_location_reports_the_model_beside_the_fit(capsys, tmp_path) -> None:
    if not CKEXPLORER.exists():
        pytest.skip("ckexplorer-holds absent")
    code, out, err = run(["calibrate", CKEXPLORER, "--sensor", "mag", "--location", "45,-75,100", "--date", "2026-03-01",
                          "--json", "-o", tmp_path / "mag.json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    w = d["wmm"]
    ref = wmm_reference(Location(45.0, -75.0, 100.0), dt.date(2026, 3, 1))
    assert w["field_strength_nT"] == pytest.approx(ref.total_nT) and w["dip_deg"] == pytest.approx(ref.inclination_deg)
    assert w["measured_dip_deg"] == pytest.approx(d["dip_deg"])
    units = d["units"]["input"] if isinstance(d["units"], dict) else d["units"]
    from optcal.families.mag.units import UT_PER_UNIT

    assert w["measured_field_nT"] == pytest.approx(d["field_strength"] * UT_PER_UNIT[units] * 1000.0)
    assert "date: --date" in err
    saved = json.loads((tmp_path / "mag.json").read_text())
    assert saved["wmm"] == w
    from optcal.families.mag.calibration import MagCalibration

    assert MagCalibration.from_dict(saved).info["wmm"] == w
    code, out, _ = run(["calibrate", CKEXPLORER, "--sensor", "mag", "--location", "45,-75"], capsys)
    assert code == 0 and "World Magnetic Model" in out and "dip measured" in out


def test_location_errors_are_one_line_with_exit_2(capsys, monkeypatch) -> None:
    if not CKEXPLORER.exists():
        pytest.skip("ckexplorer-holds absent")
    cases = [
        (["calibrate", CKEXPLORER, "--location", "45,-75"], "apply with --sensor mag"),
        (["calibrate", CKEXPLORER, "--sensor", "mag", "--date", "2026-01-01"], "--date applies with --location"),
        (["calibrate", CKEXPLORER, "--sensor", "mag", "--location", "north"], "--location"),
    ]
    for argv, expected in cases:
        code, _, err = run(argv, capsys)
        assert code == 2 and expected in err and err.count("\n") == 1, err
    monkeypatch.setitem(sys.modules, "pygeomag", None)  # the extra not installed
    code, _, err = run(["calibrate", CKEXPLORER, "--sensor", "mag", "--location", "45,-75"], capsys)
    assert code == 2 and "pip install 'optcal[mag]'" in err and err.count("\n") == 1, err
