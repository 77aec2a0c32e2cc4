"""The extended calibration: the lumped model plus temperature, drift and nonlinearity terms.

Parameters, units and equation
------------------------------
=================  ==============  ================================================================
``T``              g per raw unit  3×3 lower-triangular, positive diagonal (canonical, as ``lumped``)
``o``              raw units       3, bias at the reference temperature and time
``terms``          see below       every selected term: effect, axis, coefficients of orders 1..p
``temp_ref``       °C              reference temperature ``T_ref`` (when a term needs temperature)
``t_ref``          s               reference time ``t_ref`` (when a term needs time)
``validity``       °C, s, g        temperature span, time span and ``|ā|`` range of the fit
``bias_repeatability``  g          optional (format 2.1): turn-on bias repeatability per axis when the
                                   calibration was fitted to several sessions (``o`` is then their mean)
``bias_random_walk``    g/√s, g    optional (format 2.2): the bias wanders in time as a random walk of
                                   intensity ``K`` (the diagnosis named it); ``o`` is the fit's bias and
                                   ``K √Δt`` the uncertainty it gains over ``Δt`` seconds
=================  ==============  ================================================================

Term coefficients of order ``p``: ``temperature_bias`` g/°C^p, ``temperature_scale`` 1/°C^p,
``bias_drift`` g/s^p, ``scale_nonlinearity`` g/g² (order 1 only).  The forward model (written once
in :mod:`optcal.core.extended_model`, :class:`~optcal.core.extended_model.ExtendedModel`), with ``C = T⁻¹``,
``S_i = ‖row i of C‖``, ``y = C ā`` and ``f_i = y_i / S_i``::

    a_i = (1 + Σ_p s_ip ΔT^p) · S_i (f_i + k2_i f_i²) + o_i + S_i (Σ_p k_ip ΔT^p + Σ_p d_ip Δt^p)
    ΔT = temp − T_ref,   Δt = t − t_ref

and :meth:`ExtendedCalibration.correct` inverts it per axis in closed form
(:func:`optcal.core.extended_model.invert_axis`), then ``ā = T y`` (Lu 2017, eq. 6).

Validity range
--------------
The polynomials are fitted on a temperature span, a time span and (static poses) ``|ā|`` near
1 g; outside them they are extrapolations.  :meth:`ExtendedCalibration.correct` warns with a
:class:`~optcal.families.caltypes.base.ValidityRangeWarning` saying how far outside and for how many
samples.  Samples of a raw recording scatter around their pose means, so each range is given a
margin (stored in the file): 1 °C, 5 % of the time span, 0.05 g.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.jsonio import FORMAT_VERSION, jsonable
from optcal.families.caltypes.base import Calibration, FitPoses, ValidityRangeWarning, as_column, as_samples, read_matrix
from optcal.families.caltypes.lumped import LumpedCalibration
from optcal.core.extended_model import MAX_ORDER, NEEDS, PARAMETRIC, UNITS, ExtendedModel, axis_number
from optcal.errors import InputError
from optcal.core.model import AXES, LumpedModel

#: Default margins of the validity range (see the module docstring).
TEMP_MARGIN_C: float = 1.0
TIME_MARGIN_FRACTION: float = 0.05
NORM_MARGIN_G: float = 0.05

_WHAT: dict[str, tuple[str, str]] = {"temp": ("temperature", "°C"), "t": ("time", "s"), "norm_g": ("|a|", "g")}


def term_units(effect: str, order: int) -> str:
    """Units of the order-``order`` coefficient of ``effect`` (e.g. ``g/°C^2``)."""
    unit = UNITS[effect]
    return unit if order == 1 or effect == "scale_nonlinearity" else f"{unit}^{order}"


@dataclass(frozen=True, eq=False)
class ExtendedTerm:
    """One selected term of the extended model.

    Attributes
    ----------
    effect : str
        ``temperature_bias``, ``temperature_scale``, ``bias_drift`` or ``scale_nonlinearity``.
    axis : str
        Sensor output axis ``x``, ``y`` or ``z``.
    coefficients : tuple of float
        Coefficients of orders 1..``order`` (units: :func:`term_units`).
    """

    effect: str
    axis: str
    coefficients: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.effect not in PARAMETRIC:
            raise InputError(f"unknown term effect {self.effect!r}; use one of {', '.join(PARAMETRIC)}")
        object.__setattr__(self, "axis", AXES[axis_number(self.axis)])
        c = tuple(float(v) for v in np.atleast_1d(np.asarray(self.coefficients, dtype=float)))
        if not 1 <= len(c) <= MAX_ORDER[self.effect]:
            raise InputError(f"{self.effect}: give 1 to {MAX_ORDER[self.effect]} coefficients (orders 1..), got {len(c)}")
        if not all(np.isfinite(c)):
            raise InputError(f"{self.effect} on {self.axis}: coefficients must be finite")
        object.__setattr__(self, "coefficients", c)

    @property
    def order(self) -> int:
        return len(self.coefficients)

    def to_dict(self) -> dict[str, Any]:
        return {
            "effect": self.effect,
            "axis": self.axis,
            "order": self.order,
            "coefficients": list(self.coefficients),
            "units": [term_units(self.effect, p) for p in range(1, self.order + 1)],
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "ExtendedTerm":
        return cls(str(d["effect"]), str(d["axis"]), tuple(d["coefficients"]))


@dataclass(frozen=True)
class BiasRepeatability:
    """Turn-on bias repeatability: how much the bias differed between the sessions of the fit.

    A future session's bias is unknown, so a calibration fitted to several sessions applies the
    mean of their biases (its ``o``) and carries this spread as the uncertainty of that bias.

    Attributes
    ----------
    per_axis_g : tuple of float
        Sample standard deviation of the sessions' biases per axis x, y, z (g; 0 on an axis
        where the sessions agreed).
    sessions : int
        Number of sessions.
    """

    per_axis_g: tuple[float, float, float]
    sessions: int

    def __post_init__(self) -> None:
        values = tuple(float(v) for v in np.asarray(self.per_axis_g, dtype=float).ravel())
        if len(values) != 3 or not all(np.isfinite(v) and v >= 0 for v in values):
            raise InputError("bias_repeatability per_axis_g must be three finite non-negative numbers (g)")
        if int(self.sessions) < 2:
            raise InputError(f"bias_repeatability needs at least 2 sessions, got {self.sessions}")
        object.__setattr__(self, "per_axis_g", values)
        object.__setattr__(self, "sessions", int(self.sessions))

    def to_dict(self) -> dict[str, Any]:
        return {"per_axis_g": list(self.per_axis_g), "sessions": self.sessions,
                "meaning": "the bias o is the mean of the sessions' biases; a new session's bias differs from it "
                           "by about this much (sample standard deviation over the sessions)"}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "BiasRepeatability":
        if not isinstance(d, dict) or "per_axis_g" not in d or "sessions" not in d:
            raise InputError("bias_repeatability must be an object with per_axis_g (3 numbers, g) and sessions")
        return cls(tuple(d["per_axis_g"]), int(d["sessions"]))


@dataclass(frozen=True)
class BiasRandomWalk:
    """The bias wanders in time as a random walk (bias instability), named by the diagnosis.

    A wander cannot be predicted for a later recording, so the calibration applies its fitted
    bias ``o`` and carries the walk as that bias's uncertainty: after ``Δt`` seconds the bias is
    off by about ``K √Δt`` (one standard deviation per axis).

    Attributes
    ----------
    K_g_per_sqrt_s : float
        Intensity ``K``, g/√s (the rate random walk of ``optcal allan``, in g).
    K_interval_g_per_sqrt_s : tuple of float
        Its 95 % profile-likelihood interval.
    wander_rms_g : float
        RMS of the smoothed bias about its mean over the fitted recording(s), g.
    """

    K_g_per_sqrt_s: float
    K_interval_g_per_sqrt_s: tuple[float, float]
    wander_rms_g: float

    def __post_init__(self) -> None:
        values = [float(self.K_g_per_sqrt_s), *(float(v) for v in self.K_interval_g_per_sqrt_s), float(self.wander_rms_g)]
        if len(values) != 4 or not all(np.isfinite(v) and v >= 0 for v in values):
            raise InputError("bias_random_walk needs finite non-negative K_g_per_sqrt_s, a 2-number "
                             "K_interval_g_per_sqrt_s and wander_rms_g (g/√s, g)")
        object.__setattr__(self, "K_g_per_sqrt_s", values[0])
        object.__setattr__(self, "K_interval_g_per_sqrt_s", (values[1], values[2]))
        object.__setattr__(self, "wander_rms_g", values[3])

    def to_dict(self) -> dict[str, Any]:
        return {"K_g_per_sqrt_s": self.K_g_per_sqrt_s, "K_interval_g_per_sqrt_s": list(self.K_interval_g_per_sqrt_s),
                "wander_rms_g": self.wander_rms_g,
                "meaning": "the bias wanders as a random walk: o is the fitted bias, and after dt seconds the bias "
                           "is off by about K_g_per_sqrt_s * sqrt(dt) per axis (one standard deviation)"}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "BiasRandomWalk":
        keys = ("K_g_per_sqrt_s", "K_interval_g_per_sqrt_s", "wander_rms_g")
        if not isinstance(d, dict) or any(k not in d for k in keys):
            raise InputError("bias_random_walk must be an object with K_g_per_sqrt_s, K_interval_g_per_sqrt_s "
                             "(2 numbers) and wander_rms_g")
        return cls(float(d["K_g_per_sqrt_s"]), tuple(d["K_interval_g_per_sqrt_s"]), float(d["wander_rms_g"]))


@dataclass(frozen=True)
class RangeExcess:
    """How far some samples lie outside one range of the fit."""

    quantity: str
    low: float
    high: float
    n_outside: int
    n_samples: int
    worst: float
    excess: float

    def describe(self) -> str:
        name, unit = _WHAT[self.quantity]
        side = "above" if self.worst > self.high else "below"
        return (
            f"{name} {self.worst:.4g} {unit} is {self.excess:.3g} {unit} {side} the fitted range "
            f"{self.low:.4g}..{self.high:.4g} {unit} ({self.n_outside} of {self.n_samples} samples outside)"
        )


@dataclass(frozen=True, eq=False)
class ValidityRange:
    """The ranges an extended calibration was fitted on, and the margin allowed around each.

    Attributes
    ----------
    temp : (float, float) or None
        Temperature span, °C.
    t : (float, float) or None
        Time span, s.
    norm_g : (float, float) or None
        Range of the calibrated ``|ā|``, g.
    temp_margin, t_margin, norm_margin : float
        Allowed excess beyond each range (°C, s, g).
    """

    temp: tuple[float, float] | None = None
    t: tuple[float, float] | None = None
    norm_g: tuple[float, float] | None = None
    temp_margin: float = TEMP_MARGIN_C
    t_margin: float = 0.0
    norm_margin: float = NORM_MARGIN_G

    @classmethod
    def of(cls, norm_g: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> "ValidityRange":
        """The ranges of the fit data: calibrated norms (g), temperatures (°C) and times (s)."""

        def span(x: ArrayLike | None) -> tuple[float, float] | None:
            if x is None:
                return None
            v = np.asarray(x, dtype=float)
            v = v[np.isfinite(v)]
            return (float(v.min()), float(v.max())) if v.size else None

        t_span = span(t)
        t_margin = TIME_MARGIN_FRACTION * (t_span[1] - t_span[0]) if t_span else 0.0
        return cls(span(temp), t_span, span(norm_g), t_margin=t_margin)

    def excesses(
        self, norm_g: NDArray[np.float64], temp: NDArray[np.float64] | None, t: NDArray[np.float64] | None
    ) -> tuple[NDArray[np.bool_], list[RangeExcess]]:
        """Samples outside any range (beyond its margin), and a description of each excess."""
        outside = np.zeros(norm_g.shape[0], dtype=bool)
        found: list[RangeExcess] = []
        for quantity, values, span, margin in (
            ("temp", temp, self.temp, self.temp_margin),
            ("t", t, self.t, self.t_margin),
            ("norm_g", norm_g, self.norm_g, self.norm_margin),
        ):
            if values is None or span is None:
                continue
            lo, hi = span
            below = np.nan_to_num(lo - margin - values, nan=0.0)
            above = np.nan_to_num(values - hi - margin, nan=0.0)
            out = (below > 0) | (above > 0)
            if np.any(out):
                k_lo, k_hi = int(np.argmax(below)), int(np.argmax(above))
                if above[k_hi] >= below[k_lo]:
                    worst, excess = float(values[k_hi]), float(values[k_hi] - hi)
                else:
                    worst, excess = float(values[k_lo]), float(lo - values[k_lo])
                found.append(RangeExcess(quantity, lo, hi, int(out.sum()), int(out.size), worst, excess))
                outside |= out
        return outside, found

    def to_dict(self) -> dict[str, Any]:
        return jsonable(
            {
                "temp": self.temp,
                "t": self.t,
                "norm_g": self.norm_g,
                "margins": {"temp": self.temp_margin, "t": self.t_margin, "norm_g": self.norm_margin},
                "units": {"temp": "°C", "t": "s", "norm_g": "g"},
            }
        )

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "ValidityRange":
        def span(key: str) -> tuple[float, float] | None:
            v = d.get(key)
            return None if v is None else (float(v[0]), float(v[1]))

        m = d.get("margins") or {}
        return cls(
            span("temp"), span("t"), span("norm_g"),
            float(m.get("temp", TEMP_MARGIN_C)), float(m.get("t", 0.0)), float(m.get("norm_g", NORM_MARGIN_G)),
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ValidityRange) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


@dataclass(eq=False)
class ExtendedCalibration(Calibration):
    """The lumped calibration with temperature, drift and nonlinearity terms (module docstring).

    Attributes
    ----------
    T : ndarray, shape (3, 3)
        Lower-triangular, positive diagonal, g per raw unit.
    o : ndarray, shape (3,)
        Bias at ``temp_ref`` and ``t_ref``, raw units.
    terms : tuple of ExtendedTerm
        Every selected term (at most one per effect and axis).
    temp_ref : float or None
        Reference temperature, °C (required when a term needs temperature).
    t_ref : float or None
        Reference time, s (required when a term needs time).
    validity : ValidityRange
        The ranges of the fit.
    units : str
        Raw units.
    fitted_on : FitPoses, optional
    bias_repeatability : BiasRepeatability, optional
        Fitted to several sessions: ``o`` is the mean of their biases and this is their spread.
        Files that carry it are format 2.1 (readers of 2.0 ignore it; 2.0 files load without it).
    bias_random_walk : BiasRandomWalk, optional
        The bias wanders in time: ``K`` recorded as the bias's uncertainty growing with time.
        Files that carry it are format 2.2 (older files load without it).
    """

    cal_type: ClassVar[str] = "extended"

    T: NDArray[np.float64]
    o: NDArray[np.float64]
    terms: tuple[ExtendedTerm, ...] = ()
    temp_ref: float | None = None
    t_ref: float | None = None
    validity: ValidityRange = field(default_factory=ValidityRange)
    units: str = "g"
    fitted_on: FitPoses | None = None
    bias_repeatability: BiasRepeatability | None = None
    bias_random_walk: BiasRandomWalk | None = None

    @property
    def format_version(self) -> str:
        """``2.2`` with :attr:`bias_random_walk`, ``2.1`` with :attr:`bias_repeatability`, else ``2.0``."""
        if self.bias_random_walk is not None:
            return "2.2"
        return "2.1" if self.bias_repeatability is not None else FORMAT_VERSION

    def __post_init__(self) -> None:
        base = LumpedCalibration(self.T, self.o, self.units)  # validates T (canonical) and o
        self.T, self.o = base.T, base.o
        self.terms = tuple(self.terms)
        seen = [(term.effect, term.axis) for term in self.terms]
        if len(set(seen)) != len(seen):
            raise InputError("at most one term per effect and axis; give the orders 1..p as one term's coefficients")
        for column, value in (("temp", self.temp_ref), ("t", self.t_ref)):
            if column in self.needs and (value is None or not np.isfinite(value)):
                name = "temp_ref (°C)" if column == "temp" else "t_ref (s)"
                raise InputError(f"the calibration has {_WHAT[column][0]} terms: give the reference {name}")

    # ------------------------------------------------------------- construction
    @classmethod
    def from_model(
        cls,
        model: ExtendedModel,
        units: str = "g",
        validity: ValidityRange | None = None,
        fitted_on: FitPoses | None = None,
    ) -> "ExtendedCalibration":
        """The calibration of an :class:`~optcal.core.extended_model.ExtendedModel` (its non-zero terms).

        ``model.base`` must have a canonical (lower-triangular) ``T``, as the extended fit
        returns; without ``validity``, the range is taken from ``fitted_on`` (else left open).

        Parameters
        ----------
        model : ExtendedModel
            The fitted extended model.
        units : str
            Input units (``g``, ``m/s^2`` or ``counts``).
        validity : ValidityRange, optional
            The temperature, time and ``|a|`` ranges the model holds in.
        fitted_on : FitPoses, optional
            The poses it was fitted on.

        Returns
        -------
        ExtendedCalibration
        """
        T = np.linalg.inv(model.base.C)
        if np.all(np.abs(np.triu(T, 1)) <= 1e-14 * np.abs(T).max()):
            T = np.tril(T)  # round-off of the inverse of a lower-triangular C
        base = LumpedCalibration.from_any_T(T, model.base.o, units)  # the row norms of C, hence S_i, are kept
        terms = []
        for effect in PARAMETRIC:
            c = model.coefficients[effect]
            for i in range(3):
                nonzero = np.flatnonzero(c[i])
                if nonzero.size:
                    terms.append(ExtendedTerm(effect, AXES[i], tuple(c[i, : nonzero[-1] + 1])))
        needs = {NEEDS[term.effect] for term in terms}
        cal = cls(
            base.T, base.o, tuple(terms),
            temp_ref=float(model.temp_ref) if "temp" in needs else None,
            t_ref=float(model.t_ref) if "t" in needs else None,
            units=units, fitted_on=fitted_on,
        )
        if validity is None and fitted_on is not None:
            validity = ValidityRange.of(cal.norm_errors(fitted_on.acc, fitted_on.temp, fitted_on.t) + 1.0, fitted_on.temp, fitted_on.t)
        if validity is not None:
            cal.validity = validity
        return cal

    @property
    def model(self) -> ExtendedModel:
        """The forward model (:class:`~optcal.core.extended_model.ExtendedModel`) of this calibration."""
        coefficients = {effect: np.zeros((3, MAX_ORDER[effect])) for effect in PARAMETRIC}
        for term in self.terms:
            coefficients[term.effect][axis_number(term.axis), : term.order] = term.coefficients
        return ExtendedModel(
            LumpedModel.from_T(self.T, self.o), coefficients,
            temp_ref=25.0 if self.temp_ref is None else self.temp_ref,
            t_ref=0.0 if self.t_ref is None else self.t_ref,
        )

    @property
    def needs(self) -> tuple[str, ...]:
        wanted = {NEEDS[term.effect] for term in self.terms}
        return tuple(c for c in ("temp", "t") if c in wanted)

    # --------------------------------------------------------------- application
    def correct(
        self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None, *, warn: bool = True
    ) -> NDArray[np.float64]:
        """Invert the extended model per sample (closed form), then ``ā = T y``, in g.

        Raises :class:`~optcal.errors.InputError` when a needed ``temp`` or ``t`` is missing;
        warns (:class:`~optcal.families.caltypes.base.ValidityRangeWarning`) when samples lie outside
        the validity range (``warn=False`` leaves the check to :meth:`out_of_range`).

        Parameters
        ----------
        acc : array_like, shape (n, 3)
            Raw samples in :attr:`units`.
        temp : array_like, shape (n,), optional
            Temperature of each sample, °C (needed by temperature terms).
        t : array_like, shape (n,), optional
            Time of each sample, s, on the time base of the fit (needed by drift terms).
        warn : bool
            Warn about samples outside the validity range.

        Returns
        -------
        ndarray, shape (n, 3)
            Specific force, g.
        """
        a = as_samples(acc)
        n = a.shape[0]
        temp_v, t_v = as_column(temp, n, "temp"), as_column(t, n, "t")
        for column, value in (("temp", temp_v), ("t", t_v)):
            if column in self.needs and value is None:
                effects = sorted({f"{term.effect} on {term.axis}" for term in self.terms if NEEDS[term.effect] == column})
                what = "temperature (°C)" if column == "temp" else "time (s, on the time base of the fit)"
                raise InputError(f"this extended calibration has {', '.join(effects)}: pass {column}= with the {what} of each sample")
        corrected = self.model.correct(a, temp_v, t_v)
        if warn:
            _, excesses = self.validity.excesses(np.linalg.norm(corrected, axis=1), temp_v, t_v)
            if excesses:
                warnings.warn(
                    "extended calibration applied outside its validity range: "
                    + "; ".join(e.describe() for e in excesses),
                    ValidityRangeWarning,
                    stacklevel=2,
                )
        return corrected

    def norm_errors(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        return np.linalg.norm(self.correct(acc, temp, t, warn=False), axis=1) - 1.0

    def out_of_range(
        self, corrected: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None
    ) -> NDArray[np.bool_]:
        c = as_samples(corrected, "corrected")
        n = c.shape[0]
        return self.validity.excesses(np.linalg.norm(c, axis=1), as_column(temp, n, "temp"), as_column(t, n, "t"))[0]

    # ----------------------------------------------------------------------- I/O
    def parameters(self) -> dict[str, Any]:
        return {
            "T": self.T,
            "o": self.o,
            "temp_ref": self.temp_ref,
            "t_ref": self.t_ref,
            "terms": [term.to_dict() for term in self.terms],
            "validity": self.validity.to_dict(),
            **({} if self.bias_repeatability is None else {"bias_repeatability": self.bias_repeatability.to_dict()}),
            **({} if self.bias_random_walk is None else {"bias_random_walk": self.bias_random_walk.to_dict()}),
        }

    @classmethod
    def from_parameters(cls, d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> "ExtendedCalibration":
        return cls(
            read_matrix(d, "T", (3, 3)),
            read_matrix(d, "o", (3,)),
            tuple(ExtendedTerm.from_dict(term) for term in d.get("terms", [])),
            None if d.get("temp_ref") is None else float(d["temp_ref"]),
            None if d.get("t_ref") is None else float(d["t_ref"]),
            ValidityRange.from_dict(d.get("validity") or {}),
            units,
            fitted_on,
            None if d.get("bias_repeatability") is None else BiasRepeatability.from_dict(d["bias_repeatability"]),
            None if d.get("bias_random_walk") is None else BiasRandomWalk.from_dict(d["bias_random_walk"]),
        )

    def unit_fields(self) -> dict[str, str]:
        return {"T": f"g per {self.units}", "o": self.units, "temp_ref": "°C", "t_ref": "s"}

    def describe(self) -> str:
        """One line; with :attr:`bias_repeatability`, how the bias was chosen and its uncertainty.

        Returns
        -------
        str
        """
        text = super().describe()
        r = self.bias_repeatability
        if r is not None:
            spread = "/".join(f"{v * 1e3:.2g}" for v in r.per_axis_g)
            text += (f"; bias o = mean of {r.sessions} sessions' biases, turn-on repeatability x/y/z "
                     f"{spread} mg recorded as its uncertainty")
        w = self.bias_random_walk
        if w is not None:
            text += (f"; the bias wanders as a random walk, K = {w.K_g_per_sqrt_s * 1e3:.3g} mg/√s recorded as its "
                     "uncertainty growing with time (K·√Δt)")
        return text

    def lumped(self) -> LumpedCalibration:
        """``T`` and ``o`` alone (the terms dropped): the model at ``T_ref``, ``t_ref`` and small forces.

        Returns
        -------
        LumpedCalibration
        """
        return LumpedCalibration(self.T, self.o, self.units, self.fitted_on)
