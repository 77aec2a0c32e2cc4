"""Issue 36 (evidence about time): Unix stamps in s, ms, µs or ns since 1970 settle the time column's unit.

Planted in the real Xsens log of ``../shared/data/imutk-xsens``: its stamps moved to 2023-07-22 and
written in each unit under a headerless first column.  Before issue 36 the ms, µs and ns files were
refused ("9.999 s apart (0.1 Hz) ... pass --time-unit ms").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from helpers.cli_run import run
from helpers.common import SHARED
from optcal.data import load_with_segmentation
from optcal.data.decisions import EPOCH_SPAN_S, TIME_UNITS
from optcal.errors import InputError

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
needs_xsens = pytest.mark.skipif(not XSENS.exists(), reason="needs ../shared/data/imutk-xsens")
#: 2023-07-22 00:26:40 UTC, in seconds since 1970.
START_S = 1.69e9


def headerless(tmp_path: Path, t: np.ndarray, name: str) -> Path:
    """The Xsens log's six count columns after a headerless time column ``t`` (one row per sample)."""
    x = pd.read_csv(XSENS).to_numpy()
    out = np.column_stack([t, x[:, 1:]])
    path = tmp_path / f"{name}.csv"
    np.savetxt(path, out, delimiter=",", fmt="%.17g")
    return path


def xsens_time(unit: str, start_s: float = START_S) -> np.ndarray:
    t = pd.read_csv(XSENS)["t_s"].to_numpy()
    return (start_s + t - t[0]) / TIME_UNITS[unit]


@needs_xsens
@pytest.mark.parametrize("unit", ["s", "ms", "us", "ns"])
def test_unix_stamps_in_any_unit_read_as_the_date_they_are(tmp_path, unit):
    loaded = load_with_segmentation(headerless(tmp_path, xsens_time(unit), unit))
    d = loaded.decisions
    assert d.kind.value == "raw recording"
    assert d.rate.value == pytest.approx(100.0, rel=0.01)
    assert f"in {unit} since 1970" in d.time_base.reason and "2023-07-22" in d.time_base.reason
    assert loaded.poses.n == 38  # the log's 38 rests, as with its own t_s column


@needs_xsens
def test_the_epoch_reading_is_printed_and_time_unit_overrides_it(tmp_path, capsys):
    path = headerless(tmp_path, xsens_time("ms"), "ms")
    code, out, err = run(["segment", path], capsys)
    assert code == 0, err
    assert "in ms since 1970: its first stamp 1.69e+12 is 2023-07-22 in ms (in seconds, the year 55,524)" in out + err
    forced = load_with_segmentation(path, time_unit="s")  # the override is obeyed, whatever the date says
    assert "given with --time-unit" in forced.decisions.time_base.reason
    assert forced.decisions.rate.value == pytest.approx(0.1, rel=0.01)


@needs_xsens
def test_a_counter_that_reads_as_a_date_at_no_recording_rate_is_not_a_date(tmp_path):
    """A µs counter since power-on that stands at 7e8 (12 min after power-on) reads as 1992-03 in seconds,
    but its 10 000-µs steps would be 10 000 s apart: no recording's rate, so no date; refused as before,
    naming the unit that gives a rate."""
    t = xsens_time("us", start_s=700.0)
    assert EPOCH_SPAN_S[0] <= t[0] <= EPOCH_SPAN_S[1]
    with pytest.raises(InputError, match=r"in seconds, as documented.*pass --time-unit us \(100 Hz\)"):
        load_with_segmentation(headerless(tmp_path, t, "counter"))
    loaded = load_with_segmentation(headerless(tmp_path, t, "counter"), time_unit="us")
    assert loaded.poses.n == 38
