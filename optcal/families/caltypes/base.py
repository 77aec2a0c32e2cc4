"""What every calibration file has: type, format version, units, value equality, JSON I/O.

A calibration file is one JSON object::

    {"cal_type": "lumped", "format_version": "2.0",
     "units": {"input": "counts", "output": "g", "T": "g per counts", "o": "counts"},
     ... the type's own parameters ...,
     "fitted_on": {"acc": [[...], ...], "temp": [...], "t": [...]}   (optional)}

``cal_type`` picks the class (:mod:`optcal.families.calibration_files`); ``format_version`` is
semantic (``MAJOR.MINOR``, :func:`optcal.core.jsonio.check_version`): a reader accepts every minor
version of its major version (minor versions only add optional fields) and refuses a newer major
version.  Units sit in the file next to the
numbers (imucal's convention).  ``fitted_on`` holds the static poses the calibration was fitted
on, so that an exporter can say what a simpler firmware model loses on them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.jsonio import FORMAT_VERSION, check_version, jsonable, write_json
from optcal.core.units import ACCEL_UNITS

CalibrationT = TypeVar("CalibrationT", bound="Calibration")


class ValidityRangeWarning(UserWarning):
    """A calibration was applied to samples outside the range it was fitted on."""


def as_samples(acc: ArrayLike, name: str = "acc") -> NDArray[np.float64]:
    """Samples as an (n, 3) float array (a single sample of shape (3,) becomes (1, 3))."""
    a = np.asarray(acc, dtype=float)
    if a.ndim == 1 and a.size == 3:
        a = a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"{name} must have shape (n, 3) (one row per sample: x, y, z), got shape {a.shape}")
    return a


def as_column(values: ArrayLike | None, n: int, name: str) -> NDArray[np.float64] | None:
    """A per-sample column of length ``n`` (a scalar is broadcast), or ``None``."""
    if values is None:
        return None
    v = np.asarray(values, dtype=float)
    if v.ndim == 0:
        return np.full(n, float(v))
    v = v.reshape(-1)
    if v.size != n:
        raise InputError(f"{name} has {v.size} values for {n} samples; give one per sample (or one for all)")
    return v


def units_dict(units: str, **fields: str) -> dict[str, str]:
    """``{"input": units, "output": "g", **fields}`` (every field's units written into the file)."""
    return {"input": units, "output": "g", **fields}


def read_matrix(d: dict[str, Any], key: str, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """Entry ``key`` of a calibration dictionary as a float array of ``shape``."""
    if key not in d:
        raise InputError(f"the calibration has no {key!r} entry")
    a = np.asarray(d[key], dtype=float)
    if a.size != int(np.prod(shape)):
        raise InputError(f"the calibration's {key!r} has {a.size} numbers; expected shape {shape}")
    a = a.reshape(shape)
    if not np.all(np.isfinite(a)):
        raise InputError(f"the calibration's {key!r} contains non-finite numbers")
    return a


@dataclass(frozen=True, eq=False)
class FitPoses:
    """The static poses a calibration was fitted on.

    Attributes
    ----------
    acc : ndarray, shape (n, 3)
        Mean measurement of each pose, raw units (the calibration's input units).
    temp : ndarray, shape (n,), optional
        Temperature of each pose, °C.
    t : ndarray, shape (n,), optional
        Time of each pose, s.
    """

    acc: NDArray[np.float64]
    temp: NDArray[np.float64] | None = None
    t: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        acc = as_samples(self.acc, "fitted_on.acc")
        object.__setattr__(self, "acc", acc)
        object.__setattr__(self, "temp", as_column(self.temp, len(acc), "fitted_on.temp"))
        object.__setattr__(self, "t", as_column(self.t, len(acc), "fitted_on.t"))

    @classmethod
    def of(cls, poses: Any) -> "FitPoses":
        """The measurements, temperatures and times of a :class:`~optcal.core.poses.PoseTable`."""
        return cls(poses.acc.copy(), poses.temp, poses.t)

    @property
    def n(self) -> int:
        return int(self.acc.shape[0])

    def to_dict(self) -> dict[str, Any]:
        return jsonable({"acc": self.acc, "temp": self.temp, "t": self.t})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "FitPoses":
        def column(key: str) -> NDArray[np.float64] | None:
            return None if d.get(key) is None else np.asarray(d[key], dtype=float)

        return cls(np.asarray(d["acc"], dtype=float), column("temp"), column("t"))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, FitPoses) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


class Calibration(ABC):
    """A calibration: raw accelerometer samples in, specific force in g out.

    Subclasses are dataclasses (``eq=False``) registered in :mod:`optcal.families.calibration_files`; each
    documents its parameters, units and equation in its own docstring, and defines
    :meth:`correct`, :meth:`parameters`, :meth:`from_parameters`, :meth:`unit_fields` and
    :meth:`lumped`.  Two calibrations are equal when their files would be equal (same type,
    same numbers, same units).

    Attributes
    ----------
    cal_type : str
        The type name written into the file.
    format_version : str
        The semantic version of the file format.
    units : str
        Input units (``g``, ``m/s^2`` or ``counts``); the output is always in g.
    fitted_on : FitPoses or None
        The static poses the calibration was fitted on.
    """

    cal_type: ClassVar[str]
    units: str
    fitted_on: FitPoses | None

    @property
    def format_version(self) -> str:
        """:data:`~optcal.core.jsonio.FORMAT_VERSION`; a type whose files may carry more says which minor version."""
        return FORMAT_VERSION

    # ----------------------------------------------------------------- per type
    @abstractmethod
    def correct(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """Calibrated specific force in g, shape (n, 3), for raw samples ``acc`` (n, 3).

        Parameters
        ----------
        acc : array_like, shape (n, 3)
            Raw samples in :attr:`units`.
        temp : array_like, shape (n,), optional
            Temperature of each sample, °C (needed when the calibration has temperature terms).
        t : array_like, shape (n,), optional
            Time of each sample, s, on the time base of the fit (needed for drift terms).

        Returns
        -------
        ndarray, shape (n, 3)
            Specific force, g.
        """

    @abstractmethod
    def parameters(self) -> dict[str, Any]:
        """The type's own numbers, JSON-safe (written next to ``cal_type`` and ``units``).

        Returns
        -------
        dict
            Parameter name to value (arrays as nested lists once made JSON-safe).
        """

    @classmethod
    @abstractmethod
    def from_parameters(cls: type[CalibrationT], d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> CalibrationT:
        """Rebuild the calibration from the entries written by :meth:`parameters`.

        Parameters
        ----------
        d : dict
            The file's JSON object (the entries of :meth:`parameters` among others).
        units : str
            Input units (``g``, ``m/s^2`` or ``counts``).
        fitted_on : FitPoses or None
            The poses the calibration was fitted on, when the file records them.

        Returns
        -------
        Calibration
            Of the class it is called on.
        """

    @abstractmethod
    def unit_fields(self) -> dict[str, str]:
        """Units of each parameter, e.g. ``{"T": "g per counts", "o": "counts"}``.

        Returns
        -------
        dict of str to str
        """

    @abstractmethod
    def lumped(self) -> Any:
        """The closest :class:`~optcal.families.caltypes.lumped.LumpedCalibration` (``T`` canonical, ``o``).

        Returns
        -------
        LumpedCalibration
        """

    # ------------------------------------------------------------------- shared
    @property
    def needs(self) -> tuple[str, ...]:
        """Per-sample columns :meth:`correct` needs besides the acceleration (``"temp"``, ``"t"``)."""
        return ()

    def out_of_range(
        self, corrected: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None
    ) -> NDArray[np.bool_]:
        """Which samples lie outside the range the calibration was fitted on (none, unless the type has one).

        Parameters
        ----------
        corrected : array_like, shape (n, 3)
            Corrected samples, g (:meth:`correct`'s output).
        temp : array_like, shape (n,), optional
            Temperature of each sample, °C.
        t : array_like, shape (n,), optional
            Time of each sample, s.

        Returns
        -------
        ndarray of bool, shape (n,)
            True where a sample lies outside the fitted range.
        """
        return np.zeros(as_samples(corrected, "corrected").shape[0], dtype=bool)

    def norm_errors(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """``‖ā_k‖ − 1`` in g for static samples or poses (Lu 2017, eq. 13).

        Parameters
        ----------
        acc : array_like, shape (n, 3)
            Raw static samples or poses in :attr:`units`.
        temp, t : array_like, shape (n,), optional
            As for :meth:`correct`.

        Returns
        -------
        ndarray, shape (n,)
            The norm error of each, g.
        """
        return np.linalg.norm(self.correct(acc, temp, t), axis=1) - 1.0

    def to_dict(self) -> dict[str, Any]:
        """The file's JSON object.

        Returns
        -------
        dict
            ``cal_type``, ``format_version``, ``units`` (input and each parameter's), the
            :meth:`parameters` and, when known, ``fitted_on``.
        """
        d: dict[str, Any] = {
            "cal_type": self.cal_type,
            "format_version": self.format_version,
            "units": units_dict(self.units, **self.unit_fields()),
        }
        d.update(jsonable(self.parameters()))
        if self.fitted_on is not None:
            d["fitted_on"] = self.fitted_on.to_dict()
        return d

    @classmethod
    def from_dict(cls: type[CalibrationT], d: dict[str, Any]) -> CalibrationT:
        """Rebuild a calibration of this type from :meth:`to_dict` (extra keys are ignored).

        Parameters
        ----------
        d : dict
            The file's JSON object.

        Returns
        -------
        Calibration
            Of the class it is called on.

        Raises
        ------
        InputError
            Another ``cal_type``, an unknown format version or input units, or missing or malformed entries.
        """
        if not isinstance(d, dict):
            raise InputError("a calibration is a JSON object (a dictionary)")
        found = d.get("cal_type")
        if found != cls.cal_type:
            raise InputError(f"this is a {found!r} calibration, not {cls.cal_type!r}; read it with optcal.families.calibration_files.load")
        check_version(d.get("format_version"))
        units = d.get("units")
        units = units.get("input") if isinstance(units, dict) else units
        if units not in ACCEL_UNITS:
            raise InputError(f"the calibration's input units {units!r} are not one of {', '.join(ACCEL_UNITS)}")
        fitted = d.get("fitted_on")
        try:
            return cls.from_parameters(d, str(units), None if fitted is None else FitPoses.from_dict(fitted))
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"not a valid {cls.cal_type!r} calibration ({exc.__class__.__name__}: {exc})") from exc

    def save(self, path: str | Path) -> None:
        """Write the calibration as JSON (:func:`optcal.core.jsonio.write_json`: whole or not at all).

        Parameters
        ----------
        path : str or Path
            The file written (replaced when it exists).
        """
        write_json(path, self.to_dict())

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    def describe(self) -> str:
        """One line: type, units and the size of the fit set.

        Returns
        -------
        str
        """
        fitted = f", fitted on {self.fitted_on.n} poses" if self.fitted_on is not None else ""
        return f"{self.cal_type} calibration ({self.units} in, g out{fitted})"
