"""The plan report (``optcal plan --report``): the poses to follow, the criterion, the standard errors before/after."""

from __future__ import annotations

import json
import re
import sys
from html import unescape
from pathlib import Path

import numpy as np
import pytest

from optcal.cli.main import main
from optcal.core.model import LumpedModel
from optcal.report.plan_report import orientation_rows
from optcal.families.simulate.poses import simulate_poses, six_position, uniform_directions

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from helpers.html_report import assert_self_contained, reasons_of, verdict_of  # noqa: E402

SENSOR = LumpedModel.from_physical([1.02, 0.98, 1.01], 0.003, -0.002, 0.001, [0.02, -0.01, 0.03])


def write_poses(path: Path, directions: np.ndarray, seed: int) -> Path:
    poses = simulate_poses(SENSOR, directions, 1e-3, rng=seed)
    np.savetxt(path, np.column_stack([poses.acc, poses.sigma]), delimiter=",", header="ax,ay,az,sigma", comments="")
    return path


def cells(html: str, first: str) -> list[str]:
    """The cells of the table row whose first cell is ``first``."""
    match = re.search(rf"<tr><td>{re.escape(first)}</td>(.*?)</tr>", html)
    assert match, f"no row {first!r}"
    return [unescape(c) for c in re.findall(r"<td>(.*?)</td>", match.group(1))]


def test_orientation_rows_a_person_can_follow() -> None:
    d = np.array([[np.sin(np.deg2rad(35)), 0.0, np.cos(np.deg2rad(35))], [0.0, -1.0, 0.0]])
    rows = orientation_rows(d)
    assert rows[0][:4] == ["1", "+z", "35", "z up, tilted 35° toward +x"]
    assert rows[1][:4] == ["2", "−y", "0", "y down"]


def test_plan_after_a_six_face_session(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    data = write_poses(tmp_path / "six.csv", np.repeat(six_position(), 2, axis=0), 1)
    page = tmp_path / "plan.html"
    code = main(["plan", "--poses", "4", "--given", str(data), "--json", "--report", str(page)])
    out = capsys.readouterr()
    assert code == 0, out.err
    plan = json.loads(out.out)  # --json still prints exactly one object; the report line goes to standard error
    assert "report: " in out.err
    html = page.read_text(encoding="utf-8")
    assert_self_contained(html)
    assert verdict_of(html) == "good"
    assert f"reach {100 * plan['efficiency']:.1f} % of the best any 4 poses" in unescape(reasons_of(html))
    # the table a person follows: one row per planned pose, as the planner describes it
    for k, pose in enumerate(plan["poses"], 1):
        row = cells(html, str(k))
        assert row[2] == pose["description"]
        np.testing.assert_allclose([float(x) for x in row[3].split(",")], pose["direction"], atol=6e-4)
    # standard errors before (the six faces alone) and after, the numbers of the plan itself
    for name in ("T_yx", "o_z"):
        before, after = cells(html, name)[1:3]
        assert float(before.split()[0]) == pytest.approx(plan["stderr_given"][name], rel=5e-3)
        assert float(after.split()[0]) == pytest.approx(plan["stderr"][name], rel=5e-3)
        assert plan["stderr_given"][name] > 10 * plan["stderr"][name]  # the plan fixes what the six faces leave weak
    assert "<svg" in html and "log det M" in html and "optcal plan --poses 4" in html


def test_next_pose_reports_judge_the_poses_so_far(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    six = write_poses(tmp_path / "six.csv", six_position(), 2)
    page = tmp_path / "next.html"
    assert main(["plan", "--next", str(six), "--report", str(page)]) == 0
    html = page.read_text(encoding="utf-8")
    assert verdict_of(html) == "not usable" and "do not determine the calibration" in unescape(reasons_of(html))
    assert cells(html, "T_yx")[1] == "not determined"
    many = write_poses(tmp_path / "many.csv", uniform_directions(40, 3), 3)
    assert main(["plan", "--next", str(many), "--target-stderr", "0.01", "--report", str(page)]) == 0
    html = page.read_text(encoding="utf-8")
    assert verdict_of(html) == "good" and "stop: every standard error is below 0.01" in html
    assert main(["plan", "--next", str(many), "--target-stderr", "1e-5", "--report", str(page)]) == 0
    assert verdict_of(page.read_text(encoding="utf-8")) == "usable with care"
    capsys.readouterr()


def test_next_pose_after_a_weakly_determined_real_session(shared_data: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture) -> None:
    """The MPU-6050's 10-11 hand-held poses in counts determine A_xy only weakly (calibrate refuses them
    without --allow-degenerate): the planner plans about their fit, and the verdict says 'with care'."""
    page = tmp_path / "next.html"
    data = shared_data / "mpu6050-imucalibration" / "example_data_calibration.csv"
    assert main(["plan", "--next", str(data), "--report", str(page)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"\(1[01] poses, weakly determined\)", out) and "next pose:" in out
    html = unescape(page.read_text(encoding="utf-8"))
    assert verdict_of(html) == "usable with care"
    assert "T_yx has a standard error" in reasons_of(html) and "weakly determined" in reasons_of(html)
