"""The magnetometer's columns of a text file with no header, by the common layout of its width: time stamps, an
index, unit quaternions and a leading field of words set aside, a 9-axis logger's accelerometer told from its
gyroscope, and the ``--columns`` example of a width with no common layout."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import MAG, increasing_column, joined_stamp_note, sensor_word, split_stamp, time_column_at
from optcal.errors import InputError
from optcal.families.mag.columns import NORMAL_ZERO, TWO_AXES

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
        time_at = time_column_at(columns[:width])
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
