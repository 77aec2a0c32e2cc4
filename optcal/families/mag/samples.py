"""Reading a magnetometer's samples from any file optcal reads: text, MAT/netCDF/HDF5, ULog, ROS bags.

A magnetometer needs no rests (the field is constant in the world frame), so its samples are
read as they are: :func:`read_mag` returns a :class:`MagSamples` with the magnetometer's
columns (``mx, my, mz`` and the aliases of :data:`optcal.data.columns.MAG_ALIASES`), and where
the file has them the accelerometer (for the dip), time, temperature and a current or
throttle column (for the interference of a motor).  Every row with a non-finite
magnetometer value is counted in :attr:`MagSamples.exclusions`, never silently dropped.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import (
    ALIASES, MAG, MAG_ALIASES, attribute_mapping, increasing_column, joined_stamp_note, normalise_name,
    parse_columns_option, sensor_logger_mapping, sensor_word, split_stamp,
)
from optcal.errors import InputError
from optcal.families.mag.units import EARTH_FIELD_UT, MAG_UNIT_WORDS, UT_PER_UNIT, UnitDecision, decide_mag_units

#: Names of a motor current or throttle column (ArduPilot's COMPASS_MOT takes either).
CURRENT_ALIASES: tuple[str, ...] = ("current", "curr", "i_batt", "battery_current", "amps", "ibat", "curr_a")
THROTTLE_ALIASES: tuple[str, ...] = ("throttle", "thr", "thrust", "motor", "pwm")
#: Aliases this long or longer also match the end of a longer name (``field.magnetic_field.x``).
SUFFIX_MIN_CHARS: int = 5


@dataclass
class MagSamples:
    """A magnetometer's raw samples and what else the file recorded beside them.

    Attributes
    ----------
    m : ndarray, shape (n, 3)
        Raw magnetometer samples (finite rows only), in :attr:`units`.
    units : UnitDecision
        The units and why.
    acc : ndarray, shape (n, 3), optional
        Accelerometer samples at the same rows (any units: only their direction is used).
    gyro : ndarray, shape (n, 3), optional
        Gyroscope samples at the same rows (raw units: only its rate's size is used, for the dip's near rest).
    t, temp, current, throttle : ndarray, shape (n,), optional
    path : str
    columns : dict of str to str
        Canonical name → the file's name for it.
    exclusions : dict of str to int
        Rows not used, counted by reason.
    notes : list of str
    """

    m: NDArray[np.float64]
    units: UnitDecision
    acc: NDArray[np.float64] | None = None
    gyro: NDArray[np.float64] | None = None
    t: NDArray[np.float64] | None = None
    temp: NDArray[np.float64] | None = None
    current: NDArray[np.float64] | None = None
    throttle: NDArray[np.float64] | None = None
    path: str = ""
    columns: dict[str, str] = field(default_factory=dict)
    exclusions: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.m.shape[0])

    def decision_lines(self) -> list[str]:
        """What was read and decided, one line each (printed before any result or refusal)."""
        cols = ", ".join(f"{k}={v}" for k, v in self.columns.items())
        lines = [f"magnetometer columns: {cols} (override with --columns mx=NAME,my=NAME,mz=NAME)", self.units.line()]
        lines += [f"excluded: {v} {k}" for k, v in self.exclusions.items() if v]
        return lines + self.notes


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


#: A file without a header is read as a 9-axis logger's (an accelerometer, a gyroscope and the magnetometer
#: last, the common order) when the triple read as the accelerometer has a norm whose median absolute
#: deviation is below this share of its median: a sensor turned by hand feels gravity plus a little
#: (2 rad/s at a 0.1 m lever arm adds 0.04 g), so most of its samples keep |a| within a tenth of g; a
#: gyroscope's rate during a calibration turn goes from nothing at the pauses to the turns' rate.
ACC_NORM_SPREAD: float = 0.1


def _relative_spread(v: NDArray[np.float64]) -> float:
    n = np.linalg.norm(v[np.all(np.isfinite(v), axis=1)], axis=1)
    med = float(np.median(n)) if n.size else 0.0
    return float(np.median(np.abs(n - med)) / med) if med > 0 else np.inf


#: How far from 1 the norm of four columns may lie in every row for them to be a unit quaternion (an orientation a
#: logger prints beside its sensors, with 4-7 significant digits: its norm is 1 within 1e-3); a sensor's triple and
#: any fourth column do not keep a norm of 1 to that in every row.
QUATERNION_NORM_TOL = 1e-3


def _minutes_unwrapped(col: NDArray[np.float64]) -> NDArray[np.float64]:
    """A clock's seconds of the minute (whole, 0-59, going back only from 59 to 0) counted on across the minutes;
    any other column as it is."""
    v = col[np.isfinite(col)]
    if not v.size or np.any(v != np.round(v)) or v.min() < 0 or v.max() > 59:
        return col
    back = np.flatnonzero(np.diff(v) < 0)
    if not back.size or np.any(v[back] != 59) or np.any(v[back + 1] != 0):
        return col
    out = col.copy()
    rows = np.flatnonzero(np.isfinite(col))
    out[rows] = v + 60.0 * np.concatenate(([0], np.cumsum(np.diff(v) < 0)))
    return out


def _example_columns(columns: list[NDArray[np.float64]], lead: int) -> str:
    """The ``--columns`` example of a headerless file of no common layout: the last three of the columns left once
    the time stamps (an increasing column, or whole seconds and their fraction), unit quaternions and columns of one
    value are set aside
    (a logger's common order puts the magnetometer last), with what was set aside; none when the rest is no set of
    triples."""
    skip: dict[int, str] = {}
    j = 0
    while j < len(columns):
        if j + 1 < len(columns) and split_stamp([_minutes_unwrapped(columns[j]), *columns[j + 1:]]) is not None:
            skip.update({j: "a split time stamp", j + 1: "a split time stamp"})
            j += 2
            continue
        if j + 3 < len(columns):
            q = np.column_stack(columns[j:j + 4])
            q = q[np.all(np.isfinite(q), axis=1)]
            if q.size and bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= QUATERNION_NORM_TOL)):
                skip.update({k: "a unit quaternion" for k in range(j, j + 4)})
                j += 4
                continue
        finite = columns[j][np.isfinite(columns[j])]
        if increasing_column(columns[j]):
            skip[j] = "increasing (a time)"
        elif finite.size and bool(np.all(finite == finite[0])):  # a field's axis moves as the sensor turns
            skip[j] = "one value in every row"
        j += 1
    rest = [j for j in range(len(columns)) if j not in skip]
    runs: list[list[Any]] = []  # consecutive columns set aside for one reason, said once
    for j, what in sorted(skip.items()):
        if runs and runs[-1][1] == j - 1 and runs[-1][2] == what and what in ("a split time stamp", "a unit quaternion"):
            runs[-1][1] = j
        else:
            runs.append([j, j, what])
    said = "; ".join(f"column {a + 1 + lead} {what}" if a == b else f"columns {a + 1 + lead}-{b + 1 + lead} {what}"
                     for a, b, what in runs)
    if len(rest) < 3 or len(rest) % 3:
        return ("--columns mx=N,my=N,mz=N (" + (f"{said}; " if said else "") +
                f"the {len(rest)} other columns are no set of triples)")
    mx, my, mz = (str(j + 1 + lead) for j in rest[-3:])
    return (f"--columns mx={mx},my={my},mz={mz} (" + (f"{said}; " if said else "") +
            "the magnetometer the last triple of the others, a logger's common order)")


def _headerless_mag(path: str, names: list[str], columns: list[NDArray[np.float64]],
                    mapping: dict[str, str], words: dict[int, str] | None = None) -> tuple[dict[str, str], str]:
    """The magnetometer's columns of a file with no header, by the common layout of its width.

    Three columns are ``mx my mz`` (Magneto's and most loggers' ``x y z`` sample files); four are a time column
    and the three when the first (or else the last) increases. Nine (ten with such a time column) are a 9-axis
    logger's: the magnetometer the last triple (the common order, as :mod:`optcal.data.columns` reads it), the
    accelerometer the one of the first two whose norm stays near its median (:data:`ACC_NORM_SPREAD`), the
    other the gyroscope; when neither or both do, they are not read and the reason names ``--columns``. Any
    other width is left to ``--columns``. Leading fields holding no number in any row are set aside, as the
    accelerometer's reader does (:func:`optcal.data.columns.headerless_mapping`): where the first one's text
    (``words``: a field's first non-numeric value) names an accelerometer or a gyroscope (Variense VMU931's
    ``acceleration,411480,0.017,0.006,0.976``), the file is refused naming the command that reads it.

    Returns
    -------
    mapping : dict
        ``mapping`` with the magnetometer's (and the time's, the accelerometer's, the gyroscope's) 1-based
        positions added.
    reason : str
        The decision, with the flag that changes it.

    Raises
    ------
    InputError
        A width with no common layout, with the ``--columns`` that names the columns.
    """
    # a first field holding no number in any row (the sensor's word in every row: VMU931's export,
    # "magnetometer,411480,-12.3,25.1,-40.2") is no column of the layout: set aside, said so; positions stay the file's
    lead = 0
    while len(columns) - lead > 3 and not np.isfinite(columns[lead]).any():
        lead += 1
    text = (words or {}).get(0, "")
    word = sensor_word(text) if lead else None
    if word in ("acc", "gyro"):
        reader = "optcal calibrate FILE" if word == "acc" else "optcal allan FILE --sensor gyro"
        raise InputError(f"{path}: column 1 reads {text!r}: not a magnetometer's log; {reader} reads it")
    given, names, columns = columns, names[lead:], columns[lead:]
    width = len(names)
    time_at: int | None = None
    # a stamp split in whole seconds and their fraction (ROS's secs, nsecs) in the first two fields: one time column
    joined = split_stamp(columns) if width in (5, 11) else None
    if joined is not None:
        columns[0] = given[lead] = joined[0]
        time_at = 0
    elif width in (3, 4, 10):
        time_at = 0 if increasing_column(columns[0]) else (width - 1 if increasing_column(columns[width - 1]) else None)
    # a field's axis turns back as the sensor turns (a full turn in any plane passes each axis's extremes), so a
    # second column increasing in every row beside the time is an index or a second clock, not a field's axis: of
    # 3 or 4 columns, 2 are then left for the field, a 2-axis compass's log (TWO_AXES)
    index_at = None
    if width == 4 and time_at is not None and increasing_column(columns[1 if time_at == 0 else 2]):
        index_at = 1 if time_at == 0 else 2
        steps = np.diff(columns[0][np.isfinite(columns[0])])
        if time_at == 0 and bool(np.all(steps == np.round(steps))) and float(np.median(steps)) == 1.0:
            time_at, index_at = 1, 0  # the first counts rows (whole steps, mostly 1): the index; the second the clock
    rest = [j for j in range(width) if j not in (time_at, index_at) and not (joined is not None and j == 1)]
    if len(rest) == 2:
        canon2 = {"mx": str(rest[0] + 1 + lead), "my": str(rest[1] + 1 + lead), "mz": NORMAL_ZERO}
        clocks = [f"column {j + 1 + lead} increases ({'the time' if j == time_at else 'an index or a second clock'})"
                  for j in sorted(k for k in (index_at, time_at) if k is not None)]
        if time_at is not None:
            canon2["t"] = str(time_at + 1 + lead)
        return {**mapping, **canon2}, (f"no header; {width} columns: " + "".join(f"{x}; " for x in clocks) +
                                       f"columns {canon2['mx']} and {canon2['my']}: {TWO_AXES}")
    if len(rest) not in (3, 9):
        raise InputError(f"{path}: the file has no header row, and its {width} unnamed columns fit no common layout of "
                         f"a magnetometer; name them by 1-based position, e.g. {_example_columns(columns, lead)}")
    canon = {k: str(j + 1 + lead) for k, j in zip(MAG, rest[-3:])}
    if time_at is not None:
        canon["t"] = str(time_at + 1 + lead)
    where = "" if time_at is None else f"; column {time_at + 1 + lead} increases"
    if joined is not None:
        where = joined_stamp_note(joined[1])
    if lead:
        what_word = f" ({text!r}: the magnetometer)" if word == "mag" else ""
        where += (f"; {'column 1 holds' if lead == 1 else f'columns 1-{lead} hold'} no number in any row{what_word}: "
                  "not read")
    if len(rest) == 9:
        triples = (rest[0:3], rest[3:6])
        spread = [_relative_spread(np.column_stack([columns[j] for j in t])) for t in triples]
        span = [f"{t[0] + 1 + lead}-{t[2] + 1 + lead}" for t in triples]
        near = [k for k in (0, 1) if spread[k] < ACC_NORM_SPREAD]
        said = (f"the norm of columns {span[0]} spreads by {100 * spread[0]:.2g} % of its median, of columns {span[1]} "
                f"by {100 * spread[1]:.2g} %; an accelerometer turned by hand stays within {100 * ACC_NORM_SPREAD:g} %")
        if len(near) == 1:
            acc, gyro = triples[near[0]], triples[1 - near[0]]
            canon.update({k: str(j + 1 + lead) for k, j in zip(("ax", "ay", "az", "gx", "gy", "gz"), acc + gyro)})
            where += f"; a 9-axis logger's: the magnetometer last, the accelerometer columns {span[near[0]]} ({said})"
        else:
            where += (f"; a 9-axis logger's: the magnetometer last; columns {span[0]} and {span[1]} not read, neither "
                      f"alone an accelerometer ({said}): name them with --columns ax=..,gx=..")
    what = " ".join(k for k, _ in sorted(canon.items(), key=lambda kv: int(kv[1])))
    return {**mapping, **canon}, (f"no header; {width} columns read as '{what}' (the common layout of {width} columns"
                                  f"{where}); name them by position to change it, e.g. --columns "
                                  f"mx={canon['mx']},my={canon['my']},mz={canon['mz']}")


#: The exclusion of rows whose magnetometer reads exactly 0, 0, 0.
ZERO_ROWS = "all-zero magnetometer rows (a logger's placeholder: a field never reads 0, 0, 0)"


#: The exclusion key of the samples at a rail.
MAG_RAIL_ROWS = "magnetometer samples with an axis at its converter's rail (the field beyond its full scale)"
#: A magnetometer's rail lies at least this far from its zero, µT: twice the Earth's strongest field (65 µT,
#: :data:`~optcal.families.mag.units.EARTH_FIELD_UT`), so that the extreme of a field seen through a hard-iron offset
#: as large as the field itself, read twice by a coarse converter, is never taken for one.  A converter whose full
#: scale is nearer (an HMC5883L at its ±0.88 G range) has its rail found only where it is an integer one.
MAG_RAIL_MIN_UT: float = 2 * EARTH_FIELD_UT[1]


def mag_rail(m: NDArray, usable: NDArray[np.bool_], units: str) -> tuple[NDArray[np.bool_], list[float]]:
    """Samples with an axis at a saturation rail (:func:`optcal.data.rails.rail_samples`, the accelerometer's model:
    an extreme reached exactly by several samples, the same magnitude on any axis), at least
    :data:`MAG_RAIL_MIN_UT` from the zero on the extreme's side; in counts only a 16-bit converter's full scale (the
    unit unknown, no distance can be stated).

    A turning magnetometer's field passes its extreme slowly (a 0.5-G component turning at 1 rad/s, read at 256 Hz
    in steps of 1/2048 G, stays within one step of its top for about 23 samples), so an extreme read by several
    equal samples is a rail only where it is held longer than a smooth peak of its flanks' curvature holds: the
    gyro's test (:data:`~optcal.data.rails.GYRO_RAIL_MIN_RUN`, ``rails._held_beyond_a_peak``)."""
    from optcal.data.rails import GYRO_RAIL_MIN_RUN, rail_samples

    per_ut = UT_PER_UNIT.get(units)
    distance = MAG_RAIL_MIN_UT / per_ut if per_ut else float("inf")
    levels: list[float] = []
    rail = rail_samples(np.asarray(m, dtype=float), usable, (0.0, 0.0, 0.0), distance, min_run=GYRO_RAIL_MIN_RUN,
                        levels=levels, outward=True)
    return rail, sorted(levels)


#: A magnetometer's range is chosen so that the field and the board's hard iron fit in it as the sensor turns:
#: samples left beside a rail whose largest axis reads beyond this share of the rail (median over the samples) sit
#: nearer the full scale than the zero, so their magnitude says nothing of the unit (the unit's note is left out)
#: and the rail's line says what such a reading is.
MAG_NEAR_RAIL_SHARE: float = 0.5


def rail_line(levels: list[float], units: str, n_rail: int, n: int) -> str:
    """The one line that says the rail: its level(s), the samples held there, and the flag that keeps them."""
    at = ", ".join(f"±{v:.7g}" for v in levels) or "a 16-bit converter's full scale"
    return (f"magnetometer rail: {n_rail} of {n} samples ({100 * n_rail / max(n, 1):.3g} %) hold an axis at {at} "
            f"{units}, the converter's full scale (the field beyond it unknown): left out; --accept-mag-fit "
            f"keeps them")


def _build(path: str, m: NDArray, stated: str | None, where: str, mag_units: str | None, columns: dict[str, str],
           others: dict[str, NDArray], notes: list[str], keep_rail: bool = False) -> MagSamples:
    finite = np.all(np.isfinite(m), axis=1)
    exclusions = {"rows with a non-finite magnetometer value": int(np.count_nonzero(~finite))}
    # a magnetometer in the Earth's field (25-65 µT) never reads exactly 0, 0, 0 (its noise alone moves the last
    # digit): such a row is a logger's placeholder before the sensor answered, as the accelerometer's readers count it
    zero = finite & np.all(m == 0.0, axis=1)
    if zero.any():
        if zero.sum() == finite.sum():
            raise InputError(f"{path}: every magnetometer row reads 0, 0, 0 (a logger's placeholder, not a field): "
                             "no magnetometer data; check the columns (--columns mx=...,my=...,mz=...)")
        exclusions[ZERO_ROWS] = int(zero.sum())
        finite &= ~zero
    units = decide_mag_units(m[finite], stated, where, mag_units)
    rail, levels = mag_rail(m, finite, units.units)
    if rail.any() and not keep_rail:
        n_rail, n = int(rail.sum()), int(finite.sum())
        if n_rail == n:
            raise InputError(f"{path}: {rail_line(levels, units.units, n_rail, n).split(': ', 1)[1].split(': left')[0]}; "
                             f"none is left: the magnetometer measured no field in its range; --accept-mag-fit "
                             f"keeps them")
        exclusions[MAG_RAIL_ROWS] = n_rail
        finite &= ~rail
        units = decide_mag_units(m[finite], stated, where, mag_units)  # the field's median, not the rail's
        line = rail_line(levels, units.units, n_rail, n)
        near = float(np.median(np.max(np.abs(m[finite]), axis=1))) / max(levels) if levels else 0.0
        if near >= MAG_NEAR_RAIL_SHARE:  # their magnitude is the rail's neighbourhood, no evidence of a unit
            line += (f"; the {n - n_rail} left read their largest axis at {100 * near:.3g} % of the rail (median): "
                     f"a magnet near the sensor, a range too small or a failed sensor")
            units = UnitDecision(units.units, units.reason.split("; note: ")[0], units.median_field)
        notes = [*notes, line]
    elif rail.any():
        notes = [*notes, f"{int(rail.sum())} magnetometer samples at a rail kept (--accept-mag-fit)"]
    pick = (lambda a: None if a is None else np.asarray(a, dtype=float)[finite])
    acc = pick(others.get("acc"))
    if acc is not None and not np.any(np.all(np.isfinite(acc), axis=1)):
        acc = None
    gyro = pick(others.get("gyro"))
    return MagSamples(m=np.ascontiguousarray(m[finite]), units=units, acc=acc, gyro=gyro, t=pick(others.get("t")),
                      temp=pick(others.get("temp")), current=pick(others.get("current")),
                      throttle=pick(others.get("throttle")), path=path, columns=columns, exclusions=exclusions, notes=notes)


def _read_text(path: str, mapping: dict[str, str], mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    from optcal.data.text import read_numbers

    layout, parsed = read_numbers(Path(path))
    if not layout.has_header and layout.comment_names is not None:
        # the header written as a comment (rostopic echo -p's "%time,field.header.seq,...", "# mx my mz"): taken
        # when it names the magnetometer's columns (or --columns names one of its words)
        words = list(layout.comment_names)
        if any(v in words for v in mapping.values()) or set(_match(words, MAG_ALIASES)[0]) == set(MAG):
            layout = layout.with_comment_header()
    names = list(layout.names)
    col = dict(zip(names, parsed.columns))
    notes: list[str] = [parsed.comments.describe()] if parsed.comments is not None and parsed.comments.count else []
    if not layout.has_header and layout.comment_names is None and not any(k in MAG for k in mapping):
        mapping, reason = _headerless_mag(path, names, parsed.columns, mapping,
                                          {j: v[2] for j, v in parsed.non_numeric.items()})
        col = dict(zip(names, parsed.columns))  # a split stamp's two fields joined into the first (split_stamp)
        notes.append(reason)
    logger = sensor_logger_mapping(names, path, sensor="mag") if layout.has_header and not mapping else None
    if logger is not None:  # Sensor Logger's Magnetometer.csv: bare x, y, z in µT, by its file's name (UNITS.md)
        mapping = logger[0]
        notes.append(logger[1])
    elif layout.has_header and not mapping and parsed.columns and (attribute := attribute_mapping(
            names, {names[j]: v for j, v in parsed.non_numeric.items()}, len(parsed.columns[0]), path, "mag")):
        mapping = attribute[0]  # VMU931's bare x, y, z: a column of words in every row says the quantity
        notes.append(attribute[1])
    mag_cols, word = _mag_triple(names, mapping)
    if mag_cols["mz"] == NORMAL_ZERO:  # a 2-axis compass's log: its plane's normal, unmeasured, read as 0 (TWO_AXES)
        col[NORMAL_ZERO] = np.zeros(len(col[mag_cols["mx"]]))
        if layout.has_header:
            notes.append(f"2 columns ({mag_cols['mx']}, {mag_cols['my']}): {TWO_AXES}")
    if logger is not None:
        word = "ut"
    taken = set(mag_cols.values())
    rest = [n for n in names if n not in taken]
    extra_aliases = {"ax": ALIASES["ax"], "ay": ALIASES["ay"], "az": ALIASES["az"], "gx": ALIASES["gx"],
                     "gy": ALIASES["gy"], "gz": ALIASES["gz"], "t": ALIASES["t"],
                     "temp": ALIASES["temp"], "current": CURRENT_ALIASES, "throttle": THROTTLE_ALIASES}
    found, _ = _match(rest, extra_aliases)
    found.update({k: v for k, v in mapping.items() if k in extra_aliases and v in names})
    others: dict[str, NDArray] = {k: col[v] for k, v in found.items() if k in ("t", "temp", "current", "throttle")}
    if all(k in found for k in ("ax", "ay", "az")):
        others["acc"] = np.column_stack([col[found[k]] for k in ("ax", "ay", "az")])
    if all(k in found for k in ("gx", "gy", "gz")):
        others["gyro"] = np.column_stack([col[found[k]] for k in ("gx", "gy", "gz")])
    m = np.column_stack([col[mag_cols[k]] for k in MAG])
    columns = {**mag_cols, **{k: v for k, v in found.items()}}
    if word is None and all(normalise_name(mag_cols[k]).endswith("magnetic_field_" + k[1]) for k in MAG):
        # a ROS export's columns (rostopic echo -p's field.magnetic_field.x, a ros2 bag export's magnetic_field.x):
        # sensor_msgs/MagneticField is in tesla (REP 145)
        return _build(path, m, "T", "sensor_msgs/MagneticField's field names (tesla, REP 145)", mag_units, columns,
                      others, notes, keep_rail)
    where = "Sensor Logger's documentation (UNITS.md: µT)" if logger is not None else f"the unit word {word!r} in the column names"
    return _build(path, m, word, where, mag_units, columns, others, notes, keep_rail)


def _read_container(path: str, kind: str, topic: str | None, mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    from optcal.data.containers import (ACCELEROMETER, MAGNETOMETER, MAGNETIC_UNIT_SPELLINGS, MAT5, Variable,
                                        orientations, read_hdf5, read_mat5, role_of)

    contents = read_mat5(path) if kind == MAT5 else read_hdf5(path, kind)

    clocks: dict[str, tuple[NDArray, int]] = {}  # a variable's time column and its axes' first 1-based column

    def as_samples(var: Variable) -> NDArray | None:
        values = np.asarray(var.values, dtype=np.float64)
        shape = tuple(values.shape)
        if len(shape) == 2 and 3 in shape:
            return values if shape[1] == 3 and "rows" in orientations(shape) else values.T
        if len(shape) == 2 and 4 in shape and 3 not in shape and min(shape) == 4:
            # a buffer of a time and the three axes (sunsided/sensor-fusion's compassBuffer, 4 × n: t, x, y, z), as
            # a headerless text file of 4 columns is read: the time the first (or else the last) when it increases
            v = values if shape[1] == 4 else values.T
            at = 0 if increasing_column(v[:, 0]) else (3 if increasing_column(v[:, 3]) else None)
            if at is None:
                return None
            clocks[var.name] = (v[:, at], 2 if at == 0 else 1)
            return np.delete(v, at, axis=1)
        return None

    by_role: dict[str, list] = {}
    for var in contents.variables:
        by_role.setdefault(role_of(var) or "", []).append(var)
    candidates = [v for v in by_role.get(MAGNETOMETER, []) if as_samples(v) is not None]
    if topic is not None:
        candidates = [v for v in contents.variables if v.name == topic and as_samples(v) is not None]
    if len(candidates) != 1:
        have = ", ".join(f"{v.name} ({v.shape_text})" for v in contents.variables) or "none"
        what = "no" if not candidates else "more than one"
        raise InputError(f"{path}: {what} magnetometer variable (by its name or units) among: {have}; "
                         f"name it with --topic NAME")
    var = candidates[0]
    m = as_samples(var)
    assert m is not None
    unit_attr = var.text("units")
    stated = unit_attr if unit_attr and re.sub(r"[\s_.·*]+", "", unit_attr.lower()) in MAGNETIC_UNIT_SPELLINGS else None
    others: dict[str, NDArray] = {}
    accs = [a for v in by_role.get(ACCELEROMETER, []) if (a := as_samples(v)) is not None and a.shape[0] == m.shape[0]]
    first = clocks[var.name][1] if var.name in clocks else 1  # the axes' 1-based columns: 2-4 after a leading time
    columns = {k: f"{var.name}(:,{j + first})" for j, k in enumerate(MAG)}
    if len(accs) == 1:
        others["acc"] = accs[0]
    notes = [f"variable {var.name!r} ({var.shape_text}) read as the magnetometer"]
    if var.name in clocks:  # its time and three axes (as_samples); the time's unit is not stated: seconds assumed
        others["t"] = clocks[var.name][0]
        notes[0] += " (its 4 columns a time, increasing, and x, y, z; --topic names another variable)"
    return _build(path, m, stated, f"the variable's units attribute {unit_attr!r}", mag_units, columns, others, notes,
                  keep_rail)


#: PX4's magnetometer topics with their calibration (``CAL_MAG*``) applied, read where ``sensor_mag`` (the driver's
#: samples) is not logged: ``vehicle_magnetometer`` (PX4 v1.10 on) and ``sensor_combined``'s ``magnetometer_ga``
#: (before), both in gauss.
PX4_CALIBRATED_MAG: tuple[str, ...] = ("vehicle_magnetometer", "sensor_combined")
#: ``sensor_combined``'s relative stamp of a row without that sensor's sample (PX4's ``RELATIVE_TIMESTAMP_INVALID``).
_RELATIVE_INVALID = 2**31 - 1


def _ulog_field(d: dict[str, NDArray], stem: str, rel: str | None) -> tuple[NDArray, NDArray] | None:
    """Times (s) and the 3 axes of a ULog topic's ``stem`` fields (``x``/``y``/``z`` or ``stem[0..2]``), the rows
    without the sensor's sample (``rel`` invalid) left out."""
    keys = [f"{stem}[{i}]" for i in range(3)] if stem else list("xyz")
    if any(k not in d for k in keys):
        return None
    t = d["timestamp"].astype(float)
    ok = np.ones(t.size, dtype=bool)
    if rel is not None and rel in d:
        r = d[rel].astype(np.int64)
        ok = r != _RELATIVE_INVALID
        t = t + np.where(ok, r, 0)
    return t[ok] * 1e-6, np.column_stack([d[k].astype(float)[ok] for k in keys])


def _read_ulog(path: str, topic: str | None, mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    from optcal.data.ulog import import_pyulog

    ULog = import_pyulog()
    name, instance = (topic or "sensor_mag"), 0
    if ":" in name:
        name, inst = name.split(":", 1)
        if not inst.isdigit():
            raise InputError(f"--topic {topic!r}: the instance after ':' must be a number")
        instance = int(inst)
    names = [name, "sensor_accel", *PX4_CALIBRATED_MAG] if topic is None else [name, "sensor_accel", "sensor_combined"]
    try:
        log = ULog(str(path), message_name_filter_list=names)
    except Exception as exc:
        raise InputError(f"{path}: not a readable ULog file ({exc.__class__.__name__}: {exc})") from exc

    def dataset(topic_name: str) -> dict[str, NDArray] | None:
        try:
            return dict(log.get_dataset(topic_name, instance).data)
        except (KeyError, IndexError, ValueError):
            return None

    notes: list[str] = []
    d, read = dataset(name), None
    if d is not None:
        read = _ulog_field(d, "" if name == "sensor_mag" else "magnetometer_ga", "magnetometer_timestamp_relative")
    if read is None and topic is None:
        for other in PX4_CALIBRATED_MAG:
            if (od := dataset(other)) is not None and (read := _ulog_field(
                    od, "magnetometer_ga", "magnetometer_timestamp_relative")) is not None:
                notes.append(f"{name} is not logged; {other}:{instance} read, PX4's magnetometer with its calibration "
                             f"(CAL_MAG*) applied, so the fit is of what that calibration left")
                name = other
                break
    if read is None:
        logged = sorted({f"{x.name}:{x.multi_id}" for x in ULog(str(path)).data_list if "mag" in x.name
                         or x.name == "sensor_combined"})
        raise InputError(f"{path}: no ULog topic {name} instance {instance} with a magnetometer (logged: "
                         f"{', '.join(logged) or 'none'}); choose one with --topic (sensor_mag[:N], vehicle_magnetometer or "
                         f"sensor_combined)")
    t, m = read
    others: dict[str, NDArray] = {"t": t}
    if d is not None and "temperature" in d and name == "sensor_mag":
        others["temp"] = d["temperature"].astype(float)
    acc = dataset("sensor_accel")
    acc_read = (_ulog_field(acc, "", None) if acc is not None else None) or (
        _ulog_field(c, "accelerometer_m_s2", "accelerometer_timestamp_relative")
        if (c := dataset("sensor_combined")) is not None else None)
    if acc_read is not None and acc_read[0].size > 1:
        ta, av = acc_read
        order = np.argsort(ta)
        others["acc"] = np.column_stack([np.interp(t, ta[order], av[order, k]) for k in range(3)])
    stem = "" if name == "sensor_mag" else "magnetometer_ga"
    columns = {k: f"{name}.{a if not stem else f'{stem}[{i}]'}" for i, (k, a) in enumerate(zip(MAG, "xyz"))}
    return _build(path, m, "gauss", f"PX4's {name} (gauss)", mag_units, columns, others,
                  [f"ULog topic {name}:{instance}", *notes], keep_rail)


def _read_dataflash(path: str, topic: str | None, mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    """An ArduPilot DataFlash log's ``MAG`` messages (``MAG[:N]``; ``MAG2``... in older logs): ``MagX..Z`` in
    milligauss (LogStructure.h: unit G, multiplier C = 1e-3), the rows ArduPilot marked unhealthy left out and
    counted, the IMU's accelerometer interpolated onto their times for the dip."""
    from optcal.data.dataflash import dataflash_instances, open_dataflash

    log = open_dataflash(path)
    name, _, inst = (topic or "MAG").upper().partition(":")
    digit = name[3:] if name.startswith("MAG") else None
    if digit is None or (digit and not digit.isdigit()) or (inst and not inst.isdigit()):
        raise InputError(f"--topic {topic!r}: a DataFlash log's magnetometer is read from MAG[:N] (MAG2... in older logs)")
    instance = int(inst) if inst else (int(digit) - 1 if digit else 0)
    mags = dataflash_instances(log, "MAG")
    d = mags.get(instance)
    if d is None or any(f"Mag{a}" not in d for a in "XYZ"):
        raise InputError(f"{path}: no DataFlash MAG instance {instance} (logged: "
                         f"{', '.join(f'MAG:{i}' for i in sorted(mags)) or 'none'}); choose one with --topic MAG:N")
    key = "TimeUS" if "TimeUS" in d else "TimeMS"
    t = d[key] * (1e-6 if key == "TimeUS" else 1e-3)
    m = np.column_stack([d[f"Mag{a}"] for a in "XYZ"])
    exclusions: dict[str, int] = {}
    if "Health" in d and (sick := d["Health"] < 1).any():  # LogStructure.h: Health, true if the compass is considered healthy
        exclusions["DataFlash MAG rows with Health=0 (ArduPilot judged the compass unhealthy)"] = int(sick.sum())
        t, m = t[~sick], m[~sick]
    others: dict[str, NDArray] = {"t": t}
    imu = dataflash_instances(log, "IMU").get(0)
    if imu is not None and t.size and all(f"Acc{a}" in imu for a in "XYZ"):
        ta = imu["TimeUS"] * 1e-6 if "TimeUS" in imu else imu["TimeMS"] * 1e-3
        order = np.argsort(ta)
        others["acc"] = np.column_stack([np.interp(t, ta[order], imu[f"Acc{a}"][order]) for a in "XYZ"])
    samples = _build(path, m, "mgauss", "ArduPilot's MAG (milligauss, LogStructure.h)", mag_units,
                     {k: f"MAG.Mag{a}" for k, a in zip(MAG, "XYZ")}, others,
                     [f"DataFlash MAG:{instance} ({', '.join(f'MAG:{i}' for i in sorted(mags))} logged; --topic MAG:N)"], keep_rail)
    samples.exclusions.update(exclusions)
    return samples


#: The ROS message of a magnetometer (``magnetic_field`` in tesla, REP 145) and the IMU's.
ROS_MAG_TYPE: str = "sensor_msgs/msg/MagneticField"
ROS_IMU_TYPE: str = "sensor_msgs/msg/Imu"
#: An IMU sample is joined to a magnetometer sample when their stamps are at most this share of the IMU's median
#: period apart (the nearest of two samples is then that sample, not one across a gap in the IMU's stream: farther,
#: the accelerometer's direction may belong to another orientation of a turning sensor).
ROS_JOIN_SHARE: float = 0.5


def _stamps(reader: Any, conns: list, fields: Any) -> NDArray[np.float64]:
    """Rows ``(stamp, *fields(message))`` of ``conns``' messages (the header stamp; the bag's time when it is zero)."""
    rows = []
    for conn, logtime, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        rows.append((stamp if stamp > 0 else logtime * 1e-9, *fields(msg)))
    return np.array(rows, dtype=float).reshape(len(rows), -1)


def _read_rosbag(path: str, kind: str, topic: str | None, mag_units: str | None,
        keep_rail: bool = False) -> MagSamples:
    """``sensor_msgs/MagneticField`` messages of one topic (tesla) and, where the bag has one ``sensor_msgs/Imu``
    topic, its accelerometer at the nearest stamps (:data:`ROS_JOIN_SHARE`; the samples without one counted)."""
    from optcal.data.readers import bag_topic, open_rosbag

    reader = open_rosbag(path, kind)
    try:
        mag_conns = bag_topic(reader, path, ROS_MAG_TYPE, topic)
        topic = mag_conns[0].topic
        imus = [c for c in reader.connections if c.msgtype == ROS_IMU_TYPE]
        try:
            mag = _stamps(reader, mag_conns,
                          lambda msg: (msg.magnetic_field.x, msg.magnetic_field.y, msg.magnetic_field.z))
            imu_topics = sorted({c.topic for c in imus})
            imu = (_stamps(reader, imus, lambda msg: (msg.linear_acceleration.x, msg.linear_acceleration.y,
                                                      msg.linear_acceleration.z))
                   if len(imu_topics) == 1 else None)
        except Exception as exc:
            raise InputError(f"{path}: the bag is truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc
    finally:
        reader.close()
    if not mag.size:
        raise InputError(f"{path}: topic {topic!r} has no messages")
    mag = mag[np.argsort(mag[:, 0], kind="stable")]
    others: dict[str, NDArray] = {"t": mag[:, 0]}
    notes = [f"ROS topic {topic} (sensor_msgs/MagneticField, tesla)"]
    columns = {k: f"{topic}.magnetic_field.{a}" for k, a in zip(MAG, "xyz")}
    if imu is not None and len(imu) >= 2:
        imu = imu[np.argsort(imu[:, 0], kind="stable")]
        j = np.clip(np.searchsorted(imu[:, 0], mag[:, 0]), 1, len(imu) - 1)
        j = np.where(np.abs(imu[j - 1, 0] - mag[:, 0]) <= np.abs(imu[j, 0] - mag[:, 0]), j - 1, j)
        gap = np.abs(imu[j, 0] - mag[:, 0])
        near = gap <= ROS_JOIN_SHARE * float(np.median(np.diff(imu[:, 0])))
        acc = np.where(near[:, None], imu[j, 1:4], np.nan)
        others["acc"] = acc
        imu_topic = imu_topics[0]
        columns.update({k: f"{imu_topic}.linear_acceleration.{a}" for k, a in zip(("ax", "ay", "az"), "xyz")})
        notes.append(f"accelerometer from {imu_topic} at the nearest stamps: {int(np.count_nonzero(~near))} of "
                     f"{len(mag)} magnetometer samples without an IMU sample within {ROS_JOIN_SHARE:g} of its period "
                     f"(largest gap {float(gap.max()):.3g} s), no accelerometer there")
    elif len(imu_topics) > 1:
        notes.append(f"several sensor_msgs/Imu topics ({', '.join(imu_topics)}): no accelerometer joined")
    return _build(path, mag[:, 1:4], "T", "sensor_msgs/MagneticField (tesla, REP 145)", mag_units, columns, others,
                  notes, keep_rail)


#: Exclusion reason of the rows a logger repeated until the magnetometer's next update (:mod:`optcal.data.held_samples`).
HELD_ROWS = "magnetometer rows repeating its last update (a slower magnetometer in a faster log)"
#: Exclusion reason of a held log's rows between two updates that hold axes of both (a torn copy).
TORN_ROWS = "magnetometer rows holding axes of two updates (a logger's torn copy between them)"


def drop_held(samples: MagSamples, keep: bool = False) -> MagSamples:
    """``samples`` with one row per magnetometer update where the logger repeated each value until the next
    (:func:`optcal.data.held_samples.held_runs`), the repeats counted and said; with ``keep`` every row, said."""
    from dataclasses import replace

    from optcal.data.held_samples import held_runs

    held = held_runs(samples.m)
    if held is None:
        return samples
    note = held.describe("magnetometer", "--keep-mag-repeats", kept=keep)
    if keep:
        return replace(samples, notes=[*samples.notes, note])
    rows = held.first
    torn = {TORN_ROWS: int(held.torn.size)} if held.torn.size else {}
    pick = (lambda a: None if a is None else a[rows])
    return replace(samples, m=np.ascontiguousarray(samples.m[rows]), acc=pick(samples.acc), gyro=pick(samples.gyro),
                   t=pick(samples.t), temp=pick(samples.temp), current=pick(samples.current),
                   throttle=pick(samples.throttle), exclusions={**samples.exclusions, HELD_ROWS: held.n_repeats, **torn},
                   notes=[*samples.notes, note])


def read_mag(path: str | Path, *, columns: str | dict[str, str] | None = None, topic: str | None = None,
             mag_units: str | None = None, keep_rail: bool = False, keep_repeats: bool = False,
             keep_spikes: bool = False) -> MagSamples:
    """Read a magnetometer's samples (module docstring).

    Parameters
    ----------
    path : str or Path
        A delimited text file, MAT-file, netCDF-4/HDF5 file, PX4 ULog or ROS 1/2 bag (``sensor_msgs/MagneticField``).
    columns : str or dict, optional
        ``--columns mx=NAME,my=NAME,mz=NAME`` (names or 1-based positions; ``ax=...`` for the accelerometer).
    topic : str, optional
        The magnetometer's variable of a container, the ULog topic (``sensor_mag:1``) or the bag's MagneticField topic.
    mag_units : str, optional
        The units (``--mag-units``), instead of the file's word or the decision from the magnitude.
    keep_rail : bool
        Keep the samples with an axis at the converter's rail (:func:`mag_rail`; left out and counted by default).
    keep_repeats : bool
        Keep every row where the logger repeats each magnetometer value until its next update (:func:`drop_held`;
        by default one row per update, the repeats counted).
    keep_spikes : bool
        Keep the samples that leave both neighbours by more than a turning field moves
        (:func:`optcal.families.mag.spikes.drop_spikes`; left out and counted by default).

    Raises
    ------
    InputError
        No magnetometer found, or a file optcal cannot read.
    """
    from optcal.families.mag.spikes import drop_spikes

    held = drop_held(_read_any_mag(str(path), columns, topic, mag_units, keep_rail), keep_repeats)
    return drop_spikes(held, keep_spikes)


def _read_any_mag(p: str, columns: str | dict[str, str] | None, topic: str | None, mag_units: str | None,
                  keep_rail: bool) -> MagSamples:
    from optcal.data.containers import container_type
    from optcal.data.readers import detect_file_type

    if not Path(p).exists():
        raise InputError(f"{p}: no such file")
    kind = detect_file_type(p)
    if kind == "csv" and (container := container_type(p)) is not None:
        return _read_container(p, container, topic, mag_units, keep_rail)
    if kind == "csv":
        return _read_text(p, parse_columns_option(columns) if isinstance(columns, str) or columns else {}, mag_units,
                          keep_rail)
    if kind == "ulog":
        return _read_ulog(p, topic, mag_units, keep_rail)
    if kind in ("ros1 bag", "ros2 bag"):
        return _read_rosbag(p, kind, topic, mag_units, keep_rail)
    if kind == "dataflash":
        return _read_dataflash(p, topic, mag_units, keep_rail)
    raise InputError(f"{p}: the magnetometer is read from text, MAT/netCDF/HDF5 and ULog files, not a {kind} yet; "
                     f"export its mx, my, mz columns to CSV")
