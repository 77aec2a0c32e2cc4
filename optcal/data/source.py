"""What a reader returns: the :class:`Source` (a file's data under canonical column names, with what the file
says about units, rate and saturation) and :class:`GyroOnlyColumns`, the refusal that carries one.

Part of the *read* step (:mod:`optcal.data.readers`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.data.columns import ACC, GYRO, ColumnRoles


class GyroOnlyColumns(InputError):
    """A file whose columns name a gyroscope and no accelerometer; ``source`` holds what was read (time and gyro).

    Refused by every reader of an accelerometer's recording; :func:`optcal.data.gyro_log.read_gyro_recording`
    takes the source and reads the gyro alone (``optcal allan FILE --sensor gyro``).
    """

    def __init__(self, message: str, source: "Source") -> None:
        super().__init__(message)
        self.source = source


@dataclass
class Source:
    """Data read from a file, under canonical column names (the *read* step).

    Attributes
    ----------
    path : str
    file_type : str
        ``"csv"``, ``"parquet"``, ``"ros1 bag"``, ``"ros2 bag"``, ``"ulog"`` or ``"dataflash"``.
    data : dict of str to ndarray
        Canonical columns (a subset of :data:`CANONICAL` plus ``index``) as floats; cells
        that were not numbers are NaN and counted in :attr:`non_numeric`.
    extra : dict of str to ndarray
        Further numeric columns of the file, under their own names.
    column_map : dict of str to str
        Canonical name → the file's column name (or ``#N`` for the N-th field of a file
        without a header).
    columns_reason : str
        How the columns were matched (header names, positions, ``--columns``).
    ignored_columns : list of str
        Columns neither mapped nor numeric (e.g. a text label column).
    units_hint, units_reason : str or None, str
        Accelerometer units stated by the file (a unit word in the column names, or the
        format's convention), and where that came from.
    gyro_units : str or None
    rate_hint, rate_reason : float or None, str
        Sampling rate stated by the file (e.g. an ``Fs,100`` metadata line).
    time_unit, time_reason : str or None, str
        Unit of the time column as the file states it (a unit word, or the format), and
        how it was read; ``None`` when nothing states it (decided in :mod:`optcal.data.decisions`).
    header : dict of str to str
        Metadata lines found above the header row.
    layout : str
        How a text file is laid out (delimiter, decimal mark, header), for reports.
    non_numeric : dict of str to tuple
        Canonical column → (number of non-numeric cells, first data row, first value).
    saturated, gyro_saturated : ndarray of bool or None
        Per-row saturation flags of the accelerometer and the gyro stated by the file (ULog clip counters).
    always_raw : bool
        The format holds time series only (bags, ULog).
    size_bytes : int
        Size of the file (evidence for the kind of data).
    notes : list of str
    exclusions : dict of str to int
        What the reader could not use, counted (e.g. a message cut off by truncation).
    roles : ColumnRoles or None
        Columns whose names do not settle their roles (a file without a header, ``tx, ty,
        tz``), read in the common layout; the decisions read them as the evidence says.
    gyro_unhealthy : ndarray of bool or None
        Rows whose gyro sample the file marks unusable while their accelerometer sample is sound (a DataFlash
        ``GH`` = 0): the row is kept, its gyro sample left out of the gyro's use (counted by the reader).
    """

    path: str
    file_type: str
    data: dict[str, NDArray[np.float64]]
    extra: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    column_map: dict[str, str] = field(default_factory=dict)
    columns_reason: str = "header names"
    ignored_columns: list[str] = field(default_factory=list)
    units_hint: str | None = None
    units_reason: str = ""
    gyro_units: str | None = None
    rate_hint: float | None = None
    rate_reason: str = ""
    time_unit: str | None = None
    time_reason: str = ""
    header: dict[str, str] = field(default_factory=dict)
    layout: str = ""
    non_numeric: dict[str, tuple[int, int, str]] = field(default_factory=dict)
    saturated: NDArray[np.bool_] | None = None
    gyro_saturated: NDArray[np.bool_] | None = None
    always_raw: bool = False
    size_bytes: int = 0
    notes: list[str] = field(default_factory=list)
    exclusions: dict[str, int] = field(default_factory=dict)
    roles: ColumnRoles | None = None
    gyro_unhealthy: NDArray[np.bool_] | None = None

    @property
    def n_rows(self) -> int:
        return int(next(iter(self.data.values())).size) if self.data else 0

    def has(self, *names: str) -> bool:
        """Whether every canonical column in ``names`` is present."""
        return all(n in self.data for n in names)

    def column(self, name: str) -> NDArray[np.float64]:
        return self.data[name]

    def describe_columns(self) -> str:
        """``ax←acc_x_counts, ...`` for reports."""
        return ", ".join(f"{k}←{v}" for k, v in self.column_map.items() if k != v) or "as named"

    def block(self, names: tuple[str, ...]) -> NDArray[np.float64]:
        """The columns ``names`` as one (n, k) array in column-major (Fortran) order.

        Each column is contiguous, so the column-by-column statistics of the static detection and
        the per-interval means read contiguous memory.  When the columns are already adjacent
        columns, in this order, of one column-major block (a large text file is parsed into one,
        :class:`optcal.data.text.ColumnBlock`), the result is a view of that block: no copy.
        """
        view = self._adjacent([self.column(name) for name in names])
        if view is not None:
            return view
        block = np.empty((self.n_rows, len(names)), order="F")
        for j, name in enumerate(names):
            block[:, j] = self.column(name)
        return block

    @staticmethod
    def _adjacent(cols: list[NDArray[np.float64]]) -> NDArray[np.float64] | None:
        """``base[:n, k:k + len(cols)]`` when ``cols`` are those columns of one column-major base, else ``None``."""
        base = cols[0].base
        if not isinstance(base, np.ndarray) or base.ndim != 2 or not base.flags.f_contiguous or base.dtype != np.float64:
            return None
        n = cols[0].size
        start = base.__array_interface__["data"][0]
        stride = base.strides[1]
        first = cols[0].__array_interface__["data"][0] - start
        if n > base.shape[0] or first % stride:
            return None
        k = first // stride
        for j, col in enumerate(cols):
            if (col.base is not base or col.ndim != 1 or col.size != n or col.strides != (8,)
                    or col.__array_interface__["data"][0] - start != (k + j) * stride):
                return None
        if k + len(cols) > base.shape[1]:
            return None
        return base[:n, k:k + len(cols)]

    def with_accelerometer(self, k: int) -> Source:
        """This source read with candidate triple ``k`` of :attr:`roles` as the accelerometer (and the
        other as the gyroscope): a copy that shares the arrays."""
        if self.roles is None or k == self.roles.acc:
            return self
        by_name = {self.column_map[c]: self.data[c] for c in (*ACC, *GYRO) if c in self.data}
        data, column_map = dict(self.data), dict(self.column_map)
        for i, names in enumerate(self.roles.triples):
            for canon, name in zip(ACC if i == k else GYRO, names):
                data[canon], column_map[canon] = by_name[name], name
        order = [c for c in self.column_map]  # the columns listed as before
        roles = ColumnRoles(self.roles.triples, k, self.roles.layout, self.roles.conditional)
        return replace(self, data=data, column_map={c: column_map[c] for c in order}, roles=roles)

    def assign_accelerometer(self, k: int) -> None:
        """Read candidate triple ``k`` of :attr:`roles` as the accelerometer from now on (in place)."""
        other = self.with_accelerometer(k)
        self.data, self.column_map, self.roles = other.data, other.column_map, other.roles
