"""The extended forward model of a triaxial accelerometer and its closed-form inversion.

The paper's model (Lu 2017, eq. 5) is ``a = C ā + o + n`` with constant ``C`` and ``o``.
:class:`ExtendedModel` adds temperature, time and nonlinearity terms; it is the forward model
the diagnosis (:mod:`optcal.applications.diagnosis`) fits and the model an extended calibration applies.

Extended forward model
----------------------
"Axis i" is always **sensor output axis i** (x, y, z: the raw columns ``ax, ay, az``).  With
``y = C ā`` the linear lumped output (raw units), ``S_i = ‖row i of C‖`` the sensitivity of
axis i (raw units per g) and ``f_i = y_i / S_i`` the true specific force along sensing axis i
(g; the rows of ``C/S`` are the unit sensing directions, Lu 2017 eq. 1), output i is::

    a_i = (1 + Σ_p s_ip ΔT^p) · S_i (f_i + k2_i f_i²)
          + o_i + S_i (Σ_p k_ip ΔT^p + Σ_p d_ip Δt^p) + n_i

    ΔT = temp − T_ref,   Δt = t − t_ref

The terms and the units of their order-``p`` coefficients:

=====================  =========================================================  ==========
``temperature_bias``   bias of axis i is ``o_i + S_i Σ k_ip ΔT^p``                  g/°C^p
``temperature_scale``  output of axis i is scaled by ``1 + Σ s_ip ΔT^p``            1/°C^p
``bias_drift``         bias of axis i is ``o_i + S_i Σ d_ip Δt^p``                  g/s^p
``scale_nonlinearity`` axis i gains ``k2_i f_i²``, quadratic in the true force      g/g²
=====================  =========================================================  ==========

Bias terms are per g (``S_i`` converts them to raw units), so coefficients do not depend on
the raw units.  With all coefficients zero the model is exactly the paper's.  The
nonlinearity acts on the force *along the sensing axis*, which makes it invariant to the
unidentifiable rotation of ``C`` (``C → C Q``, ``ā → Qᵀ ā`` leaves ``y`` and hence ``f``
unchanged).

Inversion
---------
Every term is inverted in closed form per axis (:func:`invert_axis`): ``z = a − o − S·bias``,
``w = z/(1 + scale)``, ``y = 2w / (1 + √(1 + 4 k2 w / S))`` solves ``S(f + k2 f²) = w``; the
calibrated specific force is ``T y`` (Lu 2017, eq. 6).  The same function, given CasADi's
``sqrt``, is the residual of the diagnosis's fit, so the fit and the applied calibration
invert the model identically.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.model import AXES, LumpedModel

#: The terms of the extended model, in the order they are reported.
PARAMETRIC: tuple[str, ...] = ("temperature_bias", "temperature_scale", "bias_drift", "scale_nonlinearity")
#: Highest polynomial order of each term.
MAX_ORDER: dict[str, int] = {"temperature_bias": 3, "temperature_scale": 2, "bias_drift": 3, "scale_nonlinearity": 1}
#: Column each term needs (``None``: none).
NEEDS: dict[str, str | None] = {
    "temperature_bias": "temp", "temperature_scale": "temp", "bias_drift": "t", "scale_nonlinearity": None,
}
#: Units of each term's first-order coefficient.
UNITS: dict[str, str] = {
    "temperature_bias": "g/°C", "temperature_scale": "1/°C", "bias_drift": "g/s", "scale_nonlinearity": "g/g²",
}


def axis_number(axis: str | int) -> int:
    """0, 1, 2 for ``"x"``, ``"y"``, ``"z"`` (or the number itself)."""
    if isinstance(axis, (int, np.integer)) and 0 <= int(axis) < 3:
        return int(axis)
    if axis in AXES:
        return AXES.index(str(axis))
    raise InputError(f"unknown axis {axis!r}; use x, y or z")


def inverse_lower(L: Any) -> list[list[Any]]:
    """Entries of the inverse of the lower-triangular 3×3 matrix ``L`` (works for CasADi and numpy)."""
    c00 = 1 / L[0][0]
    c11 = 1 / L[1][1]
    c22 = 1 / L[2][2]
    c10 = -L[1][0] * c00 * c11
    c21 = -L[2][1] * c11 * c22
    c20 = (L[1][0] * L[2][1] - L[1][1] * L[2][0]) * c00 * c11 * c22
    return [[c00, 0, 0], [c10, c11, 0], [c20, c21, c22]]


def invert_axis(z: Any, S: Any, bias: Any, scale: Any, k2: Any, sqrt: Callable, fmax: Callable) -> Any:
    """Linear output ``y_i`` of one axis from ``z_i = a_i − o_i`` (the module docstring, inverted).

    ``bias`` (g) and ``scale`` (relative) are the polynomial terms at the pose, ``k2`` the
    nonlinearity; ``y = 2w/(1 + √(1 + 4 k2 w/S))`` is the root of ``S(f + k2 f²) = w`` that
    tends to ``w`` as ``k2 → 0`` (no cancellation at ``k2 = 0``).
    """
    w = (z - S * bias) / (1 + scale)
    return 2 * w / (1 + sqrt(fmax(1 + 4 * k2 * w / S, 1e-6)))


@dataclass
class ExtendedModel:
    """The extended forward model with physical coefficients (module docstring).

    Attributes
    ----------
    base : LumpedModel
        ``C`` and ``o`` (raw units).
    coefficients : dict of str to ndarray, shape (3, MAX_ORDER[effect])
        Per effect and axis, the polynomial coefficients of orders 1.. (``g/°C^p``,
        ``1/°C^p``, ``g/s^p``; ``g/g²`` for the nonlinearity).  Missing effects are zero.
    temp_ref, t_ref : float
        ``T_ref`` (°C) and ``t_ref`` (s).
    """

    base: LumpedModel
    coefficients: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    temp_ref: float = 25.0
    t_ref: float = 0.0

    def __post_init__(self) -> None:
        full: dict[str, NDArray[np.float64]] = {}
        for effect in PARAMETRIC:
            c = np.zeros((3, MAX_ORDER[effect]))
            if effect in self.coefficients:
                given = np.asarray(self.coefficients[effect], dtype=float).reshape(3, -1)
                if given.shape[1] > MAX_ORDER[effect]:
                    raise InputError(f"{effect}: at most order {MAX_ORDER[effect]}")
                c[:, : given.shape[1]] = given
            full[effect] = c
        unknown = set(self.coefficients) - set(PARAMETRIC)
        if unknown:
            raise InputError(f"unknown effect(s) {', '.join(sorted(unknown))}; use {', '.join(PARAMETRIC)}")
        self.coefficients = full

    @classmethod
    def with_effect(
        cls,
        base: LumpedModel,
        effect: str,
        axis: str | int,
        value: float | ArrayLike,
        temp_ref: float = 25.0,
        t_ref: float = 0.0,
    ) -> "ExtendedModel":
        """A model with one effect on one axis (``value``: first-order coefficient, or orders 1..)."""
        if effect not in PARAMETRIC:
            raise InputError(f"{effect!r} is not a parametric effect; use one of {', '.join(PARAMETRIC)}")
        c = np.zeros((3, MAX_ORDER[effect]))
        v = np.atleast_1d(np.asarray(value, dtype=float))
        c[axis_number(axis), : v.size] = v
        return cls(base, {effect: c}, temp_ref, t_ref)

    def sensitivity(self) -> NDArray[np.float64]:
        """``S_i = ‖row i of C‖``, raw units per g."""
        return np.linalg.norm(self.base.C, axis=1)

    def _terms(self, n: int, temp: ArrayLike | None, t: ArrayLike | None) -> tuple[NDArray, NDArray]:
        """Bias (g) and relative scale terms of each pose and axis, shape (n, 3) each."""
        bias, scale = np.zeros((n, 3)), np.zeros((n, 3))
        needs_temp = np.any(self.coefficients["temperature_bias"]) or np.any(self.coefficients["temperature_scale"])
        if needs_temp:
            if temp is None:
                raise InputError("the model has temperature terms: give the temperature of each pose")
            dT = np.asarray(temp, float).reshape(n) - self.temp_ref
            powers = np.column_stack([dT**p for p in range(1, 4)])
            bias += powers[:, : MAX_ORDER["temperature_bias"]] @ self.coefficients["temperature_bias"].T
            scale += powers[:, : MAX_ORDER["temperature_scale"]] @ self.coefficients["temperature_scale"].T
        if np.any(self.coefficients["bias_drift"]):
            if t is None:
                raise InputError("the model has a bias drift: give the time of each pose")
            dt = np.asarray(t, float).reshape(n) - self.t_ref
            bias += np.column_stack([dt**p for p in range(1, 4)]) @ self.coefficients["bias_drift"].T
        return bias, scale

    def distort(self, linear: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """Measurements from the linear outputs ``y = C ā`` (raw, without ``o``), shape (n, 3)."""
        y = np.asarray(linear, dtype=float).reshape(-1, 3)
        S = self.sensitivity()
        f = y / S
        k2 = self.coefficients["scale_nonlinearity"][:, 0]
        bias, scale = self._terms(len(y), temp, t)
        return (1 + scale) * S * (f + k2 * f**2) + self.base.o + S * bias

    def measure(self, directions: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """Noise-free measurements of unit directions (n, 3) at the poses' temperature and time."""
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        return self.distort(d @ self.base.C.T, temp, t)

    def linear_output(self, raw: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """``y = C ā`` recovered from measurements (the model inverted per axis)."""
        a = np.asarray(raw, dtype=float).reshape(-1, 3)
        S = self.sensitivity()
        bias, scale = self._terms(len(a), temp, t)
        k2 = self.coefficients["scale_nonlinearity"][:, 0]
        return invert_axis(a - self.base.o, S, bias, scale, k2, np.sqrt, np.maximum)

    def correct(self, raw: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """Calibrated specific force ``T y(a)`` in g (Lu 2017, eq. 6, with the extensions removed)."""
        return self.linear_output(raw, temp, t) @ self.base.T.T

    def active(self) -> list[tuple[str, str, int]]:
        """(effect, axis, order) of every non-zero coefficient."""
        return [
            (effect, AXES[i], p + 1)
            for effect in PARAMETRIC
            for i in range(3)
            for p in range(MAX_ORDER[effect])
            if self.coefficients[effect][i, p] != 0
        ]



def format_value(effect: str, value: float, stderr: float | None = None) -> str:
    """A first-order coefficient of ``effect`` in readable units (mg/°C, ppm/°C, µg/s, mg/g²) with its standard error."""
    factor, unit = {
        "temperature_bias": (1e3, "mg/°C"),
        "temperature_scale": (1e6, "ppm/°C"),
        "bias_drift": (1e6, "µg/s"),
        "scale_nonlinearity": (1e3, "mg/g²"),
        "session_bias": (1e3, "mg"),  # a bias offset between sessions (turn-on repeatability), g
    }[effect]
    text = f"{value * factor:+.3g}"
    if stderr is not None and np.isfinite(stderr):
        text += f" ± {stderr * factor:.2g}"
    return f"{text} {unit}"

