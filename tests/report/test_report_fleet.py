"""The fleet report (``optcal fleet --report``): the verdict on a synthetic fleet with a planted odd unit, in Chromium."""

from __future__ import annotations

import re
import sys
from html import unescape
from pathlib import Path

import numpy as np
import pytest

from optcal.cli.main import main
from optcal.applications.fleet.inputs import UnitInput
from optcal.applications.fleet.population import flag_units, population_stats
from optcal.applications.fleet.results import FleetResult
from optcal.applications.fleet.synthetic import unit_model, write_fleet
from optcal.applications.fleet.unit import UnitOutcome, fit_unit
from optcal.applications.quality.verdict import judge_fleet
from optcal.families.simulate.poses import simulate_poses, uniform_directions

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from helpers.html_report import assert_self_contained, reasons_of, verdict_of  # noqa: E402
from helpers.html_report import BROWSER, open_in_browser  # noqa: E402


@pytest.fixture(scope="module")
def fleet_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[object, int, str, str]:
    """One ``optcal fleet --report`` run (one local worker) on 30 units: one with an 8 % x scale error, one with the
    six faces only (calibrated with the prior), one unreadable file."""
    folder = tmp_path_factory.mktemp("fleet")
    truth = write_fleet(folder / "units", 30, seed=3, n_poses=30, unreadable_units=1)
    page = folder / "fleet.html"
    code = main(["fleet", str(folder / "units"), "-o", str(folder / "results.parquet"), "--workers", "1",
                 "--no-progress", "--tolerance", "5", "--report", str(page)])
    return truth, code, page.read_text(encoding="utf-8"), str(page)


def test_fleet_report_names_the_odd_failed_and_weak_units(fleet_report) -> None:
    truth, code, html, _ = fleet_report
    assert code == 0
    assert_self_contained(html)
    assert verdict_of(html) == "usable with care"
    reasons = unescape(reasons_of(html))
    odd, six, unreadable = truth.units("scale_error")[0], truth.units("six_faces")[0], truth.units("unreadable")[0]
    # the planted odd unit, in engineers' words: its x scale factor (8 % low in T_xx, so ≈ 8 % high in S_x) above the fleet
    match = re.search(rf"{odd}: scale factor x (\d\.\d+) g/g is ([\d.]+) robust SD above the fleet's median (\d\.\d+)",
                      reasons)
    assert match, reasons
    assert float(match.group(1)) / float(match.group(3)) == pytest.approx(1 / (1 - 0.08), abs=0.02)
    assert float(match.group(2)) > 5
    assert sum(u in reasons for u in truth.units("normal")) == 0  # no clean unit is named as odd or weak
    assert f"{unreadable} (failed: " in reasons
    assert f"prior: {six}" in reasons
    assert "Every calibrated unit's held-out rms error" in reasons  # 2 mg pose noise: within 5 mg
    # the population table in engineers' units, one figure per quantity, the prior, the command and versions
    assert re.search(r"<td>scale factor x</td><td>S_x</td><td>(0\.99|1\.00)\d*</td>", html)
    assert "<td>non-orthogonality ρ (y axis towards x)</td>" in html and "<td>bias z in g</td>" in html
    assert html.count("<svg") == 10
    assert re.search(rf"<td>{six}</td><td>24</td><td>T_yx 1\.00, T_zx 1\.00, T_zy 1\.00</td>", html)
    assert "does not bias them" in html
    assert "optcal fleet" in html and "dask.distributed LocalCluster, 1 worker" in html and "<th scope=\"row\">numpy</th>" in html


@pytest.mark.skipif(BROWSER is None, reason="no headless Chromium installed (apt-get install chromium)")
def test_fleet_report_renders_in_chromium(fleet_report, tmp_path: Path) -> None:
    import os

    shots = Path(os.environ.get("OPTCAL_SCREENSHOT_DIR", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    console, requested = open_in_browser(Path(fleet_report[3]), shots / "report_fleet.png", tmp_path / "profile")
    assert console == [] and requested == []


def small_fleet(n: int, odd_scale_error: float = 0.0) -> FleetResult:
    """``n`` units calibrated in this process (no Dask), the last with an x scale error."""
    outcomes: list[UnitOutcome] = []
    for k in range(n):
        rng = np.random.default_rng([5, k])
        model = unit_model(rng, odd_scale_error if k == n - 1 else 0.0)
        poses = simulate_poses(model, uniform_directions(24, rng), 5e-4, rng=rng)
        outcomes.append(fit_unit(UnitInput(f"u{k}", f"u{k}.csv"), poses))
    stats = population_stats(outcomes)
    assert stats is not None
    flag_units(outcomes, stats)
    return FleetResult(outcomes, stats, None, "not asked for", "in-process", 0.0)


def test_fleet_verdict_rules() -> None:
    clean = small_fleet(12)
    verdict = judge_fleet(clean)
    assert verdict.level == "good", verdict.summary()
    assert "12 units: 12 calibrated by their own data" in verdict.reasons[0].text
    odd = small_fleet(12, odd_scale_error=0.15)
    verdict = judge_fleet(odd)
    assert verdict.level == "usable with care" and "u11" in verdict.summary()
    assert judge_fleet(clean, tolerance_mg=0.1).level == "usable with care"  # 0.5 mg pose noise: held-out above 0.1 mg
    failed = [UnitOutcome(f"f{k}", f"f{k}.csv", "failed", "not a text file") for k in range(13)]
    mostly_failed = FleetResult(clean.outcomes + failed, clean.stats, None, "not asked for", "in-process", 0.0)
    verdict = judge_fleet(mostly_failed)
    assert verdict.level == "not usable" and "fewer than half" in verdict.summary()
