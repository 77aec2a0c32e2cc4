"""Command-line usage errors and messages: one ``error: ...`` line, exit 2, flags rather than Python arguments."""

import numpy as np
import pytest

from optcal.cli.main import main
from optcal.simulate import simulate_poses, tilted_sweeps


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def pose_csv(tmp_path, lu_model):
    poses = simulate_poses(lu_model, tilted_sweeps(10), 0.002, rng=np.random.default_rng(3))
    path = tmp_path / "poses.csv"
    lines = ["ax,ay,az"] + [",".join(f"{v:.10g}" for v in row) for row in poses.acc]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("args, expected", [
    (("apply", "{cal}", "{data}"), "Missing option '-o' / '--output'"),
    (("export", "{cal}", "--format", "matlab"), "Invalid value for '--format'"),
    (("calibrate", "{data}", "--rate", "-3"), "Invalid value for '--rate'"),
    (("calibrate", "{data}", "--rate", "0"), "Invalid value for '--rate'"),
    (("calibrate", "{data}", "--scale-range", "-1", "2"), "Invalid value for '--scale-range'"),
    (("export", "{cal}", "--format", "ardupilot", "--counts-per-g", "-5"), "Invalid value for '--counts-per-g'"),
    (("calibrate", "{data}", "--no-such-flag"), "No such option"),
])
def test_usage_errors_are_one_error_line_with_exit_2(capsys, pose_csv, tmp_path, args, expected):
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    argv = [a.format(cal=cal, data=pose_csv) for a in args]
    code, out, err = run(capsys, *argv)
    lines = err.strip().splitlines()
    assert code == 2
    assert len(lines) == 1 and lines[0].startswith("error: ") and expected in lines[0], err
    assert "--help" in lines[0] and "Usage:" not in err
