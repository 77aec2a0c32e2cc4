"""Every command that writes: whole or not at all (issue 40).

A read-only folder (a patched ``mkstemp`` raising EACCES: the tests may run as root, for whom
``chmod`` does not stop a write) and a full disk (a patched flush raising ENOSPC, where a real
full disk shows at the latest) give one ``error:`` line naming the output, exit 2, and no file
left behind; Ctrl-C during a write exits 130 with no file; an input is never its own output.
"""

from __future__ import annotations

import errno
from pathlib import Path

import pytest

import optcal.core.atomic as atomic
from tests.helpers.cli_run import run


#: name -> the command's arguments given DATA (pose table), CAL and the output folder OUT.
WRITERS = {
    "calibrate -o": lambda d, c, o: ["calibrate", d, "-o", o / "c.json"],
    "calibrate --report": lambda d, c, o: ["calibrate", d, "--report", o / "r.html"],
    # no simulation check and the plans' relaxation on a 100-direction grid: the same writers, a fifth to a half of
    # the time (diagnose 2.7 -> 0.5 CPU s, plan 2.8-3.1 -> 1.5-1.6)
    "diagnose -o": lambda d, c, o: ["diagnose", d, "--simulations", "0", "-o", o / "d.json"],
    "check --report": lambda d, c, o: ["check", c, d, "--report", o / "r.html"],
    "apply -o csv": lambda d, c, o: ["apply", c, d, "-o", o / "a.csv"],
    "apply -o parquet": lambda d, c, o: ["apply", c, d, "-o", o / "a.parquet"],
    "export px4 -o": lambda d, c, o: ["export", c, "--format", "px4", "--max-loss", "1000", "-o", o / "cal.params"],
    "export c -o": lambda d, c, o: ["export", c, "--format", "c", "-o", o / "cal.h"],
    "simulate -o": lambda d, c, o: ["simulate", "-o", o / "s.csv"],
    "plan --plot": lambda d, c, o: ["plan", "--poses", "12", "--grid", "100", "--plot", o / "plan.png"],
    "plan --report": lambda d, c, o: ["plan", "--poses", "12", "--grid", "100", "--report", o / "plan.html"],
}


def _full_disk(path: Path) -> None:
    raise OSError(errno.ENOSPC, "No space left on device", str(path))


def _read_only(*args, **kwargs):
    raise PermissionError(errno.EACCES, "Permission denied", kwargs.get("dir"))


@pytest.mark.parametrize("fault", ["read-only folder", "full disk"])
@pytest.mark.parametrize("name", sorted(WRITERS))
def test_an_output_that_cannot_be_written_is_one_line_and_no_file(name, fault, tmp_path, pose_csv, cal_json, capsys,
                                                                  monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    if fault == "full disk":
        monkeypatch.setattr(atomic, "_fsync", _full_disk)
    else:
        monkeypatch.setattr(atomic.tempfile, "mkstemp", _read_only)
    code, _, err = run(WRITERS[name](pose_csv, cal_json, out), capsys)
    lines = err.strip().splitlines()
    errors = [line for line in lines if line.startswith("error:")]
    assert code == 2, err
    assert len(errors) == 1 and "Traceback" not in err, err
    assert str(out) in errors[0] and ("No space left" in errors[0] or "Permission denied" in errors[0]), errors[0]
    assert list(out.iterdir()) == []  # no partial file, no temporary file


def test_ctrl_c_while_writing_leaves_nothing_and_exits_130(tmp_path, pose_csv, cal_json, capsys, monkeypatch):
    def interrupt(path: Path) -> None:
        raise KeyboardInterrupt

    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.setattr(atomic, "_fsync", interrupt)
    code, _, err = run(["apply", cal_json, pose_csv, "-o", out / "a.csv"], capsys)
    assert code == 130 and "interrupted" in err
    assert list(out.iterdir()) == []


def test_an_output_replaces_an_existing_file_whole(tmp_path, pose_csv, cal_json, capsys):
    target = tmp_path / "a.csv"
    target.write_text("old\n")
    code, _, err = run(["apply", cal_json, pose_csv, "-o", target], capsys)
    assert code == 0, err
    assert target.read_text().startswith("ax_g") and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.mark.parametrize("how", ["same path", "through a link"])
def test_an_input_is_never_overwritten_by_its_output(how, tmp_path, pose_csv, cal_json, capsys):
    before = pose_csv.read_bytes()
    target = pose_csv
    if how == "through a link":
        target = tmp_path / "link.csv"
        target.symlink_to(pose_csv)
    for argv in (["calibrate", pose_csv, "-o", target], ["apply", cal_json, pose_csv, "-o", target],
                 ["calibrate", pose_csv, "--report", tmp_path / "r.html", "-o", cal_json.parent / "c2.json"]):
        code, _, err = run(argv, capsys)
        if "-o" in argv and argv[argv.index("-o") + 1] == target:
            assert code == 2 and err.count("error:") == 1 and "input" in err, err
    assert pose_csv.read_bytes() == before
    code, _, err = run(["export", cal_json, "--format", "c", "-o", cal_json], capsys)
    assert code == 2 and "input" in err
