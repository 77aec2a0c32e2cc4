"""A magnetometer's samples as every reader returns them (:class:`MagSamples`), and how a reader's arrays become
them: the rows with a non-finite or an all-zero magnetometer value and those at a rail counted, the units decided
(:func:`~optcal.families.mag.samples.read_mag` reads them)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.families.mag.rail import MAG_NEAR_RAIL_SHARE, MAG_RAIL_ROWS, mag_rail, rail_line
from optcal.families.mag.units import UnitDecision, decide_mag_units


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


#: The exclusion of rows whose magnetometer reads exactly 0, 0, 0.
ZERO_ROWS = "all-zero magnetometer rows (a logger's placeholder: a field never reads 0, 0, 0)"


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
