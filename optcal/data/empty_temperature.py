"""A temperature column that holds no number at all, set aside (said in a note) so that the samples read without it.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

import numpy as np

from optcal.data.source import Source


def set_aside_empty_temperature(src: Source) -> Source:
    """``src`` without its temperature column when that column holds no number at all, said in a note.

    A temperature is read beside the samples, not as one of them: a sensor with no thermometer (a PX4 driver
    that publishes NaN, a logger's empty column) must not make every accelerometer sample unusable.  A
    temperature missing in some rows only keeps those rows out, counted, as before (the temperature-dependent
    fits need it on every row they use)."""
    if not src.has("temp") or np.isfinite(src.data["temp"]).any():
        return src
    name = src.column_map.pop("temp", "temp")
    del src.data["temp"]
    src.ignored_columns.append(name)
    how = "--columns temp=NAME reads another column" if src.file_type in ("csv", "parquet") else f"a {src.file_type} holds no other"
    src.notes.append(f"temperature {name} holds no number in any of its {src.n_rows} rows (the sensor logged none): "
                     f"set aside, the samples read without a temperature ({how})")
    return src
