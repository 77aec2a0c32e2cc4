"""Rows of numbers wrapped in brackets (hu-zza/uBot_firmware's LSM303 log: MicroPython's ``print((acc, mag))``
writes ``((ax, ay, az), (mx, my, mz))``) were refused as "no data rows found", as if the file held no numbers.  The
refusal now says what the rows look like and how to convert them; the converted file reads."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.data import load
from optcal.errors import InputError
from optcal.families.mag.samples import read_mag


def test_bracketed_rows_are_named_with_their_conversion(tmp_path):
    rng = np.random.default_rng(6)
    acc = np.round(rng.normal(0, 50, (300, 3)) + [0, 0, 16384]).astype(int)
    mag = np.round(rng.normal(0, 30, (300, 3)) + [200, -100, 300]).astype(int)
    path = tmp_path / "turns.txt"
    path.write_text("".join(f"(({a[0]}, {a[1]}, {a[2]}), ({m[0]}, {m[1]}, {m[2]}))\n" for a, m in zip(acc, mag)))
    first = path.read_text().splitlines()[0]
    for read in (lambda: load(path, rate=10), lambda: read_mag(path)):
        with pytest.raises(InputError) as info:
            read()
        message = str(info.value)
        assert "wrapped in brackets" in message and f"line 1: {first}" in message and "\n" not in message
        assert "tr -d '()[]{}'" in message and "6 comma-separated columns" in message
    plain = tmp_path / "plain.csv"  # the conversion the message gives
    plain.write_text(path.read_text().translate(str.maketrans("", "", "()[]{}")))
    assert np.array_equal(read_mag(plain, columns="mx=4,my=5,mz=6").m, mag)
