"""A second text file's gyro (imu_tk's, phyphox's or Sensor Logger's ``Gyroscope.csv``) merged onto the
accelerometer's times.

Part of the *read* step (:mod:`optcal.data.readers`).

imu_tk's layout writes the accelerometer and the gyroscope of one recording in two files, each with its own time
column; :func:`merge_gyro_file` reads the gyro file and :func:`gyro_onto_times` places its
samples on DATA's rows.  Linear interpolation in time places them when every stamp is distinct.  A coarse time
column repeats stamps (cggos/imu_tk's RealSense T265 files: a 200 Hz stream stamped to 10 ms, every other row
sharing its stamp with the next); interpolation then cannot tell the rows of one stamp apart and gives each the
value of the last (half of a 200 Hz gyro replaced by its neighbours: a 100 Hz sample-and-hold, shifted by half a
period).  When the two files carry the same time column row for row they are one stream written twice, and the
rows are paired as they are; otherwise the samples interpolation cannot use are counted in the note.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.data.columns import ACC, GYRO, GYRO_UNIT_WORDS, normalise_name, resolve_columns, sensor_logger_mapping, strip_unit
from optcal.data.source import Source
from optcal.data.text_reader import read_text


def merge_gyro_file(src: Source, gyro_file: str | Path) -> None:
    """Add ``gx, gy, gz`` from a second text file ``t gx gy gz``, placed on ``src``'s times.

    imu_tk writes the accelerometer and the gyroscope of one recording in two files with
    their own time columns; samples of the gyro file are matched to the accelerometer's by
    time (:func:`gyro_onto_times`: linear interpolation, or row for row when the
    two files share a time column that repeats stamps; accelerometer samples outside the gyro file's
    time span get NaN and are counted as non-finite).
    """
    if not src.has("t"):
        raise InputError(f"{src.path}: merging a gyro file needs a time column in both files")
    if src.has(*GYRO):
        raise InputError(f"{src.path}: already has gyro columns; give gyro_file only for accelerometer-only files")
    mapping, unit = _gyro_only_mapping(gyro_file)
    g = read_text(gyro_file, mapping)
    tg = g.column("t")
    ok = np.isfinite(tg)
    if ok.sum() < 2 or np.any(np.diff(tg[ok]) < 0):
        raise InputError(f"{gyro_file}: the gyro file's time column must increase")
    if (src.time_unit or "s") != (g.time_unit or "s"):
        raise InputError(f"{gyro_file}: its time unit ({g.time_unit}) differs from {src.path}'s ({src.time_unit})")
    t = src.column("t")
    cols = ("ax", "ay", "az") if not g.has(*GYRO) else GYRO
    placed, how = gyro_onto_times(t, tg, [g.column(c) for c in cols])
    src.data.update(zip(GYRO, placed))
    src.column_map.update({name: f"{Path(gyro_file).name}:{g.column_map[c]}" for name, c in zip(GYRO, cols)})
    src.notes.append(f"gyro from {gyro_file}, {how}")
    if src.gyro_units is None and g.column_map.get("ax") is not None:  # a gyro read in the accelerometer's place
        word = strip_unit(normalise_name(g.column_map["ax"]))[1]
        src.gyro_units = GYRO_UNIT_WORDS.get(word) if word is not None else unit


def _gyro_only_mapping(gyro_file: str | Path) -> tuple[dict[str, str] | None, str | None]:
    """A gyro file whose names say gyroscope and nothing accelerometer (phyphox's ``Gyroscope.csv``: ``X (rad/s)``;
    Sensor Logger's ``Gyroscope.csv``, bare ``x, y, z`` in rad/s by its documentation): its gyro columns mapped into
    the accelerometer's place, where :func:`merge_gyro_file` reads a headerless ``t x y z`` file's, and the unit a
    name-less layout documents; ``(None, None)`` for any other file (read as it is)."""
    from optcal.data.text import sniff_layout

    layout = sniff_layout(gyro_file)
    if not layout.has_header:
        return None, None
    logger = sensor_logger_mapping(layout.names, str(gyro_file), sensor="gyro")
    if logger is not None:
        return logger[0], "rad/s"
    found = resolve_columns(layout.names, {}).column_map
    if any(c in found for c in ACC) or not all(c in found for c in GYRO):
        return None, None
    mapping = {a: found[c] for a, c in zip(ACC, GYRO)}
    if "t" in found:
        mapping["t"] = found["t"]
    return mapping, None


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
