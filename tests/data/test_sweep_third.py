"""The third strangers' sweep (docs/rest-model.md, "Strangers' recordings, third sweep"): layouts public loggers
wrote that optcal misread, each reproduced on a GENERATED file (no recording is committed).

* a header row with a delimiter after its last name (``Index,Accel X (LSB),...,Temperature,``: Ehsangit2021/ITG_MPU's
  ICM-20948 export; any Arduino loop that prints ``","`` after every field, the header's included): the empty last
  name made the line "not a row of names", so the file was read as having no header, its names kept as a metadata
  line and its columns taken by the common layout of their number (or refused as "no header row");

Each test fails on the code before this sweep.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cli_run import run
from optcal.core.model import LumpedModel
from optcal.data import load_with_segmentation
from optcal.data.text import sniff_layout
from optcal.families.simulate.poses import uniform_directions
from optcal.families.simulate.recording import synthesize_recording


@pytest.fixture(scope="module")
def turned():
    """10 poses in g at 100 Hz with a gyro in °/s."""
    model = LumpedModel.from_physical([1.01, 0.99, 1.0], 0.004, -0.003, 0.005, [0.01, -0.02, 0.015])
    return synthesize_recording(model, uniform_directions(10, rng=5), dwell_s=3.0, transition_s=1.5, sigma=0.002, rng=6)


# ------------------------------------------------------------------ a delimiter after the header's last name
@pytest.mark.parametrize("rows_end", [",", ""])
def test_a_header_ending_in_a_delimiter_names_the_columns(turned, tmp_path, rows_end):
    """``time_ms,gx,gy,gz,ax,ay,az,`` over rows with (or without) a delimiter after the last value: before, the
    header was not read (a metadata line), the first column taken as seconds and the triples by their order; now its
    names map the columns (the gyro first, the time in ms by its name)."""
    f = turned.frame
    values = np.column_stack([f["t"] * 1000.0, f[["gx", "gy", "gz"]], f[["ax", "ay", "az"]]])
    path = tmp_path / "arduino.csv"
    path.write_text("time_ms,gx,gy,gz,ax,ay,az,\n"
                    + "".join(",".join(f"{v:.6f}" for v in row) + rows_end + "\n" for row in values))
    layout = sniff_layout(path)
    assert layout.has_header and layout.names[:7] == ["time_ms", "gx", "gy", "gz", "ax", "ay", "az"]
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 1.0
    # the accelerometer's columns are the named ones (1 g at rest), not the first triple (the gyro, near 0)
    np.testing.assert_allclose(np.linalg.norm(loaded.poses.acc, axis=1), 1.0, atol=0.03)
    assert loaded.decisions.columns.reason.startswith("header names")


def test_a_header_ending_in_a_delimiter_over_rows_with_an_extra_value_is_refused_naming_columns(turned, tmp_path,
                                                                                                 capsys):
    """ITG_MPU's export: 11 names and a delimiter, over rows of 12 values and a delimiter (the temperature written
    with a decimal comma, ``32,04466``, splits in two fields). Before: "the file has no header row"; now the header
    is recognised, the mismatch said, and ``--columns`` by position reads the file with the line as a note."""
    f = turned.frame
    n = len(f)
    counts = np.column_stack([np.arange(n) + 14691, np.round(f[["ax", "ay", "az"]] * 16384),
                              np.round(f[["gx", "gy", "gz"]] * 131), np.tile([-89, 217, 275], (n, 1))]).astype(int)
    names = ["Index"] + [f"{s} {a} (LSB)" for s in ("Accel", "Gyro", "Compass") for a in "XYZ"] + ["Temperature"]
    path = tmp_path / "IMU.csv"
    path.write_text(",".join(names) + ",\n" + "".join(
        ",".join(str(v) for v in row) + f",32,{4466 + i % 7:05d},\n" for i, row in enumerate(counts)))
    code, out, err = run(["segment", path], capsys)
    assert code == 2 and "Traceback" not in err
    assert "no header row" not in err
    assert "line 1 looks like the header (11 columns: Index" in err and "--columns" in err
    code, out, err = run(["segment", path, "--columns", "ax=2,ay=3,az=4,gx=5,gy=6,gz=7", "--rate", "100"], capsys)
    assert code == 0, err
    assert "line 1's names do not match the fields (read as a note)" in out
