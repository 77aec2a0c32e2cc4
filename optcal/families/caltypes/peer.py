"""A calibration made by another tool (imucal, imu_tk), held exactly as that tool applies it.

Parameters, units and equation
------------------------------
=================  =====================  ======================================================
``W``              g per raw unit         3×3, full: the peer's scale, misalignment and frame
                                          (not reduced to optcal's canonical form)
``o``              raw units              3, the peer's accelerometer bias
``gravity_m_s2``   m/s²                   the g the peer's m/s² output is scaled to (its
                                          ``grav``/``g_mag``): ``W = M / g`` for the peer's
                                          matrix ``M`` in m/s² per raw unit
``Tg``             rad/s per gyro unit    3×3 full (optional): the peer's gyro matrix
``bg``             gyro units             gyro bias (optional)
``Gg``             gyro units per g       the acceleration's influence on the gyro (imucal's
                                          ``K_ga`` times g; optional)
=================  =====================  ======================================================

::

    ā = W (a − o)                      in g;  the peer's own output is g·ā (m/s²)
    ω = T_g (g − b_g − G_g ā)          rad/s, in the peer's accelerometer frame

imucal (``imucal/ferraris_calibration_info.py``, ``_calibrate_acc`` and ``_calibrate_gyr``)::

    acc = R_a⁻¹ K_a⁻¹ (raw − b_a)                          m/s²
    gyr = R_g⁻¹ K_g⁻¹ (raw − K_ga acc − b_g)               deg/s

so ``W = R_a⁻¹ K_a⁻¹ / g``, ``o = b_a``, ``T_g = (π/180) R_g⁻¹ K_g⁻¹``, ``b_g = b_g``,
``G_g = g K_ga``.  imu_tk (``include/imu_tk/calibration.h``, ``CalibratedTriad_::unbiasNormalize``)::

    X' = T K (X − B)                     acc in m/s² (at imu_tk's g_mag), gyro in rad/s

so ``W = T K / g``, ``o = B`` and ``T_g = T K``, ``b_g = B``.  The readers are in
:mod:`optcal.families.peer_files`; the peer's own numbers, units and file are kept in
:attr:`PeerCalibration.peer` so that what optcal applies can be traced back to them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.gyro_model import GyroModel
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration, FitPoses, as_samples, read_matrix
from optcal.families.caltypes.lumped import LumpedCalibration


@dataclass(eq=False)
class PeerCalibration(Calibration):
    """Another tool's calibration (module docstring).

    Attributes
    ----------
    tool : str
        ``imucal`` or ``imu_tk``.
    peer_type : str
        The peer's own name of its method (imucal's ``cal_type``: ``Ferraris``, ``Turntable``;
        imu_tk: ``multi-position``).
    W : ndarray, shape (3, 3)
        g per raw unit.
    o : ndarray, shape (3,)
        Raw units.
    units : str
        Accelerometer input units (``g``, ``m/s^2``, ``counts``).
    gravity_m_s2 : float
        The g of the peer's m/s² output, and :attr:`gravity_reason` where it came from.
    gyro : GyroModel, optional
        The peer's gyro calibration (``T_g`` rad/s per gyro unit, ``b_g``, ``G_g`` per g).
    gyro_units : str, optional
        Gyro input units (``counts``, ``rad/s``, ``deg/s``).
    source : str
        The file(s) it was read from.
    read_as : str
        How the file was recognised (its content, not its name).
    peer : dict
        The peer's own parameters, names and units as in its file.
    notes : list of str
        What the reader assumed.
    """

    cal_type: ClassVar[str] = "peer"

    tool: str
    peer_type: str
    W: NDArray[np.float64]
    o: NDArray[np.float64]
    units: str
    gravity_m_s2: float
    gravity_reason: str = ""
    gyro: GyroModel | None = None
    gyro_units: str | None = None
    source: str = ""
    read_as: str = ""
    peer: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    fitted_on: FitPoses | None = None

    def __post_init__(self) -> None:
        W = np.array(self.W, dtype=float).reshape(3, 3)
        o = np.array(self.o, dtype=float).reshape(3)
        if not (np.all(np.isfinite(W)) and np.all(np.isfinite(o))) or abs(np.linalg.det(W)) < 1e-300:
            raise InputError(f"the {self.tool} calibration's accelerometer matrix must be finite and invertible")
        if not (np.isfinite(self.gravity_m_s2) and self.gravity_m_s2 > 0):
            raise InputError(f"the gravity of a peer calibration must be positive, got {self.gravity_m_s2}")
        if (self.gyro is None) != (self.gyro_units is None):
            raise InputError("a peer calibration's gyro needs both its model and its input units")
        self.W, self.o = W, o

    # ------------------------------------------------------------------ naming
    @property
    def label(self) -> str:
        """The peer named by its tool and its method, e.g. ``imucal Ferraris``."""
        return f"{self.tool} {self.peer_type}"

    @property
    def has_gyro(self) -> bool:
        return self.gyro is not None

    @property
    def T(self) -> NDArray[np.float64]:
        """``W``: the accelerometer matrix (g per raw unit), under the name the gyro checks read."""
        return self.W

    @property
    def accelerometer(self) -> "PeerCalibration":
        """The accelerometer part (this calibration: :meth:`correct` and :attr:`T`), as the gyro checks read it."""
        return self

    def describe(self) -> str:
        gyro = f"; gyro {self.gyro_units} in, rad/s out" if self.gyro is not None else "; no gyro"
        return (f"{self.label} calibration ({self.units} in, g out, 1 g = {self.gravity_m_s2:g} m/s^2 "
                f"[{self.gravity_reason}]{gyro}); {self.read_as}")

    # ------------------------------------------------------------- Calibration
    def correct(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """``W (a − o)`` in g: the peer's own output divided by its g (module docstring).

        Parameters
        ----------
        acc : array_like, shape (n, 3)
            Raw samples in :attr:`units`.
        temp, t : array_like, shape (n,), optional
            Ignored (the peers' models have no temperature or time terms).

        Returns
        -------
        ndarray, shape (n, 3)
            Specific force, g.
        """
        return (as_samples(acc) - self.o) @ self.W.T

    def correct_gyro(self, gyro: ArrayLike, acc: ArrayLike | None = None) -> NDArray[np.float64]:
        """Body rate in rad/s, ``T_g (g − b_g − G_g ā)`` (``acc``: raw accelerometer samples, for ``G_g``).

        Parameters
        ----------
        gyro : array_like, shape (n, 3)
            Raw gyro samples in :attr:`gyro_units`.
        acc : array_like, shape (n, 3), optional
            Raw accelerometer samples of the same rows (needed when the peer has a g-sensitivity ``G_g``).

        Returns
        -------
        ndarray, shape (n, 3)
            Body rate, rad/s.

        Raises
        ------
        InputError
            The peer's file has no gyroscope part.
        """
        if self.gyro is None:
            raise InputError(f"the {self.label} calibration ({self.source}) has no gyroscope part")
        f = None
        if self.gyro.g_sensitivity is not None:
            if acc is None:
                raise InputError("this gyro calibration has an acceleration influence: pass the raw accelerometer samples")
            f = self.correct(acc)
        return self.gyro.correct(as_samples(gyro, "gyro"), f)

    def parameters(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "tool": self.tool, "peer_type": self.peer_type, "W": self.W, "o": self.o,
            "gravity_m_s2": self.gravity_m_s2, "gravity_reason": self.gravity_reason,
            "source": self.source, "read_as": self.read_as, "peer": self.peer, "notes": list(self.notes),
        }
        if self.gyro is not None:
            d.update({"Tg": self.gyro.T, "bg": self.gyro.bias, "Gg": self.gyro.g_sensitivity,
                      "gyro_units": {"input": self.gyro_units, "output": "rad/s"}})
        return d

    @classmethod
    def from_parameters(cls, d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> "PeerCalibration":
        gyro, gyro_units = None, None
        if d.get("Tg") is not None:
            gs = d.get("Gg")
            gyro = GyroModel(read_matrix(d, "Tg", (3, 3)), read_matrix(d, "bg", (3,)),
                             None if gs is None else np.asarray(gs, float).reshape(3, 3))
            gyro_units = str(d["gyro_units"]["input"])
        return cls(str(d["tool"]), str(d["peer_type"]), read_matrix(d, "W", (3, 3)), read_matrix(d, "o", (3,)), units,
                   float(d["gravity_m_s2"]), str(d.get("gravity_reason", "")), gyro, gyro_units, str(d.get("source", "")),
                   str(d.get("read_as", "")), dict(d.get("peer") or {}), list(d.get("notes") or []), fitted_on)

    def unit_fields(self) -> dict[str, str]:
        out = {"W": f"g per {self.units}", "o": self.units, "gravity_m_s2": "m/s^2"}
        if self.gyro is not None:
            out.update({"Tg": f"rad/s per {self.gyro_units}", "bg": str(self.gyro_units), "Gg": f"{self.gyro_units} per g"})
        return out

    def lumped(self) -> LumpedCalibration:
        """The lumped calibration with the same norms (``A = WᵀW``, ``o``); the peer's frame is dropped.

        Returns
        -------
        LumpedCalibration
        """
        return LumpedCalibration.from_any_T(self.W, self.o, self.units, self.fitted_on)


__all__ = ["PeerCalibration"]
