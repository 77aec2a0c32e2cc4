"""Two reading faults the seventh strangers' sweep left (docs/rest-model.md, "seventh sweep"), each reproduced on a
GENERATED file of the real file's shape (no recording is committed).

* A time column of ISO 8601 date-times (jbrodovsky/research's Pixel 6a ``imu.csv``: ``time,a_z,a_y,a_x,w_z,w_y,w_x``,
  the time written ``2023-08-04 17:47:58-04:00``): refused before as "no time column (column 'time' holds no number
  ...) ... pass --rate HZ"; now read as seconds from its first row, the zone applied, said in the time decision,
  ``--rate`` still timing the rows instead.
* An accelerometer held over several rows (fffire-oss/imu_processing's iOS dump ``circle.txt``: one record over four
  lines at 50 Hz, the accelerometer's and the gyro's values repeated for 5 records): every repeat was a sample, each
  value weighing 5, and held extremes read as saturated; now the first row of each update is kept, the repeats
  counted and said, ``--keep-held`` keeping every row.
"""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from helpers.recordings import turned_recording
from optcal.data import load_with_segmentation

G = 9.80665


@pytest.fixture(scope="module")
def turned():
    """8 poses in g at 100 Hz with a gyro in rad/s (the simulator's)."""
    return turned_recording(8, 3, 4)


def _stamp(t: float, form: str) -> str:
    """The instant ``t`` s after 2023-11-05 05:59:50 UTC as a logger writes it; ``zone``: New York's local time
    with its offset, which changes from -04:00 to -05:00 at 06:00 UTC (the local clock steps back an hour)."""
    instant = datetime(2023, 11, 5, 5, 59, 50, tzinfo=timezone.utc) + timedelta(seconds=float(t))
    if form == "zone":
        offset = -4 if instant < datetime(2023, 11, 5, 6, 0, tzinfo=timezone.utc) else -5
        local = instant + timedelta(hours=offset)
        return local.strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + f"-0{-offset}:00"
    if form == "Z":
        return instant.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"
    return instant.strftime("%Y-%m-%d %H:%M:%S.%f")


@pytest.mark.parametrize("form", ["zone", "Z", "naive"])
def test_a_time_column_of_iso_8601_date_times_is_read_as_seconds_from_its_first_row(turned, tmp_path, form):
    f = turned.frame
    path = tmp_path / "imu.csv"
    rows = [f"{_stamp(t, form)},{az * G!r},{ay * G!r},{ax * G!r},{gz!r},{gy!r},{gx!r}"
            for t, ax, ay, az, gx, gy, gz in f[["t", "ax", "ay", "az", "gx", "gy", "gz"]].itertuples(index=False)]
    path.write_text("time,a_z,a_y,a_x,w_z,w_y,w_x\n" + "\n".join(rows) + "\n")
    loaded = load_with_segmentation(path)
    assert loaded.poses.n == len(turned.dwells)
    assert abs(loaded.recording.rate_hz - 100.0) < 0.5
    t = f["t"].to_numpy()
    np.testing.assert_allclose(loaded.recording.t, t - t[0], atol=1.5e-3)  # the stamps' milliseconds
    reason = loaded.decisions.time_base.reason
    assert "column 'time' read as ISO 8601 date-times" in reason and "--rate HZ times the rows instead" in reason
    assert ("zone -04:00 applied" if form == "zone" else "zone Z applied" if form == "Z" else "no zone") in reason
    timed = load_with_segmentation(path, rate=50.0)  # --rate still overrides the column
    assert timed.decisions.time_base.value == "rate" and timed.recording.rate_hz == 50.0


def _held_records(turned, ratio: int) -> tuple[str, int]:
    """The iOS dump's shape (a date-time line, then Acceleration, Rotation Rate, Magnetic Field lines) at the
    simulator's 100 Hz, the accelerometer and the gyro updated every ``ratio`` records and held between."""
    f = turned.frame
    n = len(f)
    update = (np.arange(n) // ratio) * ratio  # the row of the update each record repeats
    acc, gyro = f[["ax", "ay", "az"]].to_numpy()[update], f[["gx", "gy", "gz"]].to_numpy()[update]
    from helpers.ios_dump import ios_dump_lines

    lines = ios_dump_lines(f["t"].to_numpy(), acc, gyro)
    return "\n".join(lines) + "\n", int(np.unique(update).size)


def test_an_accelerometer_held_over_several_rows_keeps_one_row_per_update(turned, tmp_path):
    from optcal.data.recording import HELD  # the exclusion's words (absent before this fix)

    text, updates = _held_records(turned, 5)
    path = tmp_path / "circle.txt"
    path.write_text(text)
    loaded = load_with_segmentation(path)
    rec = loaded.recording
    assert rec.n == updates and rec.exclusions[HELD] == len(turned.frame) - updates
    assert abs(rec.rate_hz - 20.0) < 0.2  # the accelerometer's own rate, 100 Hz / 5
    assert np.all(np.any(np.diff(rec.acc, axis=0) != 0, axis=1))  # no value counted twice
    assert loaded.poses.n == len(turned.dwells)
    said = " ".join(loaded.decisions.warnings)
    assert "most of 5 rows" in said and "(--keep-held keeps them)" in said
    kept = load_with_segmentation(path, keep_held=True)
    assert kept.recording.n == len(turned.frame) and HELD not in kept.recording.exclusions
    assert "every row kept (--keep-held)" in " ".join(kept.decisions.warnings)
