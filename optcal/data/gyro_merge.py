"""A second text file's gyro (imu_tk's, phyphox's or Sensor Logger's ``Gyroscope.csv``) merged onto the
accelerometer's times.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from optcal.errors import InputError
from optcal.data.columns import ACC, GYRO, GYRO_UNIT_WORDS, normalise_name, resolve_columns, sensor_logger_mapping, strip_unit
from optcal.data.source import Source
from optcal.data.text_reader import read_text


def merge_gyro_file(src: Source, gyro_file: str | Path) -> None:
    """Add ``gx, gy, gz`` from a second text file ``t gx gy gz``, interpolated onto ``src``'s times.

    imu_tk writes the accelerometer and the gyroscope of one recording in two files with
    their own time columns; samples of the gyro file are matched to the accelerometer's by
    time (linear interpolation; accelerometer samples outside the gyro file's time span
    get NaN and are counted as non-finite).
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
    for name, c in zip(GYRO, cols):
        v = np.interp(t, tg[ok], g.column(c)[ok], left=np.nan, right=np.nan)
        src.data[name] = v
    src.column_map.update({name: f"{Path(gyro_file).name}:{g.column_map[c]}" for name, c in zip(GYRO, cols)})
    src.notes.append(f"gyro from {gyro_file}, interpolated onto the accelerometer times")
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
