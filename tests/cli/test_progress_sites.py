"""Progress on every site of long work (issue 40): one helper, one decision made by the command line.

The sites: a large file read (streamed, rows counted), the Allan deviation (its axes, and the
search for the samples at rest), diagnose's simulations, a fleet's units.  Each draws its bar
on standard error when standard error is a terminal (faked by patching ``isatty``, the bar's
delay set to 0), and nothing with ``--quiet`` (the command's own or ``optcal -q``) or with
``--json`` into a pipe; standard output is the same with and without the bar.  A fleet drew its
bar into a log file, and diagnose its stage messages with ``--json`` into a pipe, before the one
decision; a pseudo-terminal that states no size hid every bar.
"""

from __future__ import annotations

import json
import os
import select
import sys

import click
import numpy as np
import pytest

import optcal.core.progress as progress_module
from optcal.cli.main import COMMANDS, cli, main
from optcal.families.noise.allan import simulate_noise

RATE = 100.0

#: The commands that do long work (read a recording, Allan, simulations, a fleet, a reproduction).
LONG_WORK = ("allan", "apply", "calibrate", "check", "demo", "diagnose", "export", "fleet", "plan", "reproduce",
             "segment")


@pytest.fixture
def terminal(monkeypatch):
    """Makes standard error (and standard output when called with True) report a terminal; bars drawn at once.

    Called in the test body: the captured streams are swapped in for the test's call phase, after fixtures.
    """
    monkeypatch.setattr(progress_module, "DELAY_S", 0.0)

    def make(stdout_too: bool = False) -> None:
        monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
        monkeypatch.setattr(sys.stdout, "isatty", lambda: stdout_too)

    return make


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def still_log(tmp_path):
    rng = np.random.default_rng(4)
    data = np.column_stack([simulate_noise(3_000, RATE, 3e-4, 5e-5, 0.0, rng) for _ in range(3)]) + [0, 0, 1]
    path = tmp_path / "still.csv"
    path.write_text("\n".join([f"Fs,{RATE:g}", "ax,ay,az"] + [f"{x:.7f},{y:.7f},{z:.7f}" for x, y, z in data]) + "\n")
    return path


@pytest.fixture
def pose_table(tmp_path):
    rng = np.random.default_rng(2)
    g = rng.normal(size=(40, 3))
    g /= np.linalg.norm(g, axis=1)[:, None]  # 40 poses of 1 g in random directions
    table = tmp_path / "poses.csv"
    table.write_text("ax,ay,az\n" + "\n".join(",".join(f"{v:.8f}" for v in row) for row in g + rng.normal(0, 1e-3, g.shape)))
    return table


def test_every_command_that_does_long_work_takes_quiet():
    context = click.Context(cli, obj={})
    for name in LONG_WORK:
        assert name in COMMANDS
        command = cli.get_command(context, name)
        assert command is not None
        assert any("--quiet" in getattr(p, "opts", ()) for p in command.params), name


def test_allan_the_commands_quiet_and_the_search_for_rests(still_log, capsys, terminal):
    terminal()
    code, shown, err = _run(["allan", still_log, "--units", "g"], capsys)
    assert code == 0 and "Allan deviation (acc)" in err and "finding the samples at rest" in err, err
    code, quiet, err = _run(["allan", still_log, "--units", "g", "--quiet"], capsys)
    assert code == 0 and err == "", err
    assert quiet == shown


def test_a_streamed_read_draws_its_rows_in_segment_and_not_with_quiet(still_log, capsys, terminal, monkeypatch):
    import optcal.data.text as text

    monkeypatch.setattr(text, "SMALL_FILE_BYTES", 0)  # this small file read as a large one is: streamed
    monkeypatch.setattr(text, "THREADED_READ_BYTES", 0)
    terminal()
    code, shown, err = _run(["segment", still_log, "--units", "g"], capsys)
    assert code == 0 and f"reading {still_log.name}" in err and "rows" in err, err
    code, quiet, err = _run(["segment", still_log, "--units", "g", "-q"], capsys)
    assert code == 0 and "reading" not in err, err
    assert quiet == shown


def test_a_file_pandas_reads_draws_its_rows_too(still_log, capsys, terminal):
    """Decimal commas (and text cells, runs of blanks) are read by pandas in chunks: the same bar."""
    comma = still_log.with_name("comma.csv")
    comma.write_text(still_log.read_text().replace(",", ";").replace(".", ","))
    terminal()
    code, shown, err = _run(["segment", comma, "--units", "g"], capsys)
    assert code == 0 and "reading comma.csv" in err and "rows" in err, err
    assert "decimal commas" in shown
    code, quiet, err = _run(["segment", comma, "--units", "g", "--quiet"], capsys)
    assert code == 0 and err == "" and quiet == shown, err


def test_diagnose_follows_the_one_decision(pose_table, capsys, terminal):
    terminal()
    code, shown, err = _run(["diagnose", pose_table, "--simulations", "20", "--json"], capsys)
    assert code == 0 and err == "", err  # --json into a pipe: neither bars nor stage messages
    terminal(stdout_too=True)  # the JSON read by a person: bars
    code, drawn, err = _run(["diagnose", pose_table, "--simulations", "20", "--json"], capsys)
    assert code == 0 and "simulation check" in err and "... " not in err, err
    assert json.loads(drawn) == json.loads(shown)
    assert drawn == shown


def test_diagnose_says_its_stages_into_a_log_file_but_not_with_json(pose_table, capsys):
    """Standard error not a terminal (a log file): stage messages in words; none with --json into a pipe."""
    code, talk, err = _run(["diagnose", pose_table, "--simulations", "20"], capsys)
    assert code == 0 and "... simulating the fitted model" in err and "|" not in err, err
    code, _, err = _run(["diagnose", pose_table, "--simulations", "20", "--json"], capsys)
    assert code == 0 and err == "", err


def test_a_fleet_draws_its_bar_only_in_a_terminal(tmp_path, capsys, terminal):
    from optcal.applications.fleet.synthetic import write_fleet

    write_fleet(tmp_path / "units", 12, seed=5, scale_error_units=0, six_face_units=0, unreadable_units=0)
    argv = ["fleet", tmp_path / "units", "-o", tmp_path / "r.parquet", "--workers", "1", "--prior", "none", "--json"]
    code, piped, err = _run(argv, capsys)  # standard error a file: it drew its bar into it before
    assert code == 0 and "calibrating" not in err, err
    terminal(stdout_too=True)
    code, shown, err = _run(argv, capsys)
    assert code == 0 and "calibrating" in err and "unit" in err, err
    timing = ("seconds", "wall_s")
    assert {k: v for k, v in json.loads(shown).items() if k not in timing} == \
        {k: v for k, v in json.loads(piped).items() if k not in timing}


def _read_all(fd: int) -> str:
    chunks = []
    while select.select([fd], [], [], 0.2)[0]:
        chunks.append(os.read(fd, 65536))
    return b"".join(chunks).decode("utf-8", "replace")


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_a_terminal_that_states_no_size_still_shows_the_bar(monkeypatch):
    """A pseudo-terminal opened without a size (``script``, ``docker exec -t``) is 0 × 0: tqdm hid the bar."""
    from tqdm import tqdm

    master, slave = os.openpty()  # a new pseudo-terminal: 0 columns, 0 rows
    with os.fdopen(slave, "w", encoding="utf-8") as terminal:
        assert os.get_terminal_size(terminal.fileno()) == (0, 0)
        list(tqdm(range(3), desc="before", file=terminal, delay=0, dynamic_ncols=True))  # the options of before
        terminal.flush()
        assert "before" not in _read_all(master)
        monkeypatch.setattr(sys, "stderr", terminal)
        assert list(progress_module.progress(range(3), total=3, desc="after", enabled=True, delay=0)) == [0, 1, 2]
        terminal.flush()
        assert "after" in _read_all(master)
    os.close(master)
