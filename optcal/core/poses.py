"""The pose table: one row per static pose, the input of every static estimator.

A :class:`PoseTable` holds the mean specific-force measurement of each static pose in raw
units, and, where known, its noise, sample count, time, temperature and gyro mean.  Raw
recordings are reduced to a pose table by static detection (:mod:`optcal.data`); a CSV
pose table is read as it is.  Everything that was excluded on the way (saturated samples,
non-static poses, non-finite rows, ...) is counted in :attr:`PoseTable.exclusions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.units import ACCEL_UNITS
from optcal.errors import InputError

#: Minimum number of poses for the nine identifiable parameters.
MIN_POSES: int = 9

#: The default of :attr:`PoseTable.rows`, told apart by identity: a table built without row
#: numbers numbers its poses 0..n-1 (an empty array the caller passed is still checked).
_UNNUMBERED: NDArray[np.int64] = np.empty(0, dtype=np.int64)


class ReadingDecisions(Protocol):
    """How a data file was read, each decision with its reason: what a pose table keeps of it.

    The data layer's decisions (kind, columns, units, time base, rate, exclusions) provide it;
    reports print its :meth:`lines`, JSON output carries its :meth:`to_dict`.
    """

    def lines(self) -> list[str]:
        """One line per decision, with its reason."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """The decisions as a JSON-safe dictionary."""
        ...


def _opt_array(x: ArrayLike | None, n: int, name: str, shape: tuple[int, ...] = ()) -> NDArray | None:
    if x is None:
        return None
    a = np.asarray(x, dtype=float)
    want = (n, *shape)
    if a.shape != want:
        a = a.reshape(want) if a.size == int(np.prod(want)) else a
    if a.shape != want:
        raise InputError(f"{name} has shape {a.shape}, expected {want}")
    return a


@dataclass
class PoseTable:
    """Static poses of one accelerometer.

    Attributes
    ----------
    acc : ndarray, shape (n, 3)
        Mean measured specific force of each pose, raw units.
    sigma : ndarray, shape (n,), optional
        Standard deviation of each pose's measurement (of the mean, per axis), raw units.
        Feeds the maximum-likelihood weights ``1/σ_k²`` (Lu 2017, eq. 14).
    n_samples : ndarray, shape (n,), optional
        Number of raw samples averaged into each pose.
    t : ndarray, shape (n,), optional
        Pose time, seconds (mid-point of the static interval for raw recordings).
    temp : ndarray, shape (n,), optional
        Mean temperature of each pose, °C.
    gyro : ndarray, shape (n, 3), optional
        Mean gyro reading of each pose (raw units).
    rows : ndarray of int, shape (n,)
        Row number of each pose in the user's file (or interval number for recordings),
        used whenever a pose is named in a report; 0..n-1 when not given.
    units : str
        Units of ``acc`` and ``sigma``: ``"g"``, ``"m/s^2"`` or ``"counts"``.
    source : str
        ``"pose table"`` or ``"raw recording"``.
    exclusions : dict of str to int
        What was excluded on the way, counted (e.g. ``{"saturated samples": 12}``).
    extra : dict of str to ndarray
        Further per-pose columns (e.g. ``roll_deg``, ``gx_ref``), each of length n.
    meta : dict
        Free-form provenance (file name, detected segments, thresholds, ...).
    decisions : ReadingDecisions or None
        How the data file was read (kind, columns, units, time base, rate, exclusions, each
        with its reason), for tables loaded from a file.
    """

    acc: NDArray[np.float64]
    sigma: NDArray[np.float64] | None = None
    n_samples: NDArray[np.float64] | None = None
    t: NDArray[np.float64] | None = None
    temp: NDArray[np.float64] | None = None
    gyro: NDArray[np.float64] | None = None
    rows: NDArray[np.int64] = field(default_factory=lambda: _UNNUMBERED)
    units: str = "g"
    source: str = "pose table"
    exclusions: dict[str, int] = field(default_factory=dict)
    extra: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    decisions: ReadingDecisions | None = None

    def __post_init__(self) -> None:
        acc = np.asarray(self.acc, dtype=float)
        if acc.ndim != 2 or acc.shape[1] != 3:
            raise InputError(f"acc must have shape (n, 3), got {acc.shape}")
        self.acc = acc
        n = acc.shape[0]
        self.sigma = _opt_array(self.sigma, n, "sigma")
        self.n_samples = _opt_array(self.n_samples, n, "n_samples")
        self.t = _opt_array(self.t, n, "t")
        self.temp = _opt_array(self.temp, n, "temp")
        self.gyro = _opt_array(self.gyro, n, "gyro", (3,))
        self.rows = np.arange(n) if self.rows is _UNNUMBERED else np.asarray(self.rows, dtype=int).reshape(n)
        if self.units not in ACCEL_UNITS:
            raise InputError(f"unknown units {self.units!r}; use one of {', '.join(ACCEL_UNITS)}")
        # copies: a table never shares (and so never corrupts) the caller's arrays
        self.extra = {k: np.array(v, dtype=float).reshape(n, *np.shape(v)[1:]) for k, v in self.extra.items()}

    def __eq__(self, other: object) -> bool:
        """Value equality: the same columns (NaN equal to NaN), units, source and exclusions.

        ``meta`` (free-form provenance: file name, thresholds) is not compared.
        """
        if not isinstance(other, PoseTable):
            return NotImplemented
        arrays = ("acc", "sigma", "n_samples", "t", "temp", "gyro", "rows")
        same_arrays = all(
            (getattr(self, k) is None) == (getattr(other, k) is None)
            and (getattr(self, k) is None or np.array_equal(getattr(self, k), getattr(other, k), equal_nan=True))
            for k in arrays
        )
        same_extra = self.extra.keys() == other.extra.keys() and all(
            np.array_equal(v, other.extra[k], equal_nan=True) for k, v in self.extra.items()
        )
        return (
            same_arrays
            and same_extra
            and (self.units, self.source, self.exclusions) == (other.units, other.source, other.exclusions)
        )

    __hash__ = None  # type: ignore[assignment]

    @property
    def n(self) -> int:
        """Number of poses."""
        return int(self.acc.shape[0])

    def __len__(self) -> int:
        return self.n

    def subset(self, index: ArrayLike) -> "PoseTable":
        """A new table with the poses selected by an index or boolean mask."""
        idx = np.asarray(index)
        pick = (lambda a: None if a is None else a[idx])
        return replace(
            self,
            acc=self.acc[idx],
            sigma=pick(self.sigma),
            n_samples=pick(self.n_samples),
            t=pick(self.t),
            temp=pick(self.temp),
            gyro=pick(self.gyro),
            rows=self.rows[idx],
            exclusions=dict(self.exclusions),
            extra={k: v[idx] for k, v in self.extra.items()},
            meta=dict(self.meta),
        )

    def with_acc(self, acc: ArrayLike) -> "PoseTable":
        """A copy with the measurements replaced (same poses, times, temperatures, ...)."""
        out = self.subset(np.arange(self.n))
        out.acc = np.asarray(acc, dtype=float).reshape(self.n, 3)
        return out

    def count_exclusion(self, what: str, count: int) -> None:
        """Add ``count`` to the exclusion counter ``what`` (no-op for zero)."""
        if count:
            self.exclusions[what] = self.exclusions.get(what, 0) + int(count)

    def validate(self, min_poses: int = MIN_POSES) -> "PoseTable":
        """Check the table can be calibrated; raise :class:`InputError` saying why not.

        Checks: finite values, at least ``min_poses`` poses, at least ``min_poses``
        distinct poses, poses not all in one plane, positive noise.
        """
        if not np.all(np.isfinite(self.acc)):
            bad = np.flatnonzero(~np.all(np.isfinite(self.acc), axis=1))
            raise InputError(
                f"{bad.size} pose(s) contain NaN or infinite acceleration values "
                f"(rows {', '.join(str(r) for r in self.rows[bad][:5])}"
                f"{', ...' if bad.size > 5 else ''}); remove or fix them"
            )
        for name in ("sigma", "t", "temp"):
            v = getattr(self, name)
            if v is not None and not np.all(np.isfinite(v)):
                raise InputError(f"column {name!r} contains NaN or infinite values; fix or drop the column")
        if self.sigma is not None and np.any(self.sigma <= 0):
            raise InputError("per-pose noise sigma must be positive")
        if self.n < min_poses:
            raise InputError(
                f"only {self.n} poses; at least {min_poses} static poses in different "
                "orientations are needed to calibrate bias, scale and non-orthogonality"
            )
        scale = float(np.max(np.abs(self.acc))) or 1.0
        distinct = _distinct_rows(np.round(self.acc / (scale * 1e-9)))
        if distinct < min_poses:
            raise InputError(
                f"only {distinct} distinct poses among {self.n} (identical rows); at least "
                f"{min_poses} different orientations are needed"
            )
        centred = self.acc - self.acc.mean(axis=0)
        sv = np.linalg.svd(centred, compute_uv=False)
        if sv[0] == 0 or sv[-1] / sv[0] < 1e-6:
            raise InputError(
                "all poses lie in one plane (coplanar measurements); rotate the sensor "
                "about more than one axis so that the poses span three dimensions"
            )
        return self


def _distinct_rows(rows: NDArray[np.float64]) -> int:
    """Number of distinct rows (``np.unique(rows, axis=0)``'s, without its import of ``numpy.ma``)."""
    if rows.shape[0] == 0:
        return 0
    ordered = rows[np.lexsort(rows.T[::-1])]
    return 1 + int(np.count_nonzero(np.any(ordered[1:] != ordered[:-1], axis=1)))
