"""Containers engineers save: MATLAB MAT-files (level 5 and 7.3) and netCDF-4 / HDF5 files.

A container holds named variables, not columns.  This module finds the accelerometer's matrix
among them, its orientation, and the variables beside it (gyro, time, temperature), and
returns what the file states (a ``units`` attribute, a ``sampling_rate``) for the decisions
of :mod:`optcal.data.decisions` to weigh against the data, as any other reader does
(:mod:`optcal.data.readers` turns the result into its ``Source``).

* **Recognised** by their first bytes (:func:`container_type`): a MATLAB level-5 file begins
  with the text ``MATLAB 5.0 MAT-file``; an HDF5 file has the signature ``\\x89HDF\\r\\n\\x1a\\n``
  at offset 0 or after a user block of 512, 1024, 2048, ... bytes; a MATLAB 7.3 file is HDF5
  with a 512-byte MATLAB header (``MATLAB 7.3 MAT-file``); netCDF-4 is HDF5 with the
  ``_NCProperties`` attribute.  Level 5 is read by ``scipy.io.loadmat``; HDF5, MATLAB 7.3 and
  netCDF-4 by ``h5py`` (``pip install 'optcal[hdf5]'``), imported only when such a file is read.
* **Variables** are matched by their name (``acc*``, ``linear_acceleration``, ``gyr*``,
  ``angular_velocity``, ``w*``, ``time``, ``t``, ``timestamp``, ``temp*``, ``mag*``,
  ``magnetic*``: :data:`NAME_ROLES`; or a later word of it, ``static_gyr``: :data:`WORD_ROLES`) or, when the
  name says nothing, by their attributes
  (``units``, ``standard_name``, ``long_name``, ``description``).  A magnetometer is not an
  accelerometer: it is skipped and said so.
* **A matrix** with 3, 4, 6, 7, 9 or 10 axes (:data:`MATRIX_LAYOUTS`: ``ax ay az``, ``t ax ay az``,
  ``ax ay az gx gy gz``, ``t ax ... gz``, and those with a 9-axis logger's magnetometer last, not read) is read
  in either orientation: a 3 × 24 matrix is 24
  samples of 3 axes.  When both orientations are possible (a 3 × 3, a 4 × 6, ...) and no other
  variable tells the sample count, the file is refused with the flag that chooses:
  ``--topic NAME:rows`` (one sample per row) or ``--topic NAME:columns``.
* **Several candidate matrices** are refused, naming them and ``--topic NAME``.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.units import SECONDS_PER_TIME_UNIT
from optcal.errors import InputError

from optcal.data.container_kind import (  # recognising a container by its first bytes (every CSV read asks)
    HDF5 as HDF5,
    HDF5_SIGNATURE as HDF5_SIGNATURE,
    HDF5_SMALLEST_USER_BLOCK as HDF5_SMALLEST_USER_BLOCK,
    HDF5_SUFFIXES as HDF5_SUFFIXES,
    MAT5 as MAT5,
    MAT5_HEADER as MAT5_HEADER,
    MAT73 as MAT73,
    MAT73_HEADER as MAT73_HEADER,
    container_type as container_type,
)

NETCDF4 = "netCDF-4"
#: The file types of this module (what :func:`container_type` returns, before a netCDF-4 is told from HDF5).
CONTAINER_TYPES: tuple[str, ...] = (MAT5, MAT73, HDF5)

ACCELEROMETER = "accelerometer"
GYROSCOPE = "gyroscope"
MAGNETOMETER = "magnetometer"
TIME = "time"
TEMPERATURE = "temperature"

#: Roles by variable name (the last part of its path, lower case), tried in this order.
NAME_ROLES: tuple[tuple[str, re.Pattern[str]], ...] = (
    (MAGNETOMETER, re.compile(r"^(mag|magnetic|compass)")),
    (GYROSCOPE, re.compile(r"^(gyr|angular_?vel|angular_?rate|rate_of_turn|omega|w([xyz_\d]|$))")),
    (ACCELEROMETER, re.compile(r"^(acc|linear_?acc|specific_?force)")),
    (TIME, re.compile(r"^(t|time|times|timestamps?|time_?stamps?|stamps?|epoch)(_?(s|sec|ms|us|ns))?$")),
    (TEMPERATURE, re.compile(r"^(temp|tmp)")),
)
#: Roles by a later word of the name (``static_acc``, ``static_gyr``, ``static_mag``, ``raw_accel``: a trial's name
#: before the sensor's): whole words only, so ``magnitude`` or ``watts`` name nothing; taken when no prefix of
#: :data:`NAME_ROLES` matches and the words name exactly one role.
WORD_ROLES: tuple[tuple[str, re.Pattern[str]], ...] = (
    (MAGNETOMETER, re.compile(r"^(mag|mags|magn|magnetometer|magnetic|compass)$")),
    (GYROSCOPE, re.compile(r"^(gyr|gyro|gyros|gyroscope|angvel|omega)$")),
    (ACCELEROMETER, re.compile(r"^(acc|accs|accel|accelerometer|acceleration|accelerations)$")),
    (TEMPERATURE, re.compile(r"^(temp|temperature)$")),
    (TIME, re.compile(r"^(time|times|timestamp|timestamps)$")),  # a trial's time (all_time beside all_accel_1_x)
)
#: Roles by words of a variable's descriptive attributes, tried in this order.
TEXT_ROLES: tuple[tuple[str, tuple[str, ...]], ...] = (
    (MAGNETOMETER, ("magnet",)),
    (GYROSCOPE, ("angular", "gyro", "rate of turn")),
    (ACCELEROMETER, ("acceleration", "accelerometer", "specific force")),
    (TEMPERATURE, ("temperature",)),
    (TIME, ("time",)),
)
DESCRIPTIVE_ATTRIBUTES: tuple[str, ...] = ("standard_name", "long_name", "description", "units_name")

#: Canonical columns of a matrix by its number of axes (the layouts of optcal's headerless text files,
#: :data:`optcal.data.columns.HEADERLESS_TRIPLES`: an accelerometer, a gyroscope, then a 9-axis logger's
#: magnetometer, whose axes ``mx, my, mz`` are not read and are said so).  Layouts that begin with ``t`` apply
#: only when that axis increases.
MATRIX_LAYOUTS: dict[int, tuple[str, ...]] = {
    3: ("ax", "ay", "az"),
    4: ("t", "ax", "ay", "az"),
    6: ("ax", "ay", "az", "gx", "gy", "gz"),
    7: ("t", "ax", "ay", "az", "gx", "gy", "gz"),
    9: ("ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"),
    10: ("t", "ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"),
}
#: The axis counts of :data:`MATRIX_LAYOUTS` in words, for the refusals.
_AXIS_COUNTS: str = ", ".join(str(k) for k in list(MATRIX_LAYOUTS)[:-1]) + f" or {list(MATRIX_LAYOUTS)[-1]}"
#: ``--topic NAME:ORIENTATION``: one sample per row, or one sample per column.
ORIENTATIONS: tuple[str, ...] = ("rows", "columns")
#: Canonical names ``--columns`` may give positions for, along the axes of the chosen matrix.
MAPPABLE: tuple[str, ...] = ("t", "ax", "ay", "az", "gx", "gy", "gz", "temp")

#: Unit spellings (lower case, spaces, dots, underscores and ``*`` removed) of the accelerometer's units.
ACCEL_UNIT_SPELLINGS: dict[str, str] = {
    **dict.fromkeys(("g", "g0", "gn", "gee", "standardgravity", "gravity"), "g"),
    **dict.fromkeys(("m/s2", "m/s^2", "m/s²", "ms-2", "ms^-2", "ms⁻²", "m/s/s", "mps2", "ms2", "m/sec2", "m/sec^2",
                     "meterspersecondsquared", "metrespersecondsquared", "meterpersecondsquared",
                     "metrepersecondsquared"), "m/s^2"),
    **dict.fromkeys(("counts", "count", "lsb", "raw", "adc", "digits"), "counts"),
}
GYRO_UNIT_SPELLINGS: dict[str, str] = {
    **dict.fromkeys(("rad/s", "rads-1", "rads^-1", "rad/sec", "radianspersecond", "radian/s", "rps"), "rad/s"),
    **dict.fromkeys(("deg/s", "°/s", "degs-1", "degs^-1", "deg/sec", "dps", "degreespersecond", "degree/s"), "deg/s"),
}
#: Units of magnetic flux density (a magnetometer's): microtesla, nanotesla, tesla, gauss.
MAGNETIC_UNIT_SPELLINGS: frozenset[str] = frozenset(
    ("ut", "µt", "μt", "microtesla", "nt", "nanotesla", "t", "tesla", "gauss", "gs", "milligauss", "mgauss"))
TEMPERATURE_UNIT_SPELLINGS: frozenset[str] = frozenset(
    ("c", "degc", "°c", "celsius", "degreescelsius", "degreecelsius", "k", "kelvin"))
#: Time unit spellings and the unit they name (a CF ``seconds since ...`` is read by its first word).
TIME_UNIT_SPELLINGS: dict[str, str] = {
    **dict.fromkeys(("s", "sec", "secs", "second", "seconds"), "s"),
    **dict.fromkeys(("ms", "msec", "millisecond", "milliseconds"), "ms"),
    **dict.fromkeys(("us", "µs", "μs", "microsecond", "microseconds"), "us"),
    **dict.fromkeys(("ns", "nanosecond", "nanoseconds"), "ns"),
}
#: Attribute and scalar-variable names that give the sampling rate (Hz), as the rate keys of a text header.
RATE_NAMES: tuple[str, ...] = ("sampling_rate", "sample_rate", "sampling_frequency", "sample_frequency", "fs", "rate",
                               "frequency", "freq", "sampling_rate_hz", "sample_rate_hz", "rate_hz", "samplingrate")
#: Factors to Hz of a rate attribute's stated unit (``sampling_rate_units``).
RATE_UNIT_FACTORS: dict[str, float] = {"hz": 1.0, "1/s": 1.0, "s-1": 1.0, "khz": 1e3}
#: netCDF-4 marks a dimension that has no values of its own with this NAME (an HDF5 dimension scale).
NETCDF_BARE_DIMENSION = "This is a netCDF dimension but not a netCDF variable"

HDF5_INSTALL_HINT = "pip install 'optcal[hdf5]'"


@dataclass
class Variable:
    """One numeric array of a container, as its program shows it (MATLAB's orientation for MAT-files).

    Attributes
    ----------
    name : str
        What ``--topic`` calls it: the variable name, ``struct.field``, or an HDF5 path without its leading ``/``.
    values : ndarray
    attrs : dict of str to str or float
        Its attributes (HDF5, netCDF), decoded.
    """

    name: str
    values: NDArray[np.float64]
    attrs: dict[str, str | float] = field(default_factory=dict)
    #: The variables a matrix was joined from, one per axis (:func:`join_axis_vectors`); empty for a stored one.
    parts: tuple[str, ...] = ()

    @property
    def short(self) -> str:
        """The last part of the name, lower case (what the name patterns read)."""
        return re.split(r"[./]", self.name)[-1].lower()

    @property
    def shape_text(self) -> str:
        return " × ".join(str(s) for s in self.values.shape) or "scalar"

    def text(self, key: str) -> str:
        value = self.attrs.get(key)
        return value.strip() if isinstance(value, str) else ""


@dataclass
class Contents:
    """What a container holds: numeric arrays, numeric scalars, and the names of everything else."""

    file_type: str
    variables: list[Variable]
    scalars: dict[str, float]
    global_attrs: dict[str, str | float]
    other: list[str]


# ----------------------------------------------------------------------------- reading
def read_mat5(path: str | Path) -> Contents:
    """The variables of a MATLAB level-5 MAT-file (fields of structs as ``struct.field``)."""
    from scipy.io import loadmat

    try:
        with warnings.catch_warnings():  # MATLAB objects make scipy warn of variables named "None": said below
            warnings.filterwarnings("ignore", message="Duplicate variable name")
            content = loadmat(str(path), simplify_cells=True)
    except Exception as exc:  # scipy raises several error classes for damaged files
        raise InputError(f"{path}: not a readable MAT-file, truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc
    contents = Contents(MAT5, [], {}, {}, [])
    _collect_mat5(contents, {k: v for k, v in content.items() if not k.startswith("__")}, "")
    objects = [k for k, v in content.items() if type(v).__name__ == "MatlabOpaque"]
    if objects and not contents.variables:
        # MATLAB's classdef objects (timetable, table, string, datetime: MATLAB Mobile's sensorlog) are opaque to
        # scipy, which reads them as nameless placeholders: no number of them can be read
        raise InputError(
            f"{path}: holds MATLAB objects (a timetable, table, string or datetime, opaque outside MATLAB) and no "
            "numeric matrix; export them as plain numbers in MATLAB, e.g. "
            "writetimetable(Acceleration, 'acc.csv') or acc = Acceleration{:,:}; save('acc.mat', 'acc')"
        )
    return contents


def _collect_mat5(contents: Contents, items: dict[str, Any], prefix: str) -> None:
    for key, value in items.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            _collect_mat5(contents, value, name + ".")
        elif isinstance(value, np.ndarray) and value.dtype.kind in "iuf" and value.size:
            if value.size == 1:
                contents.scalars[name] = float(value.reshape(-1)[0])
            else:
                contents.variables.append(Variable(name, np.asarray(value, dtype=float)))
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            contents.scalars[name] = float(value)
        else:
            contents.other.append(name)


def _import_h5py() -> Any:
    try:
        import h5py
    except ImportError as exc:
        raise InputError(f"reading HDF5 files (MATLAB 7.3, netCDF-4) needs the h5py library: {HDF5_INSTALL_HINT}") from exc
    return h5py


def read_hdf5(path: str | Path, kind: str) -> Contents:
    """The numeric datasets of an HDF5 file (MATLAB 7.3 arrays in MATLAB's orientation)."""
    h5py = _import_h5py()
    try:
        fh = h5py.File(str(path), "r")
    except Exception as exc:  # h5py raises OSError and others for damaged files
        raise InputError(f"{path}: not a readable HDF5 file, truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc
    with fh:
        global_attrs = _attributes(fh.attrs)
        file_type = NETCDF4 if "_NCProperties" in fh.attrs else kind
        contents = Contents(file_type, [], {}, global_attrs, [])
        datasets: list[tuple[str, Any]] = []
        fh.visititems(lambda name, obj: datasets.append((name, obj)) if isinstance(obj, h5py.Dataset) else None)
        for name, ds in datasets:
            if name.startswith("#"):  # MATLAB 7.3's hidden groups (#refs#, #subsystem#)
                continue
            label = name.replace("/", ".") if kind == MAT73 else name
            attrs = _attributes(ds.attrs)
            if str(attrs.get("NAME", "")).startswith(NETCDF_BARE_DIMENSION):
                continue  # a dimension's length, not a variable
            matlab_class = str(attrs.get("MATLAB_class", ""))
            if ds.dtype.kind not in "iuf" or matlab_class in ("char", "logical") or "MATLAB_empty" in attrs:
                contents.other.append(label)
                continue
            try:
                values = np.asarray(ds[()], dtype=float)
            except Exception as exc:
                raise InputError(f"{path}: dataset {name!r} is truncated or corrupt ({exc.__class__.__name__}: {exc})") from exc
            if kind == MAT73:
                values = values.T  # MATLAB stores column-major: h5py shows the dimensions reversed
            values = _unpack(values, attrs)
            if values.size == 1:
                contents.scalars[label] = float(values.reshape(-1)[0])
            elif values.size:
                contents.variables.append(Variable(label, values, attrs))
    return contents


def _attributes(attrs: Any) -> dict[str, str | float]:
    """HDF5 attributes decoded: text as str, one-element numbers as float (references and arrays left out)."""
    out: dict[str, str | float] = {}
    for key in attrs:
        try:
            value = attrs[key]
        except Exception:  # an attribute of a type h5py cannot read (a reference list): not evidence
            continue
        if isinstance(value, bytes):
            out[key] = value.decode("utf-8", "replace")
        elif isinstance(value, str):
            out[key] = value
        elif isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "iuf":
            out[key] = float(value.reshape(-1)[0])
        elif isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
            out[key] = float(value)
    return out


def _unpack(values: NDArray[np.float64], attrs: dict[str, str | float]) -> NDArray[np.float64]:
    """netCDF/CF conventions: fill values become NaN (counted downstream), packed values are scaled."""
    fill = attrs.get("_FillValue")
    if isinstance(fill, float) and np.isfinite(fill):
        values = np.where(values == fill, np.nan, values)
    scale, offset = attrs.get("scale_factor"), attrs.get("add_offset")
    if isinstance(scale, float):
        values = values * scale
    if isinstance(offset, float):
        values = values + offset
    return values


# ----------------------------------------------------------------------------- roles and units
def _spelling(text: str) -> str:
    return re.sub(r"[\s_.·*]+", "", text.strip().lower())


def role_of(var: Variable) -> str | None:
    """What a variable measures, by its name, else by its attributes; ``None`` when neither says."""
    for role, pattern in NAME_ROLES:
        if pattern.match(var.short):
            return role
    named = {role for word in re.split(r"[_\-\s]+", var.short)[1:] for role, pattern in WORD_ROLES if pattern.match(word)}
    if len(named) == 1:
        return named.pop()
    unit = _spelling(var.text("units"))
    if unit in MAGNETIC_UNIT_SPELLINGS:
        return MAGNETOMETER
    words = " ".join(var.text(k).lower() for k in DESCRIPTIVE_ATTRIBUTES)
    for role, keys in TEXT_ROLES:
        if any(k in words for k in keys):
            return role
    if unit in GYRO_UNIT_SPELLINGS:
        return GYROSCOPE
    if ACCEL_UNIT_SPELLINGS.get(unit, "counts") != "counts":  # counts are any sensor's
        return ACCELEROMETER
    if unit in TEMPERATURE_UNIT_SPELLINGS:
        return TEMPERATURE
    if unit.split("since")[0] in TIME_UNIT_SPELLINGS:
        return TIME
    return None


def time_unit_of(var: Variable) -> tuple[str | None, str]:
    """The unit of a time variable as its ``units`` attribute or its name states it, and where from."""
    stated = var.text("units")
    if stated:
        first = stated.lower().split(" since ")[0].strip()
        if first in TIME_UNIT_SPELLINGS:
            return TIME_UNIT_SPELLINGS[first], f"its units attribute {stated!r}"
    match = NAME_ROLES[3][1].match(var.short)
    if match and match.group(3):
        return TIME_UNIT_SPELLINGS[match.group(3)], "its name says so"
    return None, ""


def rate_of(attrs: dict[str, str | float], where: str) -> tuple[float | None, str]:
    """A sampling rate (Hz) stated by attributes (``sampling_rate`` 100, ``sampling_rate_units`` Hz)."""
    for key, value in attrs.items():
        if key.lower() not in RATE_NAMES or not isinstance(value, float) or not value > 0:
            continue
        unit = attrs.get(f"{key}_units", attrs.get(f"{key}_unit", "Hz"))
        factor = RATE_UNIT_FACTORS.get(str(unit).strip().lower())
        if factor is None:
            continue
        return value * factor, f"attribute {key} = {value:g} {unit} of {where}"
    return None, ""


# ----------------------------------------------------------------------------- the choice
@dataclass
class Choice:
    """The accelerometer's matrix and how it is read."""

    var: Variable
    orientation: str
    reason: str
    orientation_reason: str = ""

    @property
    def samples(self) -> NDArray[np.float64]:
        """(n samples, k axes)."""
        return self.var.values if self.orientation == "rows" else self.var.values.T

    def label(self, j: int) -> str:
        """MATLAB's notation of axis ``j`` (0-based): ``X(:,2)`` or ``X(2,:)``; a joined matrix's own variable."""
        if self.var.parts:
            return self.var.parts[j]
        return f"{self.var.name}(:,{j + 1})" if self.orientation == "rows" else f"{self.var.name}({j + 1},:)"


def parse_topic(topic: str | None) -> tuple[str | None, str | None]:
    """``NAME``, ``NAME:rows`` or ``NAME:columns`` → (name, orientation)."""
    if topic is None:
        return None, None
    name, _, suffix = topic.rpartition(":")
    if name and suffix in ORIENTATIONS:
        return name, suffix
    return topic, None


def orientations(shape: tuple[int, ...]) -> list[str]:
    """The orientations of a matrix with an axis count of :data:`MATRIX_LAYOUTS` and two samples or more."""
    if len(shape) != 2:
        return []
    rows, cols = shape
    found = []
    if cols in MATRIX_LAYOUTS and rows >= 2:
        found.append("rows")
    if rows in MATRIX_LAYOUTS and cols >= 2:
        found.append("columns")
    return found


def sample_count(var: Variable, orientation: str) -> int:
    return int(var.values.shape[0] if orientation == "rows" else var.values.shape[1])


def choose_matrix(path: str, contents: Contents, topic: str | None) -> tuple[Choice, list[Variable]]:
    """The accelerometer's matrix (by ``--topic``, its name or attributes, or as the one candidate).

    Returns the choice and the other variables.  Refuses a choice that is not clear, naming the
    candidates and ``--topic``.
    """
    name, orientation = parse_topic(topic)
    roles = {id(v): role_of(v) for v in contents.variables}
    if name is not None:
        matches = [v for v in contents.variables if v.name == name] or [
            v for v in contents.variables if v.name.lower() == name.lower()]
        if len(matches) != 1:
            have = ", ".join(f"{v.name} ({v.shape_text})" for v in contents.variables) or "none"
            raise InputError(f"{path}: no numeric variable {name!r} (numeric variables: {have}); choose one with --topic NAME")
        var = matches[0]
        role = roles[id(var)]
        if role in (MAGNETOMETER, GYROSCOPE, TIME, TEMPERATURE):
            raise InputError(f"{path}: variable {var.name!r} is a {role}'s ({var.shape_text}), not an accelerometer's; "
                             "choose the accelerometer's matrix with --topic NAME")
        chosen = Choice(var, "", "given with --topic")
    else:
        candidates = [v for v in contents.variables if roles[id(v)] == ACCELEROMETER and orientations(v.values.shape)]
        why = "its name or attributes say acceleration"
        if not candidates:
            candidates = [v for v in contents.variables if roles[id(v)] is None and orientations(v.values.shape)]
            why = ("the one matrix of a 9-axis logger's 9 or 10 axes"
                   if len(candidates) == 1 and not set(candidates[0].values.shape) & {3, 4, 6, 7}
                   else "the one matrix of 3, 4, 6 or 7 axes")
        if not candidates:
            have = ", ".join(f"{v.name} ({v.shape_text}{', ' + str(roles[id(v)]) if roles[id(v)] else ''})"
                             for v in contents.variables) or "none"
            raise InputError(f"{path}: no accelerometer matrix (a numeric matrix of {_AXIS_COUNTS} columns or rows) "
                             f"among the file's numeric variables: {have}{_mapping_hint(contents.variables, roles)}")
        if len(candidates) > 1:
            listed = ", ".join(f"{v.name} ({v.shape_text})" for v in candidates)
            raise InputError(f"{path}: {len(candidates)} matrices could be the accelerometer's: {listed}; "
                             "choose one with --topic NAME")
        chosen = Choice(candidates[0], "", why)
    others = [v for v in contents.variables if v is not chosen.var]
    if orientation is not None:
        chosen.orientation, chosen.orientation_reason = orientation, "given with --topic"
    else:
        chosen.orientation, chosen.orientation_reason = _orientation(path, chosen.var, others)
    return chosen, others


def _mapping_hint(variables: list[Variable], roles: dict[int, str | None]) -> str:
    """The flags that read a matrix of another axis count: ``--topic NAME:rows`` (or ``:columns``, its samples
    along its longer side) and ``--columns`` giving the accelerometer's positions; empty when no 2-D matrix of
    unknown role is there to map."""
    matrices = [v for v in variables if v.values.ndim == 2 and min(v.values.shape) >= 3 and roles.get(id(v)) is None]
    if not matrices:
        return ""
    var = max(matrices, key=lambda v: v.values.size)
    side = "rows" if var.values.shape[0] >= var.values.shape[1] else "columns"
    return (f"; read one by giving its orientation and the accelerometer's positions along its axes: "
            f"--topic {var.name}:{side} --columns ax=N,ay=N,az=N (and t=N, gx=N,gy=N,gz=N)")


def _orientation(path: str, var: Variable, others: list[Variable]) -> tuple[str, str]:
    """The orientation of ``var`` and why: the only one its shape allows, else the one whose sample count another
    variable has."""
    found = orientations(var.values.shape)
    if len(found) == 1:
        return found[0], ""
    if not found:
        raise InputError(f"{path}: variable {var.name!r} ({var.shape_text}) has no axis count optcal reads "
                         f"({_AXIS_COUNTS} columns or rows){_mapping_hint([var], {id(var): None})}")
    lengths = {v.values.size for v in others if v.values.ndim == 1 or (v.values.ndim == 2 and min(v.values.shape) == 1)}
    lengths |= {s for v in others if v.values.ndim == 2 and min(v.values.shape) > 1 for s in v.values.shape
                if s not in MATRIX_LAYOUTS}
    agreeing = [o for o in found if sample_count(var, o) in lengths]
    if len(agreeing) == 1:
        return agreeing[0], f"another variable has {sample_count(var, agreeing[0])} samples"
    raise InputError(f"{path}: variable {var.name!r} ({var.shape_text}) can be read with one sample per row or per "
                     f"column; choose with --topic {var.name}:rows or --topic {var.name}:columns")


# ----------------------------------------------------------------------------- the Source
def parse_positions(columns: str | dict[str, str] | None, n_axes: int) -> dict[str, int] | None:
    """``--columns t=1,ax=2,...``: canonical name → 0-based position along the chosen matrix's axes."""
    if not columns:
        return None
    if isinstance(columns, dict):
        pairs = [(str(k).strip(), str(v).strip()) for k, v in columns.items()]
    else:
        pairs = [(k.strip(), v.strip()) for k, _, v in (item.partition("=") for item in columns.split(",") if item.strip())]
    out: dict[str, int] = {}
    for key, value in pairs:
        if key not in MAPPABLE or not value.isdigit() or not 1 <= int(value) <= n_axes:
            raise InputError(f"--columns {key}={value}: in a MAT-file or HDF5 file, columns gives 1-based positions "
                             f"(1..{n_axes}) along the chosen matrix's axes for {', '.join(MAPPABLE)}")
        out[key] = int(value) - 1
    return out


def read_container(
    path: str | Path,
    kind: str,
    *,
    topic: str | None = None,
    columns: str | dict[str, str] | None = None,
    gyro_file: str | Path | None = None,
) -> dict[str, Any]:
    """Read a MAT-file, netCDF-4 or HDF5 file: the keyword arguments of :class:`optcal.data.readers.Source`.

    Parameters
    ----------
    path : str or Path
    kind : str
        :func:`container_type`'s answer.
    topic : str, optional
        The accelerometer's variable (``NAME``), and its orientation (``NAME:rows``: one
        sample per row; ``NAME:columns``).
    columns : str or dict, optional
        1-based positions along the chosen matrix's axes (``t=1,ax=2,ay=3,az=4``), instead of
        the layout its axis count implies (:data:`MATRIX_LAYOUTS`).
    gyro_file : refused (the container holds its own gyro, if any).
    """
    if gyro_file is not None:
        raise InputError(f"gyro_file applies to text files, not to a {kind} (it holds its own variables)")
    contents = read_mat5(path) if kind == MAT5 else read_hdf5(path, kind)
    joined = join_axis_vectors(contents)
    chosen, others = choose_matrix(str(path), contents, topic)
    samples = chosen.samples
    n, n_axes = samples.shape
    positions = parse_positions(columns, n_axes)
    if positions is None:
        layout = MATRIX_LAYOUTS.get(n_axes)
        if layout is None:
            raise InputError(f"{path}: variable {chosen.var.name!r} has {n_axes} axes; map them with --columns ax=1,ay=2,az=3")
        positions = {name: j for j, name in enumerate(layout) if name in MAPPABLE}
        if layout[0] == "t":
            t = samples[:, 0][np.isfinite(samples[:, 0])]
            if t.size < 2 or np.any(np.diff(t) < 0):
                raise InputError(f"{path}: variable {chosen.var.name!r} has {n_axes} axes, and its first does not increase "
                                 f"as a time does; map the axes with --columns (e.g. ax=1,ay=2,az=3)")
        unread = [j for j, name in enumerate(layout) if name not in MAPPABLE]
        read_as = ", ".join(name for name in layout if name in MAPPABLE)
        columns_reason = f"{chosen.reason}: {n_axes} axes read as {read_as}"
        if unread:
            columns_reason += (f"; axes {unread[0] + 1}-{unread[-1] + 1} not read: a 9-axis logger's magnetometer "
                               "(--columns gives other positions)")
    else:
        columns_reason = f"{chosen.reason}: positions given with --columns"
    missing = [c for c in ("ax", "ay", "az") if c not in positions]
    if missing:
        raise InputError(f"{path}: no position for {', '.join(missing)}; give them with --columns (e.g. ax=1,ay=2,az=3)")
    block = np.asfortranarray(samples[:, sorted(positions.values())], dtype=float)
    order = {j: k for k, j in enumerate(sorted(positions.values()))}
    data = {canon: block[:, order[j]] for canon, j in positions.items()}
    column_map = {canon: chosen.label(j) for canon, j in positions.items()}
    fields: dict[str, Any] = {
        "path": str(path), "file_type": contents.file_type, "data": data, "column_map": column_map,
        "columns_reason": columns_reason, "size_bytes": Path(path).stat().st_size,
        "header": {"variable": chosen.var.name},
    }
    used, notes = _companions(chosen, others, n, fields)
    notes[:0] = [f"{len(joined)} variable(s) stored one vector per axis joined as matrices: "
                 + ", ".join(f"{v.name} ← {', '.join(v.parts)}" for v in joined)] if joined else []
    _units_and_rate(chosen, contents, fields, notes)
    skipped = [v for v in others if id(v) not in used]
    fields["ignored_columns"] = [v.name for v in skipped] + contents.other
    fields["layout"] = _describe(contents, chosen, n, skipped, notes)
    fields["notes"] = notes
    return fields


def _companions(chosen: Choice, others: list[Variable], n: int, fields: dict[str, Any]) -> tuple[set[int], list[str]]:
    """Gyro, time and temperature variables with the accelerometer's ``n`` samples, added to ``fields``."""
    data, column_map = fields["data"], fields["column_map"]
    used: set[int] = set()
    notes: list[str] = []
    for role, canon in ((GYROSCOPE, ("gx", "gy", "gz")), (TIME, ("t",)), (TEMPERATURE, ("temp",))):
        if canon[0] in data:
            continue
        found = []
        for var in (v for v in others if role_of(v) == role):
            values = var.values
            if len(canon) == 1 and values.size == n and (values.ndim == 1 or min(values.shape) == 1):
                found.append((var, values.reshape(-1)))
            elif len(canon) == 3 and values.ndim == 2 and (values.shape == (n, 3) or values.shape == (3, n)):
                found.append((var, values if values.shape == (n, 3) else values.T))
        if len(found) > 1:
            # two sensors' (all_accel_1, all_gyro_1, all_accel_2, ...): the one named as the accelerometer is,
            # but for the sensor's word, is the same sensor's
            same = [(v, x) for v, x in found if _other_words(v.short) == _other_words(chosen.var.short)]
            if len(same) != 1:
                notes.append(f"{len(found)} {role} variables ({', '.join(v.name for v, _ in found)}): none used")
                continue
            notes.append(f"{len(found)} {role} variables ({', '.join(v.name for v, _ in found)}): "
                         f"{same[0][0].name} used, named as the accelerometer's {chosen.var.name} is")
            found = same
        if not found:
            continue
        var, values = found[0]
        used.add(id(var))
        for j, name in enumerate(canon):
            data[name] = np.ascontiguousarray(values[:, j] if values.ndim == 2 else values, dtype=float)
            column_map[name] = (var.name if len(canon) == 1 else var.parts[j] if var.parts
                                else f"{var.name}[{'xyz'[j]}]")
        if role == TIME:
            unit, why = time_unit_of(var)
            if unit is not None:
                if SECONDS_PER_TIME_UNIT[unit] != 1.0:
                    data["t"] = data["t"] * SECONDS_PER_TIME_UNIT[unit]
                fields["time_unit"], fields["time_reason"] = unit, f"column {var.name!r} in {unit} ({why})"
            else:
                fields["time_reason"] = f"column {var.name!r}"
        if role == GYROSCOPE:
            spelled = GYRO_UNIT_SPELLINGS.get(_spelling(var.text("units")))
            if spelled is not None:
                fields["gyro_units"] = spelled
    return used, notes


#: A vector of one axis: a name ending in a separator and the axis (``all_accel_1_x``, ``acc.x``).
AXIS_VECTOR = re.compile(r"^(.+)[_.]([xyzXYZ])$")


def join_axis_vectors(contents: Contents) -> list[Variable]:
    """Join the vectors stored one per axis (``all_accel_1_x``, ``_y``, ``_z``) into one matrix each, in place.

    A group is joined when its x, y and z are vectors (or n × 1) of the same length and their common name says
    a sensor (:func:`role_of`: ``all_accel_1`` an accelerometer, ``all_gyro_1`` a gyroscope): MATLAB scripts
    save a logger's columns so, and none of them alone is a sample.  Returns the joined variables (their
    ``parts`` name the vectors), which replace their vectors in ``contents.variables``.
    """
    groups: dict[tuple[str, int], dict[str, Variable]] = {}
    for var in contents.variables:
        m = AXIS_VECTOR.match(var.name)
        if m is None or var.values.ndim not in (1, 2) or (var.values.ndim == 2 and min(var.values.shape) != 1):
            continue
        groups.setdefault((m.group(1), var.values.size), {})[m.group(2).lower()] = var
    joined: list[Variable] = []
    for (stem, size), axes in groups.items():
        if set(axes) != {"x", "y", "z"} or size < 2:
            continue
        var = Variable(stem, np.column_stack([axes[a].values.reshape(-1) for a in "xyz"]).astype(float),
                       dict(axes["x"].attrs), tuple(axes[a].name for a in "xyz"))
        if role_of(var) not in (ACCELEROMETER, GYROSCOPE):
            continue
        parts = {id(axes[a]) for a in "xyz"}
        at = min(i for i, v in enumerate(contents.variables) if id(v) in parts)
        contents.variables[:] = [v for v in contents.variables if id(v) not in parts]
        contents.variables.insert(at, var)
        joined.append(var)
    return joined


def _other_words(short: str) -> tuple[str, ...]:
    """A variable name's words but those that say a sensor (``all_gyro_1`` → ``all, 1``): what tells one sensor's
    variables from another's."""
    words = re.split(r"[_\-\s]+", short)
    return tuple(w for w in words if not any(p.match(w) for _, p in WORD_ROLES))


def _units_and_rate(chosen: Choice, contents: Contents, fields: dict[str, Any], notes: list[str]) -> None:
    """What the file states: the accelerometer's ``units`` attribute and a sampling rate."""
    stated = chosen.var.text("units")
    if stated:
        units = ACCEL_UNIT_SPELLINGS.get(_spelling(stated))
        if units is not None:
            fields["units_hint"] = units
            fields["units_reason"] = f"units attribute {stated!r} of variable {chosen.var.name!r}"
        else:
            notes.append(f"units attribute {stated!r} of {chosen.var.name!r} not understood")
    rate, why = rate_of(chosen.var.attrs, f"variable {chosen.var.name!r}")
    if rate is None:
        rate, why = rate_of(contents.global_attrs, "the file")
    if rate is None:
        for name, value in contents.scalars.items():
            if re.split(r"[./]", name)[-1].lower() in RATE_NAMES and value > 0:
                rate, why = value, f"scalar variable {name} = {value:g}"
                break
    if rate is not None:
        fields["rate_hint"], fields["rate_reason"] = rate, why
        fields["header"]["rate"] = f"{rate:g}"


def _describe(contents: Contents, chosen: Choice, n: int, skipped: list[Variable], notes: list[str]) -> str:
    """The ``read:`` line: the container, the matrix and its orientation, and every variable not used, counted."""
    per = "row" if chosen.orientation == "rows" else "column"
    other_way = "columns" if per == "row" else "rows"
    flip = (f"; --topic {chosen.var.name}:{other_way} reads it the other way"
            if len(orientations(chosen.var.values.shape)) == 2 else "")
    why = f": {chosen.orientation_reason}" if chosen.orientation_reason else ""
    parts = [f"{contents.file_type}, variable {chosen.var.name!r} ({chosen.var.shape_text}: {n} samples, one per {per}"
             f"{why}{flip})"]
    magnetometers = [v for v in skipped if role_of(v) == MAGNETOMETER]
    if magnetometers:
        listed = ", ".join(f"{v.name} ({v.shape_text}{', ' + v.text('units') if v.text('units') else ''})" for v in magnetometers)
        parts.append(f"skipped {len(magnetometers)} magnetometer variable(s), not an accelerometer: {listed}")
    rest = [v.name for v in skipped if role_of(v) != MAGNETOMETER] + contents.other
    if rest:
        parts.append(f"{len(rest)} other variable(s) not used: {', '.join(rest)}")
    parts.extend(notes)
    return "; ".join(parts)
