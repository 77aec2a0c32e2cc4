"""Generated files in Variense VMU931's export layouts (Alanzwang/vmu931): one file per sensor, the sensor's word
in every row (``acceleration,411480,0.017,0.006,0.976``), headerless or under ``Attribute,Time stamp,x,y,z``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: The three files' sensors, as the exporter words them.
WORDS: tuple[str, ...] = ("acceleration", "gyroscope", "magnetometer")


#: A turned magnetometer's field and hard iron (µT), as Alanzwang/vmu931's Magnetometer.csv holds them (its field
#: 36.6 µT about a hard iron of 181 µT).
FIELD_UT: float = 36.6
HARD_IRON_UT: tuple[float, float, float] = (120.0, -95.0, 95.0)


def write_vmu931(folder: Path, first_stamp: int, header: bool, n: int = 3000, seed: int = 5,
                 mag_turned: bool = False) -> dict[str, Path]:
    """Write a still sensor's three files at 200 Hz (stamps in ms) into ``folder``; ``{word: path}``.

    Headerless files are named ``acceleration.csv`` ...; headered ones ``Acceleration.csv`` ..., with the word
    capitalised in every row too, as the exporter writes them.  ``mag_turned`` writes the magnetometer turned
    through every direction (:data:`FIELD_UT` about :data:`HARD_IRON_UT`, 0.3 µT noise) instead of still.
    """
    rng = np.random.default_rng(seed)
    stamps = first_stamp + 5 * np.arange(n)
    acc = np.array([0.017, 0.006, 0.976]) + 0.003 * rng.normal(size=(n, 3))
    gyro = np.array([-0.2, 0.04, 0.1]) + 0.05 * rng.normal(size=(n, 3))
    mag = 40.0 + rng.normal(size=(n, 3))
    if mag_turned:
        u = rng.normal(size=(n, 3))
        mag = (np.asarray(HARD_IRON_UT) + FIELD_UT * u / np.linalg.norm(u, axis=1, keepdims=True)
               + 0.3 * rng.normal(size=(n, 3)))
    paths: dict[str, Path] = {}
    for word, values in zip(WORDS, (acc, gyro, mag)):
        shown = word.capitalize() if header else word
        rows = "".join(f"{shown},{s},{x:.9g},{y:.9g},{z:.9g}\n" for s, (x, y, z) in zip(stamps, values))
        paths[word] = folder / f"{shown}.csv"
        paths[word].write_text(("Attribute,Time stamp,x,y,z\n" if header else "") + rows)
    return paths
