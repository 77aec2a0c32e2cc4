"""Progress bars (issue 40): one helper, one decision made by the command line.

A library call draws nothing; ``optcal allan`` draws its per-axis bar on standard error when
standard error is a terminal (faked here by patching ``isatty``), and none with ``--quiet`` or
with ``--json`` into a pipe.  Standard output is the same with and without the bar.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

import optcal.core.progress as progress_module
from optcal.cli.main import main
from optcal.core.progress import decide, progress
from optcal.families.noise.allan import simulate_noise

RATE = 100.0


@pytest.fixture
def still_log(tmp_path):
    rng = np.random.default_rng(4)
    data = np.column_stack([simulate_noise(3_000, RATE, 3e-4, 5e-5, 0.0, rng) for _ in range(3)]) + [0, 0, 1]
    path = tmp_path / "still.csv"
    path.write_text("\n".join([f"Fs,{RATE:g}", "ax,ay,az"] + [f"{x:.7f},{y:.7f},{z:.7f}" for x, y, z in data]) + "\n")
    return path


@pytest.fixture
def terminal(monkeypatch, capsys):
    """Makes standard error (and standard output when called with True) report a terminal, bars drawn at once.

    Called in the test body: the captured streams are swapped in for the test's call phase, after fixtures.
    """
    monkeypatch.setattr(progress_module, "DELAY_S", 0.0)

    def make(stdout_too: bool = False) -> None:
        monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
        if stdout_too:
            monkeypatch.setattr(sys.stdout, "isatty", lambda: True)

    return make


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_library_call_draws_nothing(capsys, terminal):
    terminal()
    assert list(progress(range(5), total=5, desc="work")) == list(range(5))
    assert capsys.readouterr().err == ""
    assert list(progress(range(5), total=5, desc="work", enabled=True)) == list(range(5))
    assert "work" in capsys.readouterr().err


@pytest.mark.parametrize(("stderr_tty", "quiet", "as_json", "stdout_tty", "expected"), [
    (True, False, False, False, True), (False, False, False, True, False), (True, True, False, True, False),
    (True, False, True, False, False), (True, False, True, True, True),
])
def test_the_decision(monkeypatch, stderr_tty, quiet, as_json, stdout_tty, expected):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: stderr_tty)
    monkeypatch.setattr(sys.stdout, "isatty", lambda: stdout_tty)
    assert decide(quiet, as_json) is expected


def test_allan_draws_its_bar_in_a_terminal_and_not_when_quiet(still_log, capsys, terminal):
    terminal()
    code, shown, err = _run(["allan", still_log, "--units", "g"], capsys)
    assert code == 0 and "Allan deviation (acc)" in err, err
    code, quiet, err = _run(["-q", "allan", still_log, "--units", "g"], capsys)
    assert code == 0 and "Allan deviation" not in err, err
    assert quiet == shown  # the bar is on stderr only: the same report


def test_allan_json_into_a_pipe_draws_no_bar(still_log, capsys, terminal):
    terminal()
    code, piped, err = _run(["allan", still_log, "--units", "g", "--json"], capsys)
    assert code == 0 and "Allan deviation" not in err, err
    terminal(stdout_too=True)  # now standard output is a terminal too: the JSON is read by a person, the bar is drawn
    code, shown, err = _run(["allan", still_log, "--units", "g", "--json"], capsys)
    assert code == 0 and "Allan deviation" in err, err
    assert shown == piped


def test_a_streamed_read_counts_its_rows_and_reads_the_same_numbers(still_log, capsys, terminal, monkeypatch):
    import optcal.data.text as text
    from optcal.data import load_recording

    monkeypatch.setattr(text, "SMALL_FILE_BYTES", 0)  # this small file read as a large one is: streamed
    monkeypatch.setattr(text, "THREADED_READ_BYTES", 0)
    quiet = load_recording(str(still_log), units="g")
    assert "reading" not in capsys.readouterr().err  # a library call: no bar
    progress_module.set_enabled(True)
    try:
        shown = load_recording(str(still_log), units="g")
    finally:
        progress_module.set_enabled(False)
    err = capsys.readouterr().err
    assert f"reading {still_log.name}" in err and "rows" in err, err
    np.testing.assert_array_equal(shown.acc, quiet.acc)


def test_the_global_quiet_silences_diagnose(tmp_path, capsys):
    """``optcal -q diagnose`` prints none of the stage messages diagnose prints to a non-terminal stderr."""
    rng = np.random.default_rng(2)
    g = rng.normal(size=(40, 3))
    g /= np.linalg.norm(g, axis=1)[:, None]  # 40 poses of 1 g in random directions
    table = tmp_path / "poses.csv"
    table.write_text("ax,ay,az\n" + "\n".join(",".join(f"{v:.8f}" for v in row) for row in g + rng.normal(0, 1e-3, g.shape)))
    code, talk, err = _run(["diagnose", table, "--simulations", "20"], capsys)
    assert code == 0 and "... " in err, err
    code, quiet, err = _run(["-q", "diagnose", table, "--simulations", "20"], capsys)
    assert code == 0 and "... " not in err, err
    assert quiet == talk
