"""User constraints on the calibration's parameters: fixed values and bounds, by name.

A user who knows a parameter (a bias from the datasheet, a scale factor from a previous run)
fixes it; one who knows its range bounds it.  The names are those of the reports:

* the entries of θ (:data:`optcal.core.model.PARAM_NAMES`): ``T_xx`` ... ``T_zz`` (g per raw
  unit), ``o_x``, ``o_y``, ``o_z`` (the bias, raw units; also spelt ``bias_x`` ...);
* the physical parameters of :meth:`optcal.core.model.LumpedModel.physical` (Lu 2017, eq. 1
  and 5, with ``C = T⁻¹ = S_M C_NO``): the scale factors ``S_x``, ``S_y``, ``S_z`` (raw units
  per g; also ``scale_x`` ...) and the non-orthogonality angles ``rho``, ``phi``, ``lambda``
  (degrees; also ``ρ``, ``φ``, ``λ``, ``lam``).

A θ entry is a bound on a decision variable of the NLP; a physical parameter is a nonlinear
function ``q(θ)`` of them, a general constraint ``lo ≤ q(θ) ≤ hi``.  At the optimum, the
constraints held as equalities (the fixed parameters and the bounds that are active) remove
directions from the covariance: it is the inverse Fisher information on the free subspace,
``Σ = N (Nᵀ F N)⁻¹ Nᵀ`` with N a basis of the null space of their gradients
(:func:`constrained_covariance`), so a fixed parameter has standard error zero.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import AXES, PARAM_NAMES
from optcal.errors import InputError

#: The physical parameters a user may constrain, with their units.
PHYSICAL_NAMES: tuple[str, ...] = ("S_x", "S_y", "S_z", "rho", "phi", "lambda")
PHYSICAL_UNITS: dict[str, str] = {"S_x": "raw units/g", "S_y": "raw units/g", "S_z": "raw units/g",
                                  "rho": "deg", "phi": "deg", "lambda": "deg"}
#: Other spellings of the names.
ALIASES: dict[str, str] = {
    **{f"bias_{a}": f"o_{a}" for a in AXES}, **{f"scale_{a}": f"S_{a}" for a in AXES},
    "ρ": "rho", "φ": "phi", "λ": "lambda", "lam": "lambda",
}
#: A bound counts as active when the parameter lies within this fraction of its standard error
#: (or, without one, of its magnitude) from it: the solvers stop at 1e-10 relative, so a free
#: optimum that happens to lie this close to the bound is indistinguishable from a held one.
ACTIVE_TOLERANCE: float = 1e-6


def canonical_name(name: str) -> str:
    """The name as the reports spell it, or :class:`InputError` naming the valid ones."""
    key = name.strip()
    key = ALIASES.get(key, ALIASES.get(key.lower(), key))
    if key in PARAM_NAMES or key in PHYSICAL_NAMES:
        return key
    raise InputError(f"unknown parameter {name!r}; use one of {', '.join(PARAM_NAMES + PHYSICAL_NAMES)} "
                     f"(also {', '.join(ALIASES)})")


@dataclass(frozen=True)
class ParameterConstraints:
    """Fixed values and bounds on named parameters (see the module docstring).

    Attributes
    ----------
    fixed : dict
        ``{name: value}``.
    bounds : dict
        ``{name: (low, high)}``; ``±inf`` for a one-sided bound.
    """

    fixed: dict[str, float] = field(default_factory=dict)
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)

    @classmethod
    def of(cls, fixed: Mapping[str, float] | None = None,
           bounds: Mapping[str, tuple[float, float]] | None = None) -> "ParameterConstraints":
        """Checked and named canonically; a parameter both fixed and bounded, or an empty range, is refused."""
        fx: dict[str, float] = {}
        for name, value in (fixed or {}).items():
            key = canonical_name(name)
            if not np.isfinite(float(value)):
                raise InputError(f"the fixed value of {name} must be finite, got {value}")
            fx[key] = float(value)
        bd: dict[str, tuple[float, float]] = {}
        for name, pair in (bounds or {}).items():
            key = canonical_name(name)
            lo, hi = (float(pair[0]), float(pair[1]))
            if np.isnan(lo) or np.isnan(hi) or lo > hi:
                raise InputError(f"empty bound for {name}: low {lo} > high {hi}")
            if key in fx:
                raise InputError(f"{name} is both fixed and bounded; give one of them")
            bd[key] = (lo, hi)
        return cls(fx, bd)

    def __bool__(self) -> bool:
        return bool(self.fixed or self.bounds)

    @property
    def physical(self) -> tuple[str, ...]:
        """The constrained physical parameters (general constraints of the NLP), in :data:`PHYSICAL_NAMES` order."""
        names = set(self.fixed) | set(self.bounds)
        return tuple(n for n in PHYSICAL_NAMES if n in names)

    def range_of(self, name: str) -> tuple[float, float]:
        if name in self.fixed:
            return self.fixed[name], self.fixed[name]
        return self.bounds.get(name, (-np.inf, np.inf))

    def theta_bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bounds on θ (raw units) from the θ entries fixed or bounded (±inf elsewhere)."""
        lb, ub = np.full(9, -np.inf), np.full(9, np.inf)
        for k, name in enumerate(PARAM_NAMES):
            lb[k], ub[k] = self.range_of(name)
        return lb, ub

    def to_dict(self) -> dict[str, Any]:
        return {"fixed": dict(self.fixed), "bounds": {k: [_json_float(lo), _json_float(hi)] for k, (lo, hi) in self.bounds.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "ParameterConstraints":
        d = d or {}
        return cls.of(d.get("fixed"), {k: (_from_json(v[0]), _from_json(v[1])) for k, v in (d.get("bounds") or {}).items()})


def _json_float(x: float) -> float | str:
    return x if np.isfinite(x) else ("inf" if x > 0 else "-inf")


def _from_json(x: Any) -> float:
    return float(x)


def parse_assignments(items: list[str] | tuple[str, ...], what: str) -> dict[str, str]:
    """``["o_x=12", "rho=0.1"]`` → ``{"o_x": "12", ...}`` (``what`` names the option in the error)."""
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise InputError(f"{what} {item!r} is not NAME=VALUE")
        out[name.strip()] = value.strip()
    return out


def parse_cli(fix: list[str] | tuple[str, ...], bound: list[str] | tuple[str, ...]) -> ParameterConstraints:
    """``--fix NAME=VALUE`` and ``--bound NAME=LOW:HIGH`` (an empty side is unbounded: ``S_x=:16500``)."""
    fixed: dict[str, float] = {}
    for name, text in parse_assignments(fix, "--fix").items():
        try:
            fixed[name] = float(text)
        except ValueError:
            raise InputError(f"--fix {name}={text}: the value is not a number") from None
    bounds: dict[str, tuple[float, float]] = {}
    for name, text in parse_assignments(bound, "--bound").items():
        lo, sep, hi = text.partition(":")
        if not sep:
            raise InputError(f"--bound {name}={text}: give LOW:HIGH (an empty side is unbounded)")
        try:
            bounds[name] = (float(lo) if lo.strip() else -np.inf, float(hi) if hi.strip() else np.inf)
        except ValueError:
            raise InputError(f"--bound {name}={text}: LOW and HIGH must be numbers") from None
    return ParameterConstraints.of(fixed, bounds)


class _NumpyMath:
    sqrt = staticmethod(np.sqrt)
    asin = staticmethod(np.arcsin)
    cos = staticmethod(np.cos)


def physical_of_theta(theta: Any, math: Any = _NumpyMath) -> list[Any]:
    """``(S_x, S_y, S_z, ρ, φ, λ)`` (angles in degrees) of θ, for numpy or CasADi symbols (``math``: sqrt, asin, cos).

    ``C = T⁻¹`` of the lower-triangular T in closed form, ``S_i = ‖C_i,:‖`` and the angles of
    ``C_NO = S_M⁻¹ C`` (Lu 2017, eq. 1), as :meth:`optcal.core.model.LumpedModel.physical`.
    """
    txx, tyx, tyy, tzx, tzy, tzz = (theta[k] for k in range(6))
    c00 = 1 / txx
    c10, c11 = -tyx / (txx * tyy), 1 / tyy
    c20, c21, c22 = (tyx * tzy - tyy * tzx) / (txx * tyy * tzz), -tzy / (tyy * tzz), 1 / tzz
    sx = math.sqrt(c00 * c00)
    sy = math.sqrt(c10 * c10 + c11 * c11)
    sz = math.sqrt(c20 * c20 + c21 * c21 + c22 * c22)
    deg = 180.0 / np.pi
    rho = math.asin(c10 / sy)
    lam = math.asin(c21 / sz)
    phi = math.asin(c20 / (sz * math.cos(lam)))
    return [sx, sy, sz, deg * rho, deg * phi, deg * lam]


def parameter_value(theta: NDArray, name: str) -> float:
    """The value of a named parameter (θ entry or physical) at θ (raw units)."""
    if name in PARAM_NAMES:
        return float(theta[PARAM_NAMES.index(name)])
    return float(physical_of_theta(np.asarray(theta, dtype=float))[PHYSICAL_NAMES.index(name)])


def parameter_gradient(theta: NDArray, name: str) -> NDArray[np.float64]:
    """``∂q/∂θ`` of a named parameter at θ (central differences for the physical ones)."""
    theta = np.asarray(theta, dtype=float)
    if name in PARAM_NAMES:
        return np.eye(9)[PARAM_NAMES.index(name)]
    steps = 1e-6 * np.maximum(np.abs(theta), np.max(np.abs(theta[:6])))
    g = np.empty(9)
    for k, h in enumerate(steps):
        e = np.zeros(9)
        e[k] = h
        g[k] = (parameter_value(theta + e, name) - parameter_value(theta - e, name)) / (2 * h)
    return g


@dataclass(frozen=True)
class ConstraintReport:
    """The constraints at an optimum: which hold as equalities and what that does to the covariance.

    Attributes
    ----------
    fixed : dict
        ``{name: value}`` as asked.
    bounds : dict
        ``{name: (low, high)}`` as asked.
    active : dict
        ``{name: "low" | "high"}``: the bounds the optimum sits on.
    values : dict
        Every constrained parameter's value at the optimum.
    """

    fixed: dict[str, float]
    bounds: dict[str, tuple[float, float]]
    active: dict[str, str]
    values: dict[str, float]

    @property
    def held(self) -> list[str]:
        """The parameters held as equalities at the optimum: fixed, and bounded with the bound active."""
        return [*self.fixed, *self.active]

    def covariance_note(self) -> str:
        if not self.held:
            return "no constraint active at the optimum: the covariance is the unconstrained inverse Fisher information"
        return (f"covariance computed on the free subspace: {', '.join(self.held)} held "
                f"({len(self.held)} of 9 directions removed; their standard errors are zero)")

    def lines(self) -> list[str]:
        out = [f"fixed {k} = {v:.10g}" for k, v in self.fixed.items()]
        for k, (lo, hi) in self.bounds.items():
            state = f"active at its {self.active[k]} end" if k in self.active else "inactive"
            out.append(f"bound {lo:.6g} <= {k} <= {hi:.6g}: {state} ({k} = {self.values[k]:.10g})")
        out.append(self.covariance_note())
        return out

    def to_dict(self) -> dict[str, Any]:
        return {**ParameterConstraints(self.fixed, self.bounds).to_dict(), "active": dict(self.active),
                "values": dict(self.values), "covariance": self.covariance_note()}


def constraint_report(constraints: ParameterConstraints, theta: NDArray, stderr: Callable[[str], float]) -> ConstraintReport:
    """Which bounds are active at θ (within :data:`ACTIVE_TOLERANCE` of the unconstrained standard error ``stderr(name)``)."""
    values = {n: parameter_value(theta, n) for n in [*constraints.fixed, *constraints.bounds]}
    active: dict[str, str] = {}
    for name, (lo, hi) in constraints.bounds.items():
        v = values[name]
        se = stderr(name)
        scale = se if np.isfinite(se) and se > 0 else max(abs(v), 1e-12)
        if np.isfinite(lo) and v - lo <= ACTIVE_TOLERANCE * scale:
            active[name] = "low"
        elif np.isfinite(hi) and hi - v <= ACTIVE_TOLERANCE * scale:
            active[name] = "high"
    return ConstraintReport(dict(constraints.fixed), dict(constraints.bounds), active, values)


def null_space(G: NDArray, rcond: float = 1e-10) -> NDArray[np.float64]:
    """An orthonormal basis (p, p − rank G) of the null space of the rows of G (m, p)."""
    if G.size == 0:
        return np.eye(G.shape[1])
    _, s, Vt = np.linalg.svd(G)
    rank = int(np.sum(s > rcond * max(s.max(), 1e-300)))
    return np.asarray(Vt[rank:].T)


def constrained_covariance(F: NDArray, G: NDArray) -> NDArray[np.float64]:
    """``N (Nᵀ F N)⁺ Nᵀ``: the covariance of θ with the constraints whose gradients are G's rows held.

    The inverse Fisher information restricted to the tangent space of the held constraints
    (the Cramér–Rao bound under equality constraints, Gorman & Hero 1990, eq. 7).
    """
    N = null_space(G)
    if N.shape[1] == 0:
        return np.zeros_like(F)
    reduced = N.T @ F @ N
    return np.asarray(N @ np.linalg.pinv(0.5 * (reduced + reduced.T), hermitian=True) @ N.T)


__all__ = [
    "ACTIVE_TOLERANCE", "ALIASES", "PHYSICAL_NAMES", "PHYSICAL_UNITS", "ConstraintReport", "ParameterConstraints",
    "canonical_name", "constrained_covariance", "constraint_report", "null_space", "parameter_gradient",
    "parameter_value", "parse_cli", "physical_of_theta",
]
