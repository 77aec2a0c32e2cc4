"""The HTML reports in a real browser: headless Chromium, no console errors, no network requests.

Skips where Debian's ``chromium`` (or ``chromium-browser``, ``google-chrome``) is not installed.
Screenshots go to ``$OPTCAL_SCREENSHOT_DIR`` when set (else the test's temporary directory).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from optcal.cli.main import main

from helpers.html_report import BROWSER, open_in_browser

pytestmark = pytest.mark.skipif(BROWSER is None, reason="no headless Chromium installed (apt-get install chromium)")

@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Reports of calibrate, check, diagnose and segment on a measured-like recording with a hidden drift, and the
    plan of four more poses after it (the fleet's report is rendered in tests/report/test_report_fleet.py)."""
    from optcal.families.simulate.effects import recording_with_effect

    out = tmp_path_factory.mktemp("reports")
    frame, _ = recording_with_effect("bias_drift", "y", n_poses=30, seed=4)
    data = out / "recording.csv"
    frame.to_csv(data, index=False, float_format="%.8g")
    paths = {name: out / f"{name}.html" for name in ("calibrate", "check", "diagnose", "segment", "plan")}
    assert main(["calibrate", str(data), "-o", str(out / "cal.json"), "--report", str(paths["calibrate"])]) == 0
    assert main(["check", str(out / "cal.json"), str(data), "--report", str(paths["check"])]) == 0
    assert main(["diagnose", str(data), "--simulations", "10", "--effects", "bias_drift", "--report", str(paths["diagnose"])]) == 0
    assert main(["segment", str(data), "--report", str(paths["segment"])]) == 0
    assert main(["plan", "--poses", "4", "--given", str(data), "--report", str(paths["plan"])]) == 0
    return paths


@pytest.mark.parametrize("name", ["calibrate", "check", "diagnose", "segment", "plan"])
def test_report_renders_without_errors_or_requests(reports: dict[str, Path], name: str, tmp_path: Path) -> None:
    shots = Path(os.environ.get("OPTCAL_SCREENSHOT_DIR", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    console, requested = open_in_browser(reports[name], shots / f"report_{name}.png", tmp_path / "profile")
    assert console == [], console
    assert requested == [], requested
    assert re.search(r"Verdict: <strong>", reports[name].read_text(encoding="utf-8"))


def test_the_browser_check_catches_requests_and_errors(tmp_path: Path) -> None:
    """The detector itself: a page that logs an error and loads a remote image is caught."""
    page = tmp_path / "bad.html"
    page.write_text('<html><body><p>x</p><img src="https://example.invalid/x.png">'
                    '<script>console.error("boom")</script></body></html>')
    console, requested = open_in_browser(page, tmp_path / "bad.png", tmp_path / "profile")
    assert any("boom" in line for line in console)
    assert requested == ["https://example.invalid/x.png"]
