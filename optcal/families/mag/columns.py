"""A magnetometer's columns by their names: the aliases matched whole or at the end of a longer name, the unit word
a name carries, the three axes (or a 2-axis compass's two) with ``--columns`` first, and the names of a motor's
current or throttle column."""

from __future__ import annotations

from optcal.data.columns import MAG, MAG_ALIASES, normalise_name
from optcal.errors import InputError
from optcal.families.mag.units import MAG_UNIT_WORDS

#: Names of a motor current or throttle column (ArduPilot's COMPASS_MOT takes either).
CURRENT_ALIASES: tuple[str, ...] = ("current", "curr", "i_batt", "battery_current", "amps", "ibat", "curr_a")
THROTTLE_ALIASES: tuple[str, ...] = ("throttle", "thr", "thrust", "motor", "pwm")
#: Aliases this long or longer also match the end of a longer name (``field.magnetic_field.x``).
SUFFIX_MIN_CHARS: int = 5


#: ``g`` and ``mg`` after a magnetometer's own name (x-io's ``Magnetometer X (G)``): an acceleration's unit cannot
#: measure a magnetic field, so there they are the gauss's symbols (G, mG); after a short name (``mx_g``, ``b_x_mg``)
#: they are not read so, as ``m``/``b`` may be another quantity's letter.
GAUSS_SYMBOLS: dict[str, str] = {"g": "gauss", "mg": "mgauss"}


def _strip_mag_unit(norm: str) -> tuple[str, str | None]:
    for word in MAG_UNIT_WORDS:
        if norm.endswith("_" + word) and len(norm) > len(word) + 1:
            return norm[: -len(word) - 1], word
    stem, _, symbol = norm.rpartition("_")
    if symbol in GAUSS_SYMBOLS and any(len(a) >= SUFFIX_MIN_CHARS and (stem == a or stem.endswith("_" + a))
                                       for al in MAG_ALIASES.values() for a in al):
        return stem, GAUSS_SYMBOLS[symbol]
    return norm, None


def _match(names: list[str], aliases: dict[str, tuple[str, ...]]) -> tuple[dict[str, str], dict[str, str | None]]:
    """canonical → file name (whole names first, then the end of a longer name) and the unit word each carries."""
    found: dict[str, str] = {}
    words: dict[str, str | None] = {}
    for suffix in (False, True):
        for name in names:
            base, word = _strip_mag_unit(normalise_name(name))
            for canon, al in aliases.items():
                if canon in found or name in found.values():
                    continue
                if (base in al) if not suffix else any(len(a) >= SUFFIX_MIN_CHARS and base.endswith("_" + a) for a in al):
                    found[canon], words[canon] = name, word
    return found, words


#: How a log of two field columns is read: a 2-axis compass (jremington/magcal_2D's ``x,y``, a vehicle's flat compass,
#: sebkm/sensor_fusion's ``index, time, x, y``) measures the field in its plane only, so its third axis (the plane's
#: normal) is read as 0 in every sample (:data:`NORMAL_ZERO`) and the planar (heading) form fits the two
#: (:mod:`optcal.families.mag.planar`), as it fits a 2-axis logger's ``mx,my`` with a written zero ``mz``.
TWO_AXES: str = ("a 2-axis compass's log (the field in its plane): read as mx, my with mz = 0 (the plane's normal, "
                 "unmeasured: the planar form fits it); name a 3-axis log's columns with --columns mx=NAME,my=NAME,mz=NAME")
#: The column name (no file's) of that zero third axis.
NORMAL_ZERO: str = "(mz not logged: 0)"


def _mag_triple(names: list[str], mapping: dict[str, str]) -> tuple[dict[str, str], str | None]:
    """The magnetometer's three columns (``--columns`` first) and the unit word their names carry."""
    given = {k: v for k, v in mapping.items() if k in MAG}
    for k, v in given.items():
        if v not in names and v != NORMAL_ZERO:
            if v.isdigit() and 1 <= int(v) <= len(names):
                given[k] = names[int(v) - 1]
            else:
                raise InputError(f"--columns {k}={v}: there is no column {v!r} (the file has: {', '.join(names)})")
    found, words = _match([n for n in names if n not in given.values()], MAG_ALIASES)
    cols = {**found, **given}
    if set(cols) != set(MAG) and len(names) == 2 and not given:
        return {"mx": names[0], "my": names[1], "mz": NORMAL_ZERO}, None  # a 2-axis compass's log (TWO_AXES)
    if set(cols) != set(MAG):
        raise InputError(f"no magnetometer columns (mx, my, mz or mag_x, magX, ...) among {', '.join(names)}; "
                         f"map them with --columns mx=NAME,my=NAME,mz=NAME")
    unit_words = {words.get(k) for k in MAG if k not in given}
    return cols, (unit_words.pop() if len(unit_words) == 1 else None)
