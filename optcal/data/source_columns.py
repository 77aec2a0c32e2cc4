"""Named float columns to a :class:`~optcal.data.source.Source`: the canonical columns resolved, and the units, the
time unit and the sampling rate as the names and the header state them.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.data.columns import (ACC, GYRO, GYRO_UNIT_WORDS, MAG, MAG_ALIASES, RATE_KEYS, RATE_SETTING, TIME_UNITS,
                                 normalise_name, partial_gyro, resolve_columns, strip_unit)
from optcal.data.quantiles import median
from optcal.data.source import GyroOnlyColumns, Source
from optcal.core.units import UNIT_ALIASES, normalise_units


def source_from_columns(
    names: list[str],
    columns: list[NDArray[np.float64]],
    path: str,
    file_type: str,
    mapping: dict[str, str] | None = None,
    header: dict[str, str] | None = None,
    non_numeric_by_name: dict[str, tuple[int, int, str]] | None = None,
) -> Source:
    """Map named float columns to canonical columns (units and time unit as the names state them)."""
    column_map, unit_words, roles = resolve_columns(names, mapping or {})
    missing = [c for c in ACC if c not in column_map]
    gyro_only = bool(missing) and all(c in column_map for c in GYRO)
    if missing and not gyro_only:
        # a magnetometer's file given to an accelerometer's command: its reader is one flag away
        stems = {strip_unit(normalise_name(n))[0] for n in names}
        mag = "; its columns name a magnetometer: optcal calibrate FILE --sensor mag" if all(
            stems & set(MAG_ALIASES[c]) for c in MAG) else ""
        raise InputError(
            f"{path}: no accelerometer column(s) for {', '.join(missing)} (the file has: "
            f"{', '.join(names) or 'no columns'}); name them ax, ay, az (or acc_x, ...) or map them "
            f"with columns (--columns ax=NAME,ay=NAME,az=NAME, or by 1-based position ax=2,ay=3,az=4){mag}"
        )
    if (partial := partial_gyro(column_map, names, mapping or {})) is not None:
        column_map = {c: v for c, v in column_map.items() if c not in GYRO}  # said in the layout (read_text)
    by_name = dict(zip(names, columns))
    bad_by_name = non_numeric_by_name or {}
    data = {canon: by_name[col] for canon, col in column_map.items()}
    non_numeric = {canon: bad_by_name[col] for canon, col in column_map.items() if col in bad_by_name}
    if "index" in data:
        idx = data["index"][np.isfinite(data["index"])]
        steps = np.diff(idx)
        is_index = steps.size > 0 and median(steps) == 1.0
        if not is_index and "n_samples" not in data:
            data["n_samples"] = data.pop("index")
            column_map["n_samples"] = column_map.pop("index")
    used = set(column_map.values())
    extra = {c: v for c, v in by_name.items() if c not in used and c not in bad_by_name and not np.isnan(v).all()}
    ignored = [c for c in names if c not in used and c not in extra]
    src = Source(
        path=path, file_type=file_type, data=data, extra=extra, column_map=column_map,
        ignored_columns=ignored, header=dict(header or {}), non_numeric=non_numeric, roles=roles,
        layout="" if partial is None else partial,
    )
    if roles is not None:
        src.columns_reason = (f"{', '.join(roles.triples[0])} as the accelerometer when the data say acceleration "
                              "(an acceleration in some loggers, a translation in others)")
    acc_units = {unit_words.get(c) for c in ACC}
    word = next(iter(acc_units)) if len(acc_units) == 1 else None
    if word is not None and word in UNIT_ALIASES["accelerometer"]:
        src.units_hint = normalise_units(word)
        src.units_reason = f"unit word {word!r} in the column names"
    if src.has(*GYRO):
        words = {unit_words.get(c) for c in GYRO}
        gyro_word = next(iter(words)) if len(words) == 1 else None
        if gyro_word is not None and gyro_word in GYRO_UNIT_WORDS:
            src.gyro_units = GYRO_UNIT_WORDS[gyro_word]
    if "t" in data and "t" in non_numeric and not np.isfinite(data["t"]).any():
        from optcal.data.date_times import text_time_column  # ISO 8601 text read as the clock, else set aside (said)

        text_time_column(src, file_type)
    if "t" in data and src.time_unit is None:  # not read from date-times
        word = unit_words.get("t")
        name = column_map["t"]
        if word in TIME_UNITS:
            factor = TIME_UNITS[word]
            if factor != 1.0:
                data["t"] = data["t"] * factor
            src.time_unit = "s" if word == "sec" else word
            src.time_reason = f"column {name!r} in {word} (its name says so)"
        else:
            src.time_reason = f"column {name!r}"
    for key, value in src.header.items():
        if normalise_name(key) in RATE_KEYS:
            try:
                rate = float(value.replace(",", "."))
            except ValueError:
                continue
            if rate > 0:
                src.rate_hint = rate
                src.rate_reason = f"'{key},{value}' in the file header"
        elif src.rate_hint is None:
            setting = next((m for m in RATE_SETTING.finditer(value) if normalise_name(m.group(1)) in RATE_KEYS), None)
            if setting is not None and float(setting.group(2)) > 0:
                src.rate_hint = float(setting.group(2))
                src.rate_reason = f"'{setting.group(1)} = {setting.group(2)} Hz' in the file header's {key!r} line"
    if gyro_only:  # a gyroscope's log (an Allan recording of the gyro alone): its reader is one flag away
        raise GyroOnlyColumns(
            f"{path}: no accelerometer column(s) for {', '.join(missing)} (the file has: {', '.join(names)}); its "
            f"columns name a gyroscope only: optcal allan FILE --sensor gyro analyses its noise (or map the "
            "accelerometer's with --columns ax=NAME,ay=NAME,az=NAME)", src)
    return src
