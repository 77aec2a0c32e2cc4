"""A magnetometer's samples from a MAT-file or a netCDF-4/HDF5 file: the one variable that is a magnetometer by its
name or units (or ``--topic``), its units attribute, and an accelerometer variable of as many samples."""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import MAG, time_column_at
from optcal.errors import InputError
from optcal.families.mag.sample_set import MagSamples, _build


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
            at = time_column_at(list(v.T))
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
