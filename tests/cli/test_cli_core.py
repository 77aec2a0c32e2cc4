"""The command line: calibrate, simulate, reproduce lu2017; bad input gives one line and exit 2."""

import json

import numpy as np
import pytest

from helpers.cli_run import run_args as run

from optcal.cli.main import main
from optcal.families.simulate.poses import simulate_poses, tilted_sweeps


@pytest.mark.parametrize("method", ["default", "svd", "convex", "mle", "exact", "gd"])
def test_calibrate_json(capsys, pose_csv, method, lu_model):
    code, out, err = run(capsys, "calibrate", str(pose_csv), "--method", method, "--json")
    assert code == 0, err
    d = json.loads(out)  # exactly one JSON object
    for key in ("method", "T", "o", "A", "stderr", "rms_norm_residual_g", "n_poses", "solver"):
        assert key in d
    assert d["n_poses"] == 30
    assert set(d["solver"]) >= {"name", "status", "iterations", "solve_time_s"}
    assert np.max(np.abs(np.array(d["A"]) - lu_model.A)) < 0.01
    assert d["data"]["kind"] == "pose table"


def test_calibrate_text_and_save(capsys, pose_csv, tmp_path):
    out_json = tmp_path / "cal.json"
    code, out, err = run(capsys, "calibrate", str(pose_csv), "-o", str(out_json))
    assert code == 0, err
    assert "pose table" in out and "T_xx" in out
    saved = json.loads(out_json.read_text())
    assert saved["method"] == "mle"


def test_simulate_then_calibrate(capsys, tmp_path):
    path = tmp_path / "sim.csv"
    code, _, err = run(capsys, "simulate", "--schedule", "uniform", "-n", "60", "--sigma", "0.001", "-o", str(path))
    assert code == 0, err
    code, out, err = run(capsys, "calibrate", str(path), "--json")
    assert code == 0, err
    assert json.loads(out)["solver"]["status"] == "Solve_Succeeded"
    code, _, err = run(capsys, "simulate", "--schedule", "lu2017", "-n", "60", "-o", str(path))
    code, out, err = run(capsys, "calibrate", str(path))
    assert code == 2 and "A_xy" in err and "Traceback" not in err


def bad_files():
    good = "\n".join(f"{np.cos(a):.6f},{np.sin(a):.6f},{0.3 * np.sin(3 * a):.6f}" for a in np.linspace(0, 6, 12))
    return {
        "few": ("ax,ay,az\n1,0,0\n0,1,0\n0,0,1\n-1,0,0\n0,-1,0\n", "at least 9"),
        "missing": ("ax,ay\n1,0\n0,1\n", "az"),
        "text": ("ax,ay,az\n" + good.replace("0.", "abc", 1) + "\n", "non-numeric"),
        "identical": ("ax,ay,az\n" + "0.1,0.2,0.97\n" * 12, "distinct"),
        "coplanar": ("ax,ay,az\n" + "\n".join(f"{np.cos(a):.6f},{np.sin(a):.6f},0" for a in np.linspace(0, 6, 12)) + "\n", "plane"),
        "empty": ("", "empty"),
    }


@pytest.mark.parametrize("case", sorted(bad_files()))
def test_calibrate_bad_input(capsys, tmp_path, case):
    text, needle = bad_files()[case]
    path = tmp_path / f"{case}.csv"
    path.write_text(text)
    code, out, err = run(capsys, "calibrate", str(path), "--format", "poses")
    assert code == 2
    assert needle.lower() in err.lower(), err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert out == "" or out.startswith(f"DATA: {path} refused; the decisions made before:")  # issue 26


@pytest.mark.parametrize("cell", ["nan", "inf", ""])
def test_a_non_finite_pose_is_excluded_counted_and_not_fitted(capsys, tmp_path, cell):
    """A pose table row with a NaN, an infinity or an empty cell is excluded while reading, counted in the report and
    the JSON, and the fit is the one of the other rows (issue 40: what the reader excludes is excluded everywhere)."""
    rng = np.random.default_rng(5)
    d = rng.normal(size=(24, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    good = "\n".join(",".join(f"{v:.6f}" for v in row) for row in d)
    path = tmp_path / "poses.csv"
    path.write_text("ax,ay,az\n" + good + f"\n0.5,{cell},0.5\n")
    clean = tmp_path / "clean.csv"
    clean.write_text("ax,ay,az\n" + good + "\n")
    code, out, err = run(capsys, "calibrate", str(path), "--format", "poses", "--json")
    assert code == 0, err
    got = json.loads(out)
    assert got["n_poses"] == 24 and sum(got["data"]["exclusions"].values()) == 1, got["data"]
    code, out, _ = run(capsys, "calibrate", str(clean), "--format", "poses", "--json")
    assert np.allclose(got["T"], json.loads(out)["T"], rtol=1e-9, atol=1e-12)
    code, out, err = run(capsys, "calibrate", str(path), "--format", "poses")
    assert code == 0 and "excluded while reading: non-finite samples" in out


def test_missing_file(capsys, tmp_path):
    code, _, err = run(capsys, "calibrate", str(tmp_path / "nope.csv"))
    assert code == 2 and "no such file" in err.lower()


def test_unknown_option_is_usage_error(capsys, pose_csv):
    code, _, err = run(capsys, "calibrate", str(pose_csv), "--method", "magic")
    assert code == 2 and "Traceback" not in err


def test_reproduce_lu2017_json(capsys):
    code, out, err = run(capsys, "reproduce", "lu2017", "--runs", "3", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["literal_schedule"]["fisher_rank"] == 8
    assert set(d["monte_carlo"]["methods"]) == {"svd", "convex", "mle", "exact", "gd"}


@pytest.mark.parametrize("imu", [False, True])
def test_calibrating_a_raw_recording_loads_no_heavy_library(tmp_path, imu):
    """`optcal calibrate` (and `--imu`) on a raw recording (read, rest detection, fit) starts no scipy, pandas,
    cvxpy or matplotlib: the rest model's and the gyro check's critical values come from optcal.core.quantiles,
    rotations from Rodrigues' formula (scipy.stats alone costs 0.5-0.8 s of a start that imu_tk finishes its
    whole accelerometer calibration in, 0.30-0.40 s)."""
    import subprocess
    import sys

    from optcal.core.model import lu2017_reference_model
    from optcal.families.simulate.poses import uniform_directions
    from optcal.families.simulate.recording import synthesize_recording

    path = tmp_path / "raw.csv"
    synthesize_recording(lu2017_reference_model(), uniform_directions(12, rng=1), dwell_s=3.0, sigma=0.002,
                         gyro_bias_dps=(0.5, -0.3, 0.2), gyro_sigma_dps=0.05, rng=2).to_csv(str(path))
    script = ("import sys, io, contextlib\n"
              "from optcal.cli.main import main\n"
              f"sys.argv = ['optcal', 'calibrate', {str(path)!r}, '--json'] + {['--imu'] if imu else []!r}\n"
              "with contextlib.redirect_stdout(io.StringIO()):\n"
              "    try:\n        main()\n    except SystemExit as e:\n        assert not e.code, e.code\n"
              "print(sorted({m.split('.')[0] for m in sys.modules}))")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    loaded = set(eval(done.stdout.strip().splitlines()[-1]))
    assert "numpy" in loaded and "casadi" in loaded
    assert not loaded & {"scipy", "pandas", "cvxpy", "matplotlib", "pyarrow"}, loaded
