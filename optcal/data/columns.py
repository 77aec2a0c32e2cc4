"""Column names: optcal's canonical names, the names files use for them, and the layouts of unnamed columns.

Part of the *read* step (:mod:`optcal.data.readers`).  Column names are matched
case-insensitively after removing a unit word (``acc_x_counts`` → ``acc_x`` in counts,
``t_s`` → ``t`` in seconds, ``gyr_x`` → ``gx``): exactly (:data:`ALIASES`), then by the end
of a longer name (``field.linear_acceleration.x``, ``imu_acc_x``: :func:`resolve_columns`).
``--columns ax=ACC1,ay=ACC2,...`` (:func:`parse_columns_option`) maps any other names, or
1-based positions.

Some columns have names that do not settle their roles: the fields of a file without a
header, and ``tx, ty, tz`` (an acceleration in some loggers, a translation in others).  They
are read in the common layout, and the candidates are recorded as :class:`ColumnRoles`; the
evidence (:mod:`optcal.data.evidence`) then says which triple is the accelerometer, and the
decisions (:mod:`optcal.data.decisions`) read them so, or refuse, naming ``--columns``.
"""

from __future__ import annotations

import re
from pathlib import Path
from dataclasses import dataclass
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from optcal.core.units import UNIT_ALIASES
from optcal.errors import InputError

#: optcal's column names: time, accelerometer, gyro, temperature, and the pose-table-only
#: ``sigma`` (noise of each pose mean) and ``n_samples`` (samples averaged per pose).
CANONICAL: tuple[str, ...] = ("t", "ax", "ay", "az", "gx", "gy", "gz", "temp", "sigma", "n_samples")
ACC: tuple[str, str, str] = ("ax", "ay", "az")
GYRO: tuple[str, str, str] = ("gx", "gy", "gz")

#: Normalised column names recognised for each canonical column (after a unit word is removed).
ALIASES: dict[str, tuple[str, ...]] = {
    "t": ("t", "time", "timestamp", "timestamps", "stamp", "time_stamp", "sec", "seconds", "elapsed",
          "t_idx", "t_header", "t_sample", "t_host", "time_sample", "timestamp_sample", "header_stamp",
          "host_time", "sensor_time", "time_idx", "epoch"),
    "temp": ("temp", "temperature", "tmp", "imu_temp", "imu_temperature"),
    "sigma": ("sigma", "noise", "std_mean"),
    "n_samples": ("n_samples", "samples", "nsamples", "count"),
}
for _axis in "xyz":
    ALIASES["a" + _axis] = tuple(
        f.format(_axis)
        for f in ("a{}", "acc{}", "acc_{}", "accel_{}", "accel{}", "accelerometer_{}", "accelerometer{}", "a_{}",
                  "acceleration_{}", "acceleration{}", "linear_acceleration_{}", "linear_acc_{}", "lin_acc_{}",
                  "accelerometer_m_s2_{}", "a_rs_s_{}")  # EuRoC's and Kalibr's a_RS_S_x: sensor S, in S
    )
    ALIASES["g" + _axis] = tuple(
        f.format(_axis)
        for f in ("g{}", "gyr{}", "gyr_{}", "gyro_{}", "gyro{}", "gyroscope_{}", "gyroscope{}", "omega_{}", "omega{}",
                  "w{}", "w_{}", "angular_velocity_{}", "angular_velocity{}", "angular_rate_{}", "ang_vel_{}",
                  "angvel_{}", "gyro_rad_{}", "w_rs_s_{}")  # EuRoC's and Kalibr's w_RS_S_x
    )
#: The magnetometer's canonical names (read by :mod:`optcal.families.mag.samples`, not by the
#: accelerometer's decisions) and the names files use for them, after a unit word is removed
#: (``mag_x_uT`` → ``mag_x``).
MAG: tuple[str, str, str] = ("mx", "my", "mz")
MAG_ALIASES: dict[str, tuple[str, ...]] = {
    "m" + _axis: tuple(
        f.format(_axis)
        for f in ("m{}", "m_{}", "mag{}", "mag_{}", "magn_{}", "magnt_{}", "magnetometer_{}", "magnetometer{}",
                  "magnetic_{}", "magnetic_field_{}", "magnetic_density_{}", "compass_{}", "compass{}", "b{}", "b_{}",
                  "magnetic_field{}", "field_{}")
    )
    for _axis in "xyz"
}
#: Aliases of the sensors' axes and the temperature this long or longer are also recognised at the end
#: of a longer name, after a prefix (``field.linear_acceleration.x`` of a ``rostopic echo -p`` dump,
#: ``imu_acc_x``, ``board_temperature``); shorter ones (``ax``, ``w_x``, ``a_x``) only as the whole name.
SUFFIX_MIN_CHARS: int = 5
#: Time names recognised at the end of a longer name (``field.header.stamp``): a message header's stamp.
SUFFIX_TIME_ALIASES: tuple[str, ...] = ("header_stamp",)
#: Names of an accelerometer triple only when the data say acceleration (``tx, ty, tz``: some
#: loggers' acceleration, others' translation): see :class:`ColumnRoles`.
CONDITIONAL_ACC_ALIASES: tuple[str, ...] = ("t{}", "t_{}")
#: Names of a sample-index column (time then comes from --rate or the file header).  ``count`` and ``samples``
#: are also a pose table's per-pose sample counts: which one is decided from the values (an index steps by 1 a
#: row; a pose's count of averaged samples does not), as PicoQuake's ``count,a_x,...`` recording needs.
INDEX_ALIASES: tuple[str, ...] = ("index", "idx", "sample", "samples", "sample_index", "n_samples", "counter", "n",
                                  "count")

#: Time unit words and their factor to seconds.
TIME_UNITS: dict[str, float] = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: Gyro unit words at the end of column names (``gx_dps``, ``gyro_x_rad``), and the units they state.  Column
#: names use words (``deg``, ``rad``, ``radps``) that are not spellings of ``--gyro-units``
#: (:data:`optcal.core.units.UNIT_ALIASES`), and no ``/``.
GYRO_UNIT_WORDS: dict[str, str] = {
    "dps": "deg/s", "deg_s": "deg/s", "degs": "deg/s", "deg": "deg/s",
    "rad_s": "rad/s", "rads": "rad/s", "radps": "rad/s", "rad": "rad/s",
    # a unit written with a negative power (EuRoC's and Kalibr's ``[rad s^-1]``)
    "rad_s_1": "rad/s", "deg_s_1": "deg/s",
    "counts": "counts", "lsb": "counts", "raw": "counts",
}
TEMP_UNITS: tuple[str, ...] = ("c", "degc", "deg_c", "celsius")
_UNIT_WORDS = sorted(
    set(UNIT_ALIASES["accelerometer"]) | set(TIME_UNITS) | set(GYRO_UNIT_WORDS) | set(TEMP_UNITS) | {"m_s_2"},
    key=len,
    reverse=True,
)
#: Keys of a metadata line before the header that give the sampling rate in Hz.
RATE_KEYS: tuple[str, ...] = ("fs", "rate", "sample_rate", "sampling_rate", "sampling_rate_hz", "rate_hz", "frequency", "freq",
                             "data_rate", "output_data_rate", "odr")
#: A rate stated inside a metadata value as ``NAME = NUMBER Hz`` among other settings (PicoQuake's
#: ``# Config: data_rate = 2000.0 Hz, filter = 488 Hz, ...``): the NAME must be a :data:`RATE_KEYS` key and the unit Hz.
RATE_SETTING = re.compile(r"(?:^|[,;]\s*)([A-Za-z_][\w ]*?)\s*[=:]\s*([0-9]+(?:\.[0-9]*)?(?:[eE][-+]?[0-9]+)?)\s*Hz\b")

#: The ``--columns`` value that makes optcal use no column as that name (``index=none``).
NO_COLUMN: str = "none"


@dataclass(frozen=True)
class ColumnRoles:
    """Columns whose names do not settle their roles, read in the common layout until the evidence does.

    Attributes
    ----------
    triples : tuple of (str, str, str)
        The file's names (``#N`` for the N-th field of a file without a header) of each
        candidate triple, in file order.
    acc : int
        The triple read as the accelerometer as read (the common layout); with two triples the
        other one is read as the gyroscope.
    layout : str
        The layout as read, for the reason (``"t ax ay az gx gy gz"``).
    conditional : bool
        The one triple is read as the accelerometer only when the data say acceleration
        (``tx, ty, tz``); otherwise the file is refused, naming ``--columns``.
    """

    triples: tuple[tuple[str, str, str], ...]
    acc: int = 0
    layout: str = ""
    conditional: bool = False

    def positions(self, k: int) -> str:
        """``columns 5-7`` or ``columns tx, ty, tz``: triple ``k`` as the reasons name it."""
        names = self.triples[k]
        if all(n.startswith("#") for n in names):
            return f"columns {names[0][1:]}-{names[2][1:]}"
        return "columns " + ", ".join(names)

    def columns_option(self, k: int, time: str | None) -> str:
        """The ``--columns`` value that reads triple ``k`` as the accelerometer (and the other as the gyroscope)."""
        def ref(name: str) -> str:
            return name[1:] if name.startswith("#") else name

        items = [] if time is None else [f"t={ref(time)}"]
        items += [f"{c}={ref(n)}" for c, n in zip(ACC, self.triples[k])]
        if len(self.triples) == 2:
            items += [f"{c}={ref(n)}" for c, n in zip(GYRO, self.triples[1 - k])]
        return ",".join(items)


def parse_columns_option(columns: str | dict[str, str] | None) -> dict[str, str]:
    """Parse ``"ax=acc1,ay=acc2,t=time"`` (names, or 1-based positions) into {canonical: file column}.

    A value of :data:`NO_COLUMN` (``"t=none"``, ``"index=none"``) keeps optcal from taking any
    column as that name (a recognised column is then left unused).
    """
    if columns is None or columns == "":
        return {}
    if isinstance(columns, dict):
        pairs = [(str(k), str(v)) for k, v in columns.items()]
    else:
        pairs = []
        for item in str(columns).split(","):
            if not item.strip():
                continue
            if "=" not in item:
                raise InputError(
                    f"columns item {item.strip()!r} is not NAME=COLUMN; write e.g. "
                    "ax=acc_x_counts,ay=acc_y_counts,az=acc_z_counts, or by 1-based position t=1,ax=2,ay=3,az=4"
                )
            k, v = item.split("=", 1)
            pairs.append((k.strip(), v.strip()))
    out = {}
    for k, v in pairs:
        if k not in CANONICAL and k != "index" and k not in MAG:  # mx, my, mz: read by --sensor mag
            raise InputError(f"columns: unknown name {k!r}; use {', '.join(CANONICAL)}, index, or mx, my, mz")
        if k in ACC and v.lower() == NO_COLUMN:
            raise InputError(f"columns {k}={v}: the accelerometer columns cannot be ignored; map {k} to a column")
        out[k] = v
    return out


def normalise_name(name: str) -> str:
    """Lower case, every run of other characters than letters and digits one ``_``, none at the ends.

    The micro sign (U+00B5) and the Greek mu (U+03BC) are written ``u`` first, as in ASCII unit words: phyphox's
    ``Magnetic field x (µT)`` is ``magnetic_field_x_ut``, a name and its unit (before, ``µ`` was dropped and the
    ``t`` left matched no unit word, so the column matched no magnetometer alias).
    """
    text = str(name).lower().replace("\u00b5", "u").replace("\u03bc", "u")
    return re.sub(r"[^0-9a-z]+", "_", text).strip("_")


#: A word boundary written by case alone (``scaledAccelX``: MicroStrain's MSCL channel names, a prefix joined to
#: ``Accel`` and the axis ``X`` without a separator): a lower-case letter or a digit followed by a capital.
CAMEL_BOUNDARY = re.compile(r"(?<=[a-z0-9])(?=[A-Z])")


def camel_words(name: str) -> str:
    """``name`` normalised with its case boundaries as separators (``scaledAccelX`` → ``scaled_accel_x``).

    Used only to match the end of a longer name (:data:`SUFFIX_MIN_CHARS`), after the whole name matched nothing:
    a prefix joined by case (``scaled``, ``est``) is a prefix as ``imu_`` is.
    """
    return normalise_name(CAMEL_BOUNDARY.sub("_", str(name)))


def strip_unit(norm: str) -> tuple[str, str | None]:
    """A normalised name without its trailing unit word, and that word (or ``None``)."""
    for word in _UNIT_WORDS:
        key = normalise_name(word)
        if key and norm.endswith("_" + key) and len(norm) > len(key) + 1:
            return norm[: -len(key) - 1], key
    return norm, None


#: Unit words that make a bare axis name (``x``, ``y``, ``z``: phyphox's ``X (m/s^2)``) an accelerometer's: an
#: acceleration's units (counts say nothing of the quantity, so not them).
AXIS_ACC_UNIT_WORDS: frozenset[str] = frozenset(
    normalise_name(w) for w, u in UNIT_ALIASES["accelerometer"].items() if u != "counts") | {"m_s_2"}
#: Unit words that make a bare axis name a gyroscope's (``X (rad/s)``): an angular rate's units.
AXIS_GYRO_UNIT_WORDS: frozenset[str] = frozenset(w for w, u in GYRO_UNIT_WORDS.items() if u != "counts")

#: A gyro column's stem and a word naming a rotation, not an axis (NXP's IMU logger ``GyroR GyroP GyroY``,
#: ``gyro_roll``, AndroSensor's ``GYROSCOPE Yaw``): the axis it turns about is the logger's convention (roll about x
#: in aerospace's, about y in Android's), so no axis is read from the name.
ROTATION_NAME = re.compile(r"^(?:gyroscope|gyro|gyr)_?(roll|pitch|yaw|r|p|y)$")


def partial_gyro(column_map: dict[str, str], names: list[str], given: dict[str, str]) -> str | None:
    """Why gyro columns found by name for some axes only are not read (``None`` when all three or none are).

    A gyro is three axes; one or two names matched (``GyroY`` of ``GyroR GyroP GyroY``, where ``Y`` is the yaw)
    are no gyro, and reading them as its axes would be a guess.  ``given`` (``--columns``) maps them at the user's
    word.
    """
    have = [c for c in GYRO if c in column_map]
    if not have or len(have) == len(GYRO) or any(c in given for c in GYRO):
        return None
    words = {n: m.group(1)[0] for n in names if (m := ROTATION_NAME.match(strip_unit(normalise_name(n))[0]))}
    said = f"{', '.join(f'{c}←{column_map[c]}' for c in have)} found, no {', '.join(c for c in GYRO if c not in have)}"
    if len(set(words.values())) == 3:  # roll, pitch and yaw: the axes are the logger's convention
        r, p, y = (next(n for n, w in words.items() if w == k) for k in "rpy")
        return (f"gyro not read: columns {', '.join(words)} name the rotation (roll, pitch, yaw), not the axes ({said}); "
                f"which axis each turns about is the logger's convention (roll about x in aerospace's, about y in "
                f"Android's): --columns gx={r},gy={p},gz={y} reads them so")
    return f"gyro not read: a gyro has three axes ({said}); --columns gx=NAME,gy=NAME,gz=NAME maps them"


class ResolvedColumns(NamedTuple):
    """What :func:`resolve_columns` found.

    Attributes
    ----------
    column_map : dict
        canonical → file column.
    unit_words : dict
        canonical → the unit word found in its name (or None).
    roles : ColumnRoles or None
        An accelerometer read from names that say acceleration only with the data's word
        (:data:`CONDITIONAL_ACC_ALIASES`).
    """

    column_map: dict[str, str]
    unit_words: dict[str, str | None]
    roles: ColumnRoles | None


def _canonical_of(candidate: str, suffix: bool) -> str | None:
    """The canonical name (or ``index_or_count``) of a normalised name, whole or by its end."""
    if not suffix:
        if candidate in INDEX_ALIASES:
            return "index_or_count"
        return next((c for c, al in ALIASES.items() if candidate in al), None)
    if any(candidate.endswith("_" + a) for a in SUFFIX_TIME_ALIASES):
        return "t"
    for canon, aliases in ALIASES.items():
        if canon in ACC or canon in GYRO or canon == "temp":
            if any(len(a) >= SUFFIX_MIN_CHARS and candidate.endswith("_" + a) for a in aliases):
                return canon
    return None


def resolve_columns(names: list[str], mapping: dict[str, str]) -> ResolvedColumns:
    """Match the file's column names to canonical names.

    ``mapping`` values are column names, or 1-based positions (``"2"``) when no column has
    that name.  Names are matched whole first, then by their end (:data:`SUFFIX_MIN_CHARS`),
    then, for an accelerometer no name gave, by :data:`CONDITIONAL_ACC_ALIASES`.
    """
    column_map: dict[str, str] = {}
    units: dict[str, str | None] = {}
    ignored = {canon for canon, col in mapping.items() if col.lower() == NO_COLUMN and col not in names}
    # "samples" may be taken as index or as n_samples: ignoring one ignores the column for both
    if ignored & {"index", "n_samples"}:
        ignored |= {"index", "n_samples", "index_or_count"}
    given: dict[str, str] = {}
    for canon, col in mapping.items():
        if canon in ignored:
            continue
        if col not in names:
            if col.isdigit() and 1 <= int(col) <= len(names):
                col = names[int(col) - 1]
            else:
                raise InputError(
                    f"columns {canon}={col}: there is no column {col!r} "
                    f"(the file has: {', '.join(names)}; or give a 1-based position 1..{len(names)})"
                )
        if col in given:
            where = f"column {mapping[canon]} ({col!r})" if col != mapping[canon] else f"column {col!r}"
            raise InputError(
                f"columns: {given[col]} and {canon} both map to {where}; give each name its own column"
            )
        given[col] = canon
        column_map[canon] = col
        units[canon] = strip_unit(normalise_name(col))[1]
    for suffix in (False, True):
        taken = set(column_map.values())
        for col in names:
            if col in taken:
                continue
            norm = normalise_name(col)
            found: str | None = None
            unit: str | None = None
            forms = [norm]
            if suffix and (camel := camel_words(col)) != norm:
                forms.append(camel)  # a prefix joined by case (scaledAccelX): matched by its end, after the name
            for candidate, unit in ((c, u) for form in forms for c, u in ((form, None), strip_unit(form))):
                found = _canonical_of(candidate, suffix)
                if found is not None:
                    break
            if found is None or found in ignored:
                continue
            if found == "index_or_count":
                # "n_samples"/"samples" is a per-pose count in a pose table and a sample index in a
                # recording; which one is decided from the values in source_from_columns.
                found = "index"
            if found not in column_map:
                column_map[found] = col
                units[found] = unit
                taken.add(col)
    for triple, words in ((ACC, AXIS_ACC_UNIT_WORDS), (GYRO, AXIS_GYRO_UNIT_WORDS)):
        if not any(c in column_map for c in triple):
            by_unit = _axes_by_unit(names, set(column_map.values()), words)
            if by_unit is not None:
                for canon, (col, word) in zip(triple, by_unit):
                    column_map[canon] = col
                    units[canon] = word
    if all(c in column_map for c in ACC) and not any(c in column_map for c in GYRO):
        # ``g_x`` is also an acceleration in g; beside an accelerometer named ``a_x, a_y, a_z`` (PicoQuake's
        # ``count,a_x,a_y,a_z,g_x,g_y,g_z``) the acceleration has its columns, so ``g_x, g_y, g_z`` are the gyro's
        stems = {strip_unit(normalise_name(column_map[c]))[0] for c in ACC}
        free = {strip_unit(normalise_name(c))[0]: c for c in names if c not in set(column_map.values())}
        if stems == {"a_x", "a_y", "a_z"} and all(f"g_{a}" in free for a in "xyz"):
            for canon, axis in zip(GYRO, "xyz"):
                column_map[canon] = free[f"g_{axis}"]
                units[canon] = strip_unit(normalise_name(free[f"g_{axis}"]))[1]
    roles = None
    if not any(c in column_map for c in ACC):
        conditional = _conditional_triple(names, set(column_map.values()))
        if conditional is not None:
            for canon, col in zip(ACC, conditional):
                column_map[canon] = col
                units[canon] = strip_unit(normalise_name(col))[1]
            roles = ColumnRoles((conditional,), 0, " ".join(conditional), conditional=True)
    return ResolvedColumns(column_map, units, roles)


def _axes_by_unit(names: list[str], taken: set[str], words: frozenset[str]) -> list[tuple[str, str]] | None:
    """Columns named by a bare axis and a unit that says what they measure (phyphox's ``X (m/s^2)``): the x, y
    and z columns, free, with one unit word among ``words`` (:data:`AXIS_ACC_UNIT_WORDS`,
    :data:`AXIS_GYRO_UNIT_WORDS`), each with that word; else ``None``."""
    found: list[tuple[str, str]] = []
    for axis in "xyz":
        hit = next(((c, w) for c in names if c not in taken
                    for b, w in [strip_unit(normalise_name(c))] if b == axis and w in words), None)
        if hit is None:
            return None
        found.append(hit)
    return found if len({w for _, w in found}) == 1 else None


def _conditional_triple(names: list[str], taken: set[str]) -> tuple[str, str, str] | None:
    """The columns named by :data:`CONDITIONAL_ACC_ALIASES` for x, y and z, when all three are there and free."""
    for pattern in CONDITIONAL_ACC_ALIASES:
        found = []
        for axis in "xyz":
            col = next((c for c in names if c not in taken and strip_unit(normalise_name(c))[0] == pattern.format(axis)), None)
            if col is None:
                break
            found.append(col)
        if len(found) == 3:
            return found[0], found[1], found[2]
    return None


# ----------------------------------------------------------------------------- files without a header
#: Loggers' layouts of a file without a header, by the number of fields besides a time column:
#: an accelerometer, or an accelerometer and a gyroscope (imu_tk's ``t ax ay az``, mikoff's
#: ``ax ay az gx gy gz``), or those and a magnetometer (a 9-axis logger's ``t ax ay az gx gy gz mx my
#: mz``, as imu_tk's ROS node writes ``imu_data.txt``: the last triple is not read, and the reason says
#: so).  Which of the first two triples is the accelerometer is then decided from the data.
HEADERLESS_TRIPLES: tuple[int, ...] = (3, 6, 9)


def increasing_column(col: NDArray[np.float64]) -> bool:
    """A time column: its finite values never decrease, and the last exceeds the first."""
    v = col[np.isfinite(col)]
    return v.size >= 2 and bool(np.all(np.diff(v) >= 0)) and bool(v[-1] > v[0])


def time_column_at(columns: Sequence[NDArray[np.float64]]) -> int | None:
    """The place of a headerless layout's time column: the first field when it increases (:func:`increasing_column`),
    or else the last; ``None`` when neither does."""
    if increasing_column(columns[0]):
        return 0
    if increasing_column(columns[-1]):
        return len(columns) - 1
    return None


def _first_decrease(col: NDArray[np.float64]) -> str:
    """`` (column 1 goes back at data row 6: 59022 after 59231)``, or ``""`` when its finite values never decrease."""
    rows = np.flatnonzero(np.isfinite(col))
    back = np.flatnonzero(np.diff(col[rows]) < 0)
    if back.size == 0:
        return ""
    i, j = rows[back[0]], rows[back[0] + 1]
    return f" (column 1 goes back at data row {j + 1}: {col[j]:.10g} after {col[i]:.10g}, {back.size} such step(s))"


#: A stamp split in two fields, whole seconds and the fraction of the second as an integer count of its unit:
#: ROS's ``header.stamp`` (``secs, nsecs``), C's ``struct timespec``/``timeval`` (ns, µs), a logger's ``s, ms``.
#: The fraction's unit is the one whose range [0, 10^k) its values fill: a count of ns reaches past 10^6 within
#: any second sampled more than a few times, µs past 10^3, ms stays below 10^3.
SUBSECOND_UNITS: tuple[tuple[float, str], ...] = ((1e9, "ns"), (1e6, "us"), (1e3, "ms"))
#: The reason's words for such a stamp (its second field is then read, as the time's fraction).
JOINED_STAMP: str = "columns 1-2 one time stamp"


def joined_stamp_note(sub_unit: str) -> str:
    """The reason's words for a stamp split in whole seconds and a count of ``sub_unit`` (:func:`split_stamp`)."""
    return f"; {JOINED_STAMP}, whole seconds and {sub_unit} of the second (ROS's secs, nsecs)"


def split_stamp(columns: list[NDArray[np.float64]]) -> tuple[NDArray[np.float64], str] | None:
    """The time of a stamp written in its first two fields as whole seconds and a sub-second count, or ``None``.

    The two fields are one stamp when both are integers, the second lies in [0, 10^k) of its unit
    (:data:`SUBSECOND_UNITS`), the seconds never decrease and step where the fraction wraps (it goes back only
    when the seconds advance), and the seconds alone repeat (so they are no time column on their own).

    Returns
    -------
    (time in the seconds' unit, the fraction's unit), or ``None``.
    """
    if len(columns) < 3:
        return None
    secs, frac = columns[0], columns[1]
    ok = np.isfinite(secs) & np.isfinite(frac)
    s, f = secs[ok], frac[ok]
    if s.size < 3 or np.any(s != np.round(s)) or np.any(f != np.round(f)) or f.min() < 0:
        return None
    ds, df = np.diff(s), np.diff(f)
    if np.any(ds < 0) or not np.any(ds == 0) or np.any((df < 0) & (ds == 0)):
        return None
    top = float(f.max())
    unit = next(((scale, name) for scale, name in SUBSECOND_UNITS if scale / 1000 <= top < scale), None)
    if unit is None:
        return None
    t = np.full(secs.shape, np.nan)
    t[ok] = s + f / unit[0]
    return (t, unit[1]) if increasing_column(t) else None


def _tag_column(col: NDArray[np.float64]) -> bool:
    """Whether a field holds one whole number in every row that has it (a label such as a sensor's type number;
    a line cut short at the file's end leaves it empty), in most rows."""
    values = col[np.isfinite(col)]
    return bool(2 * values.size > col.size > 1 and values[0] == np.round(values[0]) and np.all(values == values[0]))


def _field_names(fields: list[int]) -> tuple[str, str, str]:
    """``("#5", "#6", "#7")``: three 0-based fields as a headerless file's column names."""
    return f"#{fields[0] + 1}", f"#{fields[1] + 1}", f"#{fields[2] + 1}"


def sensor_word(text: str) -> str | None:
    """The sensor a word in a file's rows names (``acceleration``: ``"acc"``, ``gyroscope``: ``"gyro"``,
    ``magnetometer``: ``"mag"``; by its first letters, case and punctuation aside), or ``None``."""
    word = re.sub(r"[^a-z]", "", text.lower())
    return next((sensor for prefix, sensor in (("acc", "acc"), ("gyr", "gyro"), ("mag", "mag"))
                 if word.startswith(prefix)), None)


@dataclass(frozen=True)
class HeaderlessColumns:
    """How the fields of a file without a header are read (:func:`headerless_mapping`).

    Attributes
    ----------
    mapping : dict
        canonical → 1-based position.
    reason : str
        The columns' reason, as printed.
    roles : ColumnRoles or None
        The candidates of two triples, left to the evidence.
    joined_stamp : str or None
        The sub-second unit (``"ns"``, ``"us"``, ``"ms"``) where fields 1-2 are one time stamp split in whole
        seconds and that count (:func:`split_stamp`; field 2 is then read, as the time's fraction), else ``None``.
    """

    mapping: dict[str, str]
    reason: str
    roles: ColumnRoles | None
    joined_stamp: str | None = None


def headerless_mapping(
    path: str, columns: list[NDArray[np.float64]], described: str, words: dict[int, str] | None = None
) -> HeaderlessColumns:
    """Canonical columns of a file without a header, by the common layout of its width.

    A time column is the first (or else the last) field when it increases and 3, 6 or 9 fields
    remain, or the first two fields when they are one stamp split in whole seconds and a sub-second count
    (:func:`split_stamp`; ``columns[0]`` is then replaced, in the list given, by their sum in seconds); the first three of the others are the accelerometer, the next three the gyroscope
    (a ninth-axis triple after them, a magnetometer's, is left unread and named in the reason),
    and with two triples which one is the accelerometer is left to the evidence (:class:`ColumnRoles`).  Leading
    fields holding no number in any row are set aside; where the first one's text (``words``: a field's first
    non-numeric value) names a gyroscope (``gyroscope,411480,-0.29,0.04,0.14``: Variense VMU931's export), its one
    triple is the gyro's, and where it names a magnetometer the file is refused naming ``--sensor mag``.

    Returns
    -------
    HeaderlessColumns
        The mapping (canonical → 1-based position), the reason, the roles left to the evidence, and the split
        stamp's sub-second unit where fields 1-2 are read as one time.

    Raises
    ------
    InputError
        A width no common layout has, with the ``--columns`` that names them.
    """
    # a delimiter written after every line's last value (an Arduino loop's ``Serial.print(",")`` after each field)
    # leaves a last field that is empty in every row: it holds no number, so it is no column of the layout (said so)
    empty_tail = 0
    while len(columns) - empty_tail > 3 and not np.isfinite(columns[len(columns) - empty_tail - 1]).any():
        empty_tail += 1
    # a first field holding no number in any row (the quantity's word in every row: Variense VMU931's export,
    # "acceleration,411480,0.017,0.006,0.976") is no column of the layout either: set aside, said so; the positions
    # named stay the file's
    lead = 0
    while len(columns) - empty_tail - lead > 3 and not np.isfinite(columns[lead]).any():
        lead += 1
    full_width = len(columns)
    given = columns
    columns = columns[lead:full_width - empty_tail]
    width = len(columns)
    time_at: int | None = None
    joined = split_stamp(columns) if width - 2 in HEADERLESS_TRIPLES and not lead else None
    if joined is not None:
        # whole seconds and their fraction (ROS's secs, nsecs): one time column, the first field's place
        columns[0] = given[0] = joined[0]
        time_at = 0
    elif width - 1 in HEADERLESS_TRIPLES:
        time_at = time_column_at(columns)
    rest = [j for j in range(width) if j != time_at and not (joined is not None and j == 1)]
    pos = list(range(lead, lead + width))  # each field's 0-based place in the file
    tags: list[int] = []
    if len(rest) not in HEADERLESS_TRIPLES and joined is None and (keep := [j for j in range(width)
                                                                          if not _tag_column(columns[j])]):
        # fields holding one whole number in every row are labels, not axes (the Android IMU stream's sensor type
        # numbers: "683432.72, 3, ax, ay, az, 4, gx, gy, gz, 5, mx, my, mz"): an axis of a sensor, moved or not,
        # never reads one value over a whole recording; set aside, said so, where the layout fails with them
        tags = [pos[j] + 1 for j in range(width) if j not in keep]
        columns, pos, width = [columns[j] for j in keep], [pos[j] for j in keep], len(keep)
        time_at = None
        if width - 1 in HEADERLESS_TRIPLES:
            time_at = time_column_at(columns)
        rest = [j for j in range(width) if j != time_at]
    at = [p + 1 for p in pos] + list(range(pos[-1] + 2 if pos else lead + 1, lead + 5))  # 1-based, for the example
    example = (f"--columns t={at[0]},ax={at[1]},ay={at[2]},az={at[3]}" if width >= 4
               else f"--columns ax={at[0]},ay={at[1]},az={at[2]}")
    if time_at is None and tags and not increasing_column(columns[0]):
        example = f"--columns ax={at[0]},ay={at[1]},az={at[2]}"
    if joined is not None:  # the file's positions: the stamp's two fields, then the triples (t=1 reads both, readers)
        example = f"--columns t=1,ax={rest[0] + 1},ay={rest[1] + 1},az={rest[2] + 1}"
    if len(rest) not in HEADERLESS_TRIPLES:
        why = "fit no common layout"
        if width - 1 in HEADERLESS_TRIPLES:  # the layout with a time column, but neither end column increases
            why = (f"would be a time column and {width - 1} axes, but neither the first column nor the last "
                   f"increases{_first_decrease(columns[0])}")
        if tags:
            why += f" (columns {', '.join(map(str, tags))} set aside: one whole number in every row, a label)"
        raise InputError(
            f"{path}: the file has no header row ({described}), and {width} unnamed columns {why}; "
            f"name them by 1-based position, e.g. {example}"
        )
    canon: dict[str, int] = {} if time_at is None else {"t": time_at}
    word = sensor_word((words or {}).get(0, "")) if lead else None
    if word == "mag":
        raise InputError(f"{path}: column 1 reads {(words or {})[0]!r}: a magnetometer's log; optcal calibrate FILE "
                         "--sensor mag reads it")
    triples = GYRO if word == "gyro" and len(rest) == 3 else ACC + GYRO
    canon.update({c: j for j, c in zip(rest, triples)})
    mapping = {c: str(pos[j] + 1) for c, j in canon.items()}  # listed t, accelerometer, gyroscope
    what = " ".join(c for c, _ in sorted(canon.items(), key=lambda item: item[1]))
    roles = None
    if len(rest) >= 6:
        roles = ColumnRoles((_field_names([pos[j] for j in rest[0:3]]), _field_names([pos[j] for j in rest[3:6]])),
                            0, what)
    where = {None: "", 0: f"; column {pos[0] + 1} increases" if lead else "; the first column increases",
             width - 1: "; the last column increases"}[time_at]
    if tags:
        where += f"; columns {', '.join(map(str, tags))} hold one whole number in every row (a label): not read"
    if lead:
        said = f" ({(words or {})[0]!r}: {'the gyroscope' if triples == GYRO else 'a word'})" if words and 0 in words else ""
        where += f"; {'column 1 holds' if lead == 1 else f'columns 1-{lead} hold'} no number in any row{said}: not read"
    if joined is not None:
        where = joined_stamp_note(joined[1]) + ": column 1 holds their sum in seconds"
    if len(rest) == 9:
        where += f"; columns {pos[rest[6]] + 1}-{pos[rest[8]] + 1} not read: a 9-axis logger's magnetometer"
    if empty_tail:
        where += (f"; the last {empty_tail} of {full_width} fields empty in every row (a delimiter at each line's end): "
                  "not read")
    return HeaderlessColumns(mapping, (
        f"no header; {width} columns read as '{what}' (the common layout of {width} columns{where}); "
        f"name them by position to change it, e.g. {example}"
    ), roles, None if joined is None else joined[1])


# ----------------------------------------------------------------------------- Sensor Logger's export
#: Sensor Logger's CSV columns (tszheichoi/awesome-sensor-logger, UNITS.md): ``time`` in ns since 1970,
#: ``seconds_elapsed`` since the recording's start, and bare axes ``z, y, x`` whose quantity only the file's name says.
SENSOR_LOGGER_NAMES: frozenset[str] = frozenset(("time", "seconds_elapsed", "x", "y", "z"))
#: Its files of an accelerometer WITH gravity: TotalAcceleration (m/s²) and AccelerometerUncalibrated (g on iOS,
#: m/s² on Android: the norm tells them apart as for any file).
SENSOR_LOGGER_ACCELEROMETERS: tuple[str, ...] = ("totalacceleration", "accelerometeruncalibrated")
#: Its gyroscope files, in rad/s (UNITS.md).
SENSOR_LOGGER_GYROSCOPES: tuple[str, ...] = ("gyroscope", "gyroscopeuncalibrated")
#: Its magnetometer files, in µT (UNITS.md), read by ``optcal calibrate FILE --sensor mag``.
SENSOR_LOGGER_MAGNETOMETERS: tuple[str, ...] = ("magnetometer", "magnetometeruncalibrated")


def sensor_logger_mapping(names: list[str], path: str, sensor: str = "acc") -> tuple[dict[str, str], str] | None:
    """The columns of a Sensor Logger export, by its file's name; ``None`` for any other file.

    A resting accelerometer reads gravity, which is what a calibration fits; Sensor Logger's
    ``Accelerometer.csv`` is the acceleration *without* gravity (the user's motion only, UNITS.md), so it is
    refused, naming the files that hold gravity and the ``--columns`` that reads it anyway.  Its
    ``TotalAcceleration.csv`` and ``AccelerometerUncalibrated.csv`` map ``x, y, z`` to the accelerometer
    (``sensor="acc"``); its ``Gyroscope.csv`` (rad/s), read as a gyro file (``sensor="gyro"``), to the
    accelerometer's place, where :func:`optcal.data.readers.merge_gyro_file` reads a gyro file's axes; its
    ``Magnetometer.csv`` (µT), read by the magnetometer's reader (``sensor="mag"``), to ``mx, my, mz``.  The time
    is ``seconds_elapsed`` (seconds).

    Returns
    -------
    (mapping, reason) or None

    Raises
    ------
    InputError
        ``Accelerometer.csv`` read as the accelerometer: the acceleration without gravity.
    """
    if len(names) != len(SENSOR_LOGGER_NAMES) or {n.strip().lower() for n in names} != SENSOR_LOGGER_NAMES:
        return None
    stem = Path(path).stem
    key = re.sub(r"[^a-z]", "", stem.lower())
    by_name = {n.strip().lower(): n for n in names}
    mapping = {"t": by_name["seconds_elapsed"], "ax": by_name["x"], "ay": by_name["y"], "az": by_name["z"]}
    layout = "Sensor Logger's export (time, seconds_elapsed and bare axes)"
    if sensor == "mag":
        if key.startswith(SENSOR_LOGGER_MAGNETOMETERS):
            return ({"t": mapping["t"], "mx": mapping["ax"], "my": mapping["ay"], "mz": mapping["az"]},
                    f"{layout}: {stem} is the magnetometer, in µT")
        return None
    if sensor == "gyro":
        if key.startswith(SENSOR_LOGGER_GYROSCOPES):
            return mapping, f"{layout}: {stem} is the gyroscope, in rad/s"
        return None
    if key == "accelerometer":
        raise InputError(
            f"{path}: {layout}: {stem} holds the acceleration without gravity (the user's motion only; its UNITS.md), "
            "which no rest can calibrate: read TotalAcceleration.csv or AccelerometerUncalibrated.csv of the same "
            "recording, or --columns t=seconds_elapsed,ax=x,ay=y,az=z to read it anyway")
    if key.startswith(SENSOR_LOGGER_ACCELEROMETERS):
        return mapping, f"{layout}: {stem} is the accelerometer with gravity"
    return None


# ----------------------------------------------------------------------------- a column of words naming the sensor
#: Bare axes: their quantity is said only by a column of words in every row (Variense VMU931's headered export,
#: ``Attribute,Time stamp,x,y,z`` with ``Acceleration``, ``Gyroscope`` or ``Magnetometer`` in every row).
BARE_AXES: tuple[str, str, str] = ("x", "y", "z")


def attribute_mapping(
    names: list[str], words: dict[str, tuple[int, int, str]], n_rows: int, path: str, sensor: str = "acc"
) -> tuple[dict[str, str], str] | None:
    """The columns of a file whose bare ``x, y, z`` are named by a column of words in every row; ``None`` otherwise.

    The word names the triple (``acceleration``: the accelerometer; ``gyroscope``: the gyro's, a gyro-only log;
    ``magnetometer``: the magnetometer's, read by the magnetometer's reader, ``sensor="mag"``), a column named with
    ``time`` the time (its unit left to the time decision).  ``words`` are the file's columns with non-numeric
    cells: (count, first row, first value), as :class:`optcal.data.text.ParsedNumbers` counts them.

    Raises
    ------
    InputError
        The word names another sensor than the reader's (a magnetometer's log given to the accelerometer's
        commands, read by ``optcal calibrate FILE --sensor mag``; an accelerometer's or a gyroscope's given to
        the magnetometer's).
    """
    by_norm = {normalise_name(n): n for n in names}
    if not all(a in by_norm for a in BARE_AXES):
        return None
    axes = {by_norm[a] for a in BARE_AXES}
    column = next((n for n, (count, _, _) in words.items() if count == n_rows and n not in axes), None)
    if column is None:
        return None
    said = words[column][2]
    word = sensor_word(said)
    if word is None:
        return None  # another word (a session label): the axes' quantity is left to --columns
    if sensor == "mag" and word != "mag":
        reader = "optcal calibrate FILE" if word == "acc" else "optcal allan FILE --sensor gyro"
        raise InputError(f"{path}: column {column!r} reads {said!r}: not a magnetometer's log; {reader} reads it")
    if sensor != "mag" and word == "mag":
        raise InputError(f"{path}: column {column!r} reads {said!r}: a magnetometer's log; optcal calibrate FILE "
                         "--sensor mag reads it")
    triple = MAG if word == "mag" else ACC if word == "acc" else GYRO
    mapping = {c: by_norm[a] for c, a in zip(triple, BARE_AXES)}
    time = next((n for n in names if "time" in normalise_name(n)), None)
    if time is not None:
        mapping["t"] = time
    what = {"mag": "magnetometer", "acc": "accelerometer", "gyro": "gyroscope"}[word]
    return mapping, (f"bare axes x, y, z named by column {column!r} in every row ({said!r}: the {what}; Variense "
                     "VMU931's export)")
