"""No traceback on any bad input or fault (issue 40): every command, every way in.

Each case is one ``error:`` line on standard error, exit 2 (130 for Ctrl-C), no ``Traceback``,
and nothing written.  Compact on purpose: the numeric flags are found by introspecting every
command's click parameters, so a flag added later is audited without editing this file; the
non-finite ones are refused on the parsed arguments before any work (``optcal.cli.numbers``),
which keeps these hundreds of cases at milliseconds each.
"""

from __future__ import annotations

import errno
import json
import warnings
from pathlib import Path

import click
import numpy as np
import pytest

import optcal.core.atomic as atomic
from optcal.cli.main import COMMANDS, cli
from tests.cli.test_cli_outputs_atomic import WRITERS
from tests.helpers.cli_run import run

#: The arguments every command needs besides the flag under test (DATA, CAL, an output folder).
BASE = {
    "allan": lambda d, c, o: [d],
    "apply": lambda d, c, o: [c, d, "-o", o / "a.csv"],
    "calibrate": lambda d, c, o: [d],
    "check": lambda d, c, o: [c, d],
    "demo": lambda d, c, o: [],
    "diagnose": lambda d, c, o: [d],
    "export": lambda d, c, o: [c, "--format", "c"],
    "fleet": lambda d, c, o: [d, "-o", o / "f.parquet"],
    "plan": lambda d, c, o: ["--poses", "12"],
    "reproduce": lambda d, c, o: [],
    "segment": lambda d, c, o: [d],
    "simulate": lambda d, c, o: ["-o", o / "s.csv"],
}


def _float_flags() -> list[tuple[str, str]]:
    """(command, flag) of every option of every command that click converts to a float."""
    context = click.Context(cli)
    found = []
    for name in sorted(COMMANDS):
        command = cli.get_command(context, name)
        assert command is not None
        found += [(name, p.opts[-1]) for p in command.params
                  if isinstance(p, click.Option) and isinstance(p.type, click.types.FloatParamType)]
    return found


FLOAT_FLAGS = _float_flags()


def one_error(code: int, err: str, expected: int = 2) -> str:
    """The one ``error:`` line of a refused command (exit ``expected``, no traceback)."""
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == expected and len(errors) == 1 and "Traceback" not in err, (code, err)
    return errors[0]


def test_every_command_is_audited():
    assert set(BASE) == set(COMMANDS)
    assert len(FLOAT_FLAGS) > 80  # every command's float options found (a regression in the introspection)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
@pytest.mark.parametrize("command,flag", FLOAT_FLAGS)
def test_a_number_that_is_not_finite_is_refused_before_any_work(command, flag, value, tmp_path, pose_csv, capsys):
    out = tmp_path / "out"
    out.mkdir()
    cal = tmp_path / "cal.json"
    cal.write_text("{}")  # never read: the refusal comes first
    argv = [command, *BASE[command](pose_csv, cal, out), flag]
    argv += [value, value] if flag == "--scale-range" else [value]
    code, _, err = run(argv, capsys)
    if code == 2 and "Traceback" not in err and "error:" not in err:
        pytest.fail(err)
    line = one_error(code, err)
    assert flag in line or "--" in line, line  # the flag named (click's own refusals name it too)
    assert list(out.iterdir()) == []


#: Finite values that used to end in a traceback (OverflowError, numpy's seed ValueError).
EXTREMES = [
    ["plan", "--poses", "12", "--sigma", "1e308"],
    ["plan", "--poses", "12", "--seed", "-1"],
    ["simulate", "--seed", "-1"],
    ["diagnose", "{d}", "--seed", "-1"],
    ["allan", "{s}", "--max-tau", "1e308"],
    ["segment", "{r}", "--rate", "1e308"],
    ["simulate", "--poses", "99999999999999999999"],
    ["plan", "--poses", "99999999999999999999"],
    ["export", "{c}", "--format", "px4", "--counts-per-g", "1e308", "--max-loss", "1000"],
    # the rest tests' multipliers: K x a critical value overflowed in numpy (RuntimeWarning lines, exit 0)
    ["segment", "{g}", "--gyro-threshold", "1e308"],
    ["segment", "{g}", "--drift-threshold", "1e308"],
    ["segment", "{g}", "--static-threshold", "1e308"],
]


@pytest.fixture
def gyro_csv(tmp_path: Path) -> Path:
    """A raw recording with gyro columns: 12 rests joined by turns (t, ax, ay, az in g, gx, gy, gz in deg/s)."""
    from optcal.core.model import lu2017_reference_model
    from optcal.families.simulate.poses import uniform_directions
    from optcal.families.simulate.recording import synthesize_recording

    sim = synthesize_recording(lu2017_reference_model(), uniform_directions(12, 2), gyro=True, rng=3)
    path = tmp_path / "imu.csv"
    sim.frame.to_csv(path, index=False, float_format="%.7g")
    return path


@pytest.fixture
def still_csv(tmp_path: Path) -> Path:
    """A 200 s still log at 100 Hz in g (t, ax, ay, az)."""
    rng = np.random.default_rng(11)
    acc = np.array([0.01, -0.02, 1.0]) + 0.001 * rng.standard_normal((20_000, 3))
    path = tmp_path / "still.csv"
    path.write_text("t,ax,ay,az\n" + "\n".join(f"{i / 100:.2f},{a:.7f},{b:.7f},{c:.7f}" for i, (a, b, c) in enumerate(acc)))
    return path


@pytest.mark.parametrize("argv", EXTREMES, ids=[" ".join(a) for a in EXTREMES])
def test_an_extreme_finite_value_is_one_line_or_a_result(argv, request, tmp_path, capsys):
    fixtures = {"d": "pose_csv", "c": "cal_json", "s": "still_csv", "r": "still_csv", "g": "gyro_csv"}
    paths = {key: request.getfixturevalue(name) for key, name in fixtures.items() if "{" + key + "}" in argv}
    argv = [a.format(**paths) for a in argv]
    if argv[0] == "simulate":
        argv += ["-o", tmp_path / "s.csv"]
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        code, _, err = run(argv, capsys)
    assert "Traceback" not in err
    assert not [w for w in shown if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in shown]
    if code != 0:
        one_error(code, err)


#: Broken DATA files: name -> bytes.
BAD_DATA = {
    "empty": b"",
    "binary": bytes(range(256)) * 8,
    "truncated": b"ax,ay,az\n0.01,0.02,1.0\n0.5,0.4,0.7\n1.0,0.0,0.0\n0.0,1.",
    "wrong delimiter": b"ax|ay|az\n" + b"\n".join(b"%.4f|%.4f|%.4f" % (x, y, z) for x, y, z in np.eye(3)) + b"\n",
    "one row": b"ax,ay,az\n0.0,0.0,1.0\n",
    "all NaN": b"ax,ay,az\n" + b"nan,nan,nan\n" * 30,
    "all zero": b"ax,ay,az\n" + b"0,0,0\n" * 30,
    "header only": b"ax,ay,az\n",
    "text": b"hello world\nthis is not a recording\n",
}

DATA_COMMANDS = {
    "calibrate": lambda d, c: ["calibrate", d],
    "segment": lambda d, c: ["segment", d, "--rate", "100"],
    "allan": lambda d, c: ["allan", d, "--rate", "100"],
    "apply": lambda d, c: ["apply", c, d],
    "check": lambda d, c: ["check", c, d],
    "diagnose": lambda d, c: ["diagnose", d],
    "plan --given": lambda d, c: ["plan", "--poses", "3", "--given", d],
}


@pytest.mark.parametrize("kind", sorted(BAD_DATA))
@pytest.mark.parametrize("command", sorted(DATA_COMMANDS))
def test_a_broken_data_file_is_one_line(command, kind, tmp_path, cal_json, capsys):
    data = tmp_path / "data.csv"
    data.write_bytes(BAD_DATA[kind])
    code, out, err = run(DATA_COMMANDS[command](data, cal_json), capsys)
    assert "Traceback" not in err
    if code == 0:  # the reader coped (a '|' delimiter; apply and check evaluate even one pose): nothing uncounted
        assert kind in ("one row", "truncated", "wrong delimiter") and command in ("apply", "check"), err
        if kind == "truncated":
            assert "truncated cells): 1" in err + out, err
        return
    one_error(code, err)


def _calibration_faults(good: dict) -> dict[str, str]:
    """name -> the text of a broken calibration file made from a good one."""

    def changed(**fields) -> str:
        return json.dumps({**good, **fields})

    eye = np.eye(3).tolist()
    return {
        "corrupt JSON": json.dumps(good)[:-40],
        "not an object": "[1, 2, 3]",
        "wrong cal_type": changed(cal_type="no such type"),
        "T inf": changed(T=[[float("inf"), 0, 0], [0, 1, 0], [0, 0, 1]]).replace("Infinity", "1e999"),
        "T NaN": changed(T=[[1, 0, 0], [0, float("nan"), 0], [0, 0, 1]]),
        "T 1e308": changed(T=[[1e308, 0, 0], [0, 1e308, 0], [0, 0, 1e308]]),
        "T a string": changed(T="identity"),
        "T 2x2": changed(T=[[1, 0], [0, 1]]),
        "T ragged": changed(T=[[1, 0, 0], [0, 1], [0, 0, 1]]),
        "o of 2": changed(o=[0.0, 0.0]),
        "o null": changed(o=None),
        "no T": json.dumps({k: v for k, v in good.items() if k != "T"}),
        "no cal_type": json.dumps({k: v for k, v in good.items() if k != "cal_type"}),
        "empty object": "{}",
        "identity and units missing": json.dumps({"cal_type": "lumped", "T": eye, "o": [0, 0, 0]}),
    }


CAL_COMMANDS = {
    "apply": lambda c, d, o: ["apply", c, d, "-o", o / "a.csv"],
    "check": lambda c, d, o: ["check", c, d],
    "export c": lambda c, d, o: ["export", c, "--format", "c", "-o", o / "cal.h"],
    "export px4": lambda c, d, o: ["export", c, "--format", "px4", "--max-loss", "1000", "-o", o / "cal.params"],
    "plan --prior": lambda c, d, o: ["plan", "--poses", "12", "--prior", c],
}

FAULT_NAMES = sorted(_calibration_faults({"T": 0, "cal_type": "lumped"}))


@pytest.mark.parametrize("fault", FAULT_NAMES)
@pytest.mark.parametrize("command", sorted(CAL_COMMANDS))
def test_a_broken_calibration_file_is_one_line_and_nothing_written(command, fault, tmp_path, pose_csv, cal_json,
                                                                   capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(_calibration_faults(json.loads(cal_json.read_text()))[fault])
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run(CAL_COMMANDS[command](bad, pose_csv, out), capsys)
    if fault == "identity and units missing" and code == 0:  # the minimal lumped file: T and o are all it needs
        return
    one_error(code, err)
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_an_output_under_proc_is_one_line(name, pose_csv, cal_json, capsys):
    proc = Path("/proc/self/optcal-audit")
    code, _, err = run(WRITERS[name](pose_csv, cal_json, proc), capsys)
    line = one_error(code, err)
    assert "/proc/self" in line, line


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_ctrl_c_in_any_writer_exits_130_and_leaves_nothing(name, tmp_path, pose_csv, cal_json, capsys, monkeypatch):
    def interrupt(path: Path) -> None:
        raise KeyboardInterrupt

    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.setattr(atomic, "_fsync", interrupt)
    code, _, err = run(WRITERS[name](pose_csv, cal_json, out), capsys)
    assert code == 130 and "interrupted" in err and "Traceback" not in err, err
    assert list(out.iterdir()) == []


def test_a_full_disk_under_fleet_parquet_is_one_line(tmp_path, pose_csv, capsys, monkeypatch):
    pytest.importorskip("dask")
    pytest.importorskip("pyarrow")

    def full(path: Path) -> None:
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.setattr(atomic, "_fsync", full)
    code, _, err = run(["fleet", pose_csv, "-o", out / "f.parquet", "--workers", "1"], capsys)
    line = one_error(code, err)
    assert "No space left" in line and list(out.iterdir()) == []
