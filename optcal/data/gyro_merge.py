"""Placing a second file's gyro samples on the accelerometer's times (``--gyro-file``).

imu_tk's layout writes the accelerometer and the gyroscope of one recording in two files, each with its own time
column; :func:`optcal.data.readers.merge_gyro_file` reads the gyro file and :func:`gyro_onto_times` places its
samples on DATA's rows.  Linear interpolation in time places them when every stamp is distinct.  A coarse time
column repeats stamps (cggos/imu_tk's RealSense T265 files: a 200 Hz stream stamped to 10 ms, every other row
sharing its stamp with the next); interpolation then cannot tell the rows of one stamp apart and gives each the
value of the last (half of a 200 Hz gyro replaced by its neighbours: a 100 Hz sample-and-hold, shifted by half a
period).  When the two files carry the same time column row for row they are one stream written twice, and the
rows are paired as they are; otherwise the samples interpolation cannot use are counted in the note.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def gyro_onto_times(
    t: NDArray[np.float64], tg: NDArray[np.float64], columns: list[NDArray[np.float64]]
) -> tuple[list[NDArray[np.float64]], str]:
    """The gyro file's columns on DATA's times, and how they were placed.

    Parameters
    ----------
    t : ndarray, shape (n,)
        DATA's (the accelerometer's) time column.
    tg : ndarray, shape (m,)
        The gyro file's time column (non-decreasing where finite).
    columns : list of ndarray, shape (m,)
        The gyro file's three rate columns.

    Returns
    -------
    list of ndarray, shape (n,)
        The rates on DATA's rows: the rows as they are when ``tg`` equals ``t`` row for row and repeats a stamp;
        else linearly interpolated (NaN outside the gyro file's span).
    str
        The note saying how they were placed (and how many gyro samples interpolation could not use).
    """
    ok = np.isfinite(tg)
    repeats = int(np.count_nonzero(np.diff(tg[ok]) == 0))
    if repeats and t.shape == tg.shape and np.array_equal(t, tg, equal_nan=True):
        note = (f"paired row for row with the accelerometer (the two files share their time column, which repeats "
                f"{repeats} stamps: interpolation would give each repeated stamp's rows the last one's rate)")
        return [np.asarray(c, dtype=float).copy() for c in columns], note
    placed = [np.interp(t, tg[ok], np.asarray(c, dtype=float)[ok], left=np.nan, right=np.nan) for c in columns]
    note = "interpolated onto the accelerometer times"
    if repeats:
        note += (f"; {repeats} gyro samples share their stamp with the next and are not used (interpolation takes "
                 f"the last sample of each repeated stamp; a time column fine enough to tell them apart keeps them)")
    return placed, note
