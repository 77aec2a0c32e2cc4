"""The full six-position calibration ``ā = W a + V`` (Yin 2014, eq. 3).

Parameters, units and equation
------------------------------
======  ==============  =====================================================================
``W``   g per raw unit  3×3, full: scale, misalignment, cross-coupling **and** the rotation
                        to the reference frame of the known orientations
``V``   g               3, the bias term (``V = −W b``)
======  ==============  =====================================================================

::

    ā = W a + V                                                        Yin 2014, eq. 3

With known orientations the rotation of ``W`` is identifiable, so ``W`` is not reduced to
optcal's canonical lower-triangular form; :meth:`SixPositionCalibration.lumped` gives the
lumped calibration with the same ``A = WᵀW`` and ``o = −W⁻¹V`` (the same norms).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.families.caltypes.base import Calibration, FitPoses, as_samples, read_matrix
from optcal.families.caltypes.lumped import LumpedCalibration
from optcal.errors import InputError


@dataclass(eq=False)
class SixPositionCalibration(Calibration):
    """``ā = W a + V`` with a full ``W`` (see the module docstring).

    Attributes
    ----------
    W : ndarray, shape (3, 3)
        g per raw unit.
    V : ndarray, shape (3,)
        g.
    units : str
        Raw units (``g``, ``m/s^2`` or ``counts``).
    fitted_on : FitPoses, optional
    """

    cal_type: ClassVar[str] = "sixpos_full"

    W: NDArray[np.float64]
    V: NDArray[np.float64]
    units: str = "g"
    fitted_on: FitPoses | None = field(default=None)

    def __post_init__(self) -> None:
        W = np.array(self.W, dtype=float).reshape(3, 3)
        V = np.array(self.V, dtype=float).reshape(3)
        if not (np.all(np.isfinite(W)) and np.all(np.isfinite(V))):
            raise InputError("W and V must be finite")
        if abs(np.linalg.det(W)) < 1e-300:
            raise InputError("W must be invertible")
        self.W, self.V = W, V

    @property
    def o(self) -> NDArray[np.float64]:
        """The bias ``o = −W⁻¹ V`` in raw units (``ā = W (a − o)``)."""
        return -np.linalg.solve(self.W, self.V)  # type: ignore[return-value]  # numpy stubs type solve of float64 as floating[Any]

    def correct(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """``W a + V`` in g (Yin 2014, eq. 3); ``temp`` and ``t`` are not used.

        Parameters
        ----------
        acc : array_like, shape (n, 3)
            Raw samples in :attr:`units`.
        temp, t : array_like, shape (n,), optional
            Ignored (the six-position model has no temperature or time terms).

        Returns
        -------
        ndarray, shape (n, 3)
            Specific force, g.
        """
        return as_samples(acc) @ self.W.T + self.V

    def parameters(self) -> dict[str, Any]:
        return {"W": self.W, "V": self.V}

    @classmethod
    def from_parameters(cls, d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> "SixPositionCalibration":
        return cls(read_matrix(d, "W", (3, 3)), read_matrix(d, "V", (3,)), units, fitted_on)

    def unit_fields(self) -> dict[str, str]:
        return {"W": f"g per {self.units}", "V": "g"}

    def lumped(self) -> LumpedCalibration:
        return LumpedCalibration.from_any_T(self.W, self.o, self.units, self.fitted_on)
