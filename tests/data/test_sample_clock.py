"""Issue 36, the strangers' sweep (docs/rest-model.md, "Strangers' recordings"): an Arduino log whose first column
is ``millis()`` (a counter since power-on, no header, about 19 Hz) was read as a pose table of 58 poses "52 s
apart", its stamps taken in seconds as documented for pose tables.  Reproduced on a GENERATED file of that shape
(no recording is committed).

The model (``optcal.data.decisions._held_rows``): a pose table holds one row per pose, its consecutive rows poses a
turn apart; a recording samples a rest again and again.  Rows that stay within a pose step of the one before for
the shortest dwell at the rate a smaller unit gives are a rest sampled: with the unit unstated, the file is refused
in one line naming ``--time-unit ms`` and ``--format poses``; with ``--time-unit ms`` it is read as a recording.
Tables of distinct poses with a regular time column in seconds keep their reading.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cli_run import run
from optcal.data import load


def millis_log(path, rest_rows=(8, 12), move_rows=38, seed=0) -> None:
    """An Arduino-like log: ``millis()`` stamps (integers about 52.4 ms apart), no header, g to 0.01 g: a rest of
    ``rest_rows[0]`` rows, a slide (0.15 g of shaking per row), a rest of ``rest_rows[1]`` rows."""
    rng = np.random.default_rng(seed)
    n = rest_rows[0] + move_rows + rest_rows[1]
    t = 3450 + np.floor(np.arange(n) * 52.4 + rng.uniform(0, 1)).astype(int)
    acc = np.tile([0.08, -0.03, -1.05], (n, 1)) + rng.normal(scale=0.01, size=(n, 3))
    acc[rest_rows[0]:rest_rows[0] + move_rows] += rng.normal(scale=0.15, size=(move_rows, 3))
    path.write_text("".join(f"{ti}," + ",".join(f"{v:.2f}" for v in row) + "\n" for ti, row in zip(t, acc)))


def pose_table(path, n=24, spacing=52.4, repeat_at=None, seed=1) -> None:
    """A rig's pose table: ``t`` in whole seconds about ``spacing`` apart, then each pose's mean in g (distinct
    orientations at least 20° apart; with ``repeat_at``, that pose written twice in a row)."""
    rng = np.random.default_rng(seed)
    dirs = []
    while len(dirs) < n:
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        if not dirs or np.degrees(np.arccos(np.clip(u @ dirs[-1], -1.0, 1.0))) > 20.0:
            dirs.append(u)
    rows = [np.round(u + rng.normal(scale=0.001, size=3), 4) for u in dirs]
    if repeat_at is not None:
        rows.insert(repeat_at + 1, rows[repeat_at])
    t = np.floor(np.arange(len(rows)) * spacing + 0.5).astype(int)
    path.write_text("".join(f"{ti}," + ",".join(f"{v:.4f}" for v in row) + "\n" for ti, row in zip(t, rows)))


def test_millis_log_refused_in_one_line_naming_the_time_unit_and_the_format(tmp_path, capsys):
    f = tmp_path / "pos_x.csv"
    millis_log(f)
    code, out, err = run(["segment", f], capsys)
    assert code == 2
    error = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(error) == 1 and "Traceback" not in err
    assert "sample clock in ms" in error[0] and "19.08 Hz" in error[0]
    assert "data rows 47–58 hold one pose" in error[0]  # the second rest: 12 rows, 0.63 s at 19 Hz
    assert "--time-unit ms" in error[0] and "--format poses" in error[0]


def test_millis_log_with_its_unit_is_a_recording(tmp_path, capsys):
    f = tmp_path / "pos_x.csv"
    millis_log(f)
    code, out, err = run(["segment", f, "--time-unit", "ms"], capsys)
    assert code == 0, err
    assert "read as a raw recording (58 samples" in out
    assert "data rows 47–58 hold one pose" in out  # the kind decision says why, with its flag
    code, out, err = run(["segment", f, "--format", "poses"], capsys)  # the override: the rows as poses
    assert code == 0 and "read as a pose table (58 poses)" in out


def test_a_rest_shorter_than_the_shortest_dwell_is_no_evidence(tmp_path):
    """Both rests under 0.5 s at 19 Hz (9 rows each): nothing holds one pose for a dwell; the reading stays."""
    f = tmp_path / "short.csv"
    millis_log(f, rest_rows=(9, 9), move_rows=40)
    assert load(f).n == 58


@pytest.mark.parametrize("repeat_at", [None, 5])
def test_tables_of_distinct_poses_with_a_regular_clock_in_seconds_keep_their_reading(tmp_path, repeat_at):
    """A rig's table (poses 52 s apart, integer seconds, as regular as the Arduino's millis()), one pose written
    twice in a row or not: a repeat is not a rest's length of rows, so it stays a pose table."""
    f = tmp_path / "rig.csv"
    pose_table(f, repeat_at=repeat_at)
    poses = load(f)
    assert poses.n == 24 + (repeat_at is not None)
    assert poses.meta["decisions"]["kind"]["value"] == "pose table"
