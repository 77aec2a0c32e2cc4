"""The lumped calibration ``ā = T (a − o)`` of the self-calibrating estimators (Lu 2017, eq. 6).

Parameters, units and equation
------------------------------
======  ==============  =====================================================================
``T``   g per raw unit  3×3, **lower-triangular with a positive diagonal** (optcal's canonical
                        identifiable form, :mod:`optcal.core.model`): scale, non-orthogonality
``o``   raw units       3, the zero offset (bias)
======  ==============  =====================================================================

::

    ā = T (a − o)                                                      Lu 2017, eq. 6

Only ``A = TᵀT`` and ``o`` are identifiable from static data; the canonical ``T`` fixes the
unidentifiable rotation (the calibrated frame has x along the sensor's x axis and y in its
x-y plane).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.families.caltypes.base import Calibration, FitPoses, as_samples, read_matrix
from optcal.errors import InputError
from optcal.core.model import LumpedModel, canonicalise, theta_from


@dataclass(eq=False)
class LumpedCalibration(Calibration):
    """``ā = T (a − o)`` with canonical lower-triangular ``T`` (see the module docstring).

    Attributes
    ----------
    T : ndarray, shape (3, 3)
        Lower-triangular, positive diagonal, g per raw unit.
    o : ndarray, shape (3,)
        Bias, raw units.
    units : str
        Raw units (``g``, ``m/s^2`` or ``counts``).
    fitted_on : FitPoses, optional
    """

    cal_type: ClassVar[str] = "lumped"

    T: NDArray[np.float64]
    o: NDArray[np.float64]
    units: str = "g"
    fitted_on: FitPoses | None = field(default=None)

    def __post_init__(self) -> None:
        T = np.array(self.T, dtype=float).reshape(3, 3)
        o = np.array(self.o, dtype=float).reshape(3)
        if not (np.all(np.isfinite(T)) and np.all(np.isfinite(o))):
            raise InputError("T and o must be finite")
        if np.any(np.triu(T, 1) != 0) or np.any(np.diag(T) <= 0):
            raise InputError(
                "T of a lumped calibration must be lower-triangular with a positive diagonal (optcal's canonical "
                "form); build it with LumpedCalibration.from_model(model) or pass optcal.core.model.canonicalise(T)"
            )
        self.T, self.o = T, o

    @classmethod
    def from_model(cls, model: LumpedModel, units: str = "g", fitted_on: FitPoses | None = None) -> "LumpedCalibration":
        """The calibration of a :class:`~optcal.core.model.LumpedModel` (``T`` canonicalised).

        Parameters
        ----------
        model : LumpedModel
            The fitted model.
        units : str
            Input units (``g``, ``m/s^2`` or ``counts``).
        fitted_on : FitPoses, optional
            The poses it was fitted on.

        Returns
        -------
        LumpedCalibration
        """
        return cls(model.T_canonical, model.o, units, fitted_on)

    @classmethod
    def from_any_T(cls, T: ArrayLike, o: ArrayLike, units: str = "g", fitted_on: FitPoses | None = None) -> "LumpedCalibration":
        """From any invertible ``T``: kept when already canonical, else mapped to the canonical form.

        Parameters
        ----------
        T : array_like, shape (3, 3)
            The correction matrix (g per input unit).
        o : array_like, shape (3,)
            The offset, input units.
        units : str
            Input units (``g``, ``m/s^2`` or ``counts``).
        fitted_on : FitPoses, optional
            The poses it was fitted on.

        Returns
        -------
        LumpedCalibration
            With ``T`` lower triangular with a positive diagonal (Lu 2017, eq. 6's canonical form).
        """
        T = np.asarray(T, dtype=float).reshape(3, 3)
        if np.any(np.triu(T, 1) != 0) or np.any(np.diag(T) <= 0):
            T = canonicalise(T)
        return cls(T, np.asarray(o, dtype=float), units, fitted_on)

    @property
    def theta(self) -> NDArray[np.float64]:
        """The parameter vector θ of :mod:`optcal.core.model`."""
        return theta_from(self.T, self.o)

    @property
    def model(self) -> LumpedModel:
        """The equivalent :class:`~optcal.core.model.LumpedModel` (``C = T⁻¹``)."""
        return LumpedModel.from_T(self.T, self.o)

    def correct(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """``T (a − o)`` in g (Lu 2017, eq. 6); ``temp`` and ``t`` are not used.

        Parameters
        ----------
        acc : array_like, shape (n, 3)
            Raw samples in :attr:`units`.
        temp, t : array_like, shape (n,), optional
            Ignored (the lumped model has no temperature or time terms).

        Returns
        -------
        ndarray, shape (n, 3)
            Specific force, g.
        """
        return (as_samples(acc) - self.o) @ self.T.T

    def parameters(self) -> dict[str, Any]:
        return {"T": self.T, "o": self.o}

    @classmethod
    def from_parameters(cls, d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> "LumpedCalibration":
        return cls(read_matrix(d, "T", (3, 3)), read_matrix(d, "o", (3,)), units, fitted_on)

    def unit_fields(self) -> dict[str, str]:
        return {"T": f"g per {self.units}", "o": self.units}

    def lumped(self) -> "LumpedCalibration":
        return self
