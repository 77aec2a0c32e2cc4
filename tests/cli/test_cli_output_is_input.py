"""An output that is one of the command's inputs is refused before any work (issue 40).

The refusal is made on the parsed arguments, before the command body runs: in a fresh
interpreter the fitting and reading stacks (CasADi, cvxpy, pandas) are never imported, so no
data was read and no fit was run.  The same file is recognised however it is spelled: the same
path, ``./`` and ``folder/../`` spellings, a symbolic link and a hard link.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers.cli_run import run

#: name -> (arguments given DATA, CAL and the OUTPUT path, the flag the error must name).
REFUSALS = {
    "calibrate -o": (lambda d, c, o: ["calibrate", d, "-o", o], "-o"),
    "calibrate --report": (lambda d, c, o: ["calibrate", o, "--report", o], "--report"),  # a pose table named .html
    "diagnose -o": (lambda d, c, o: ["diagnose", d, "-o", o], "-o"),
    "apply -o": (lambda d, c, o: ["apply", c, d, "-o", o], "-o"),
    "export -o": (lambda d, c, o: ["export", c, "--format", "c", "-o", o], "-o"),
    "segment --plot": (lambda d, c, o: ["segment", d, "--plot", o], "--plot"),
    "allan --plot": (lambda d, c, o: ["allan", d, "--plot", o], "--plot"),
}

#: Runs the commands given as JSON in argv[1] and prints, per command, its exit code, its
#: standard error and whether a heavy stack was imported (which a refusal before work never does).
_PROBE = """
import contextlib, io, json, sys
from optcal.cli.main import main
results = []
for argv in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(argv)
    results.append([code, err.getvalue(), sorted(m for m in ("casadi", "cvxpy", "pandas") if m in sys.modules)])
print(json.dumps(results))
"""


def _target(how: str, original: Path, tmp_path: Path) -> Path:
    """``original`` spelled ``how``."""
    if how == "symbolic link":
        link = tmp_path / "elsewhere" / f"link{original.suffix}"
        link.parent.mkdir(exist_ok=True)
        link.symlink_to(original)
        return link
    if how == "hard link":
        link = tmp_path / f"hard{original.suffix}"
        os.link(original, link)
        return link
    if how == "dotted path":
        return original.parent / "sub" / ".." / "." / original.name
    return original


@pytest.mark.parametrize("how", ["same path", "dotted path", "symbolic link", "hard link"])
def test_an_output_over_an_input_is_refused_before_any_work(how, tmp_path, pose_csv, cal_json, capsys):
    (tmp_path / "sub").mkdir()
    html = tmp_path / "poses.html"  # --report takes only .html names: the input is given one
    html.write_bytes(pose_csv.read_bytes())
    targets = {victim: _target(how, victim, tmp_path) for victim in (pose_csv, cal_json, html)}
    cases = []
    for name, (argv, flag) in REFUSALS.items():
        victim = cal_json if name.startswith("export") else html if "--report" in name else pose_csv
        cases.append((name, flag, victim, [str(a) for a in argv(pose_csv, cal_json, targets[victim])]))
    before = {p: p.read_bytes() for p in targets}
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    done = subprocess.run([sys.executable, "-c", _PROBE, json.dumps([c[3] for c in cases])], capture_output=True,
                          text=True, env=env, check=True)
    for (name, flag, _, _), (code, err, heavy) in zip(cases, json.loads(done.stdout)):
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith(f"error: {flag} "), (name, err)
        assert "is the input" in lines[0] and "destroy the input" in lines[0], (name, err)
        assert heavy == [], (name, heavy)  # nothing was read or fitted before the refusal
    assert {p: p.read_bytes() for p in before} == before


def test_an_output_beside_the_input_is_written(tmp_path, pose_csv, capsys):
    """The check refuses only the same file: a new name in the input's folder is written."""
    code, _, err = run(["calibrate", pose_csv, "-o", pose_csv.with_suffix(".json")], capsys)
    assert code == 0, err
    assert json.loads(pose_csv.with_suffix(".json").read_text())
