"""Extensions of the error model: the effect vocabulary, its regressors, forward model and CasADi fit.

The paper's model (Lu 2017, eq. 5) is ``a = C ā + o + n`` with constant ``C`` and ``o``.
:mod:`optcal.diagnosis` asks whether measured data need more than that; this module says
what "more" can be, how each extension enters the measurement, and fits any combination of
them jointly with ``T`` and ``o``.

Extended forward model
----------------------
"Axis i" is always **sensor output axis i** (x, y, z: the raw columns ``ax, ay, az``).  With
``y = C ā`` the linear lumped output (raw units), ``S_i = ‖row i of C‖`` the sensitivity of
axis i (raw units per g) and ``f_i = y_i / S_i`` the true specific force along sensing axis i
(g; the rows of ``C/S`` are the unit sensing directions, Lu 2017 eq. 1), output i is::

    a_i = (1 + Σ_p s_ip ΔT^p) · S_i (f_i + k2_i f_i²)
          + o_i + S_i (Σ_p k_ip ΔT^p + Σ_p d_ip Δt^p) + n_i

    ΔT = temp − T_ref,   Δt = t − t_ref   (T_ref, t_ref: mid-points of the recorded ranges)

The effects (the vocabulary) and the units of their first-order coefficients:

=====================  ===========================================================  ========
``temperature_bias``   bias of axis i is ``o_i + k_i ΔT`` (+ higher powers)           g/°C
``temperature_scale``  output of axis i is scaled by ``1 + s_i ΔT`` (+ higher powers)  1/°C
``bias_drift``         bias of axis i is ``o_i + d_i Δt`` (+ higher powers)            g/s
``scale_nonlinearity`` axis i gains ``k2_i f_i²``, quadratic in the true force        g/g²
``outliers``           poses that are not static or are corrupt (no parameters:       rows
                       found by a robust fit and given zero weight)
=====================  ===========================================================  ========

Bias terms are per g (``S_i`` converts them to raw units), so estimates do not depend on the
raw units; order ``p`` coefficients are in g/°C^p, 1/°C^p and g/s^p.  With all coefficients
zero the model is exactly the paper's.  The nonlinearity acts on the force *along the
sensing axis*, which makes it invariant to the unidentifiable rotation of ``C`` (``C → C Q``,
``ā → Qᵀ ā`` leaves ``y`` and hence ``f`` unchanged).

Fit: norm residuals with the model inverted inside
--------------------------------------------------
Every term is inverted in closed form per axis (``z = a − o − S·bias``, ``w = z/(1 + scale)``,
``y = 2w / (1 + √(1 + 4 k2 w / S))`` solves ``S(f + k2 f²) = w``), and the residual is Lu
2017's norm residual of the recovered linear output, ``r = ‖T y(a)‖ − 1`` (eq. 13), weighted
by ``1/(σ_k ‖Tᵀ ā_k‖)²``.  Why this and not the errors-in-variables problem with a latent
direction per pose (:mod:`optcal.estimators.exact`)?  Eliminating the latent unit direction
from eq. 8 leaves, to first order in the noise, exactly this weighted norm residual (the
distance of the measurement to the ellipsoid along its normal, :mod:`optcal.identifiability`);
the difference is of relative order σ² (≈1e-6 for mg noise), far below any effect worth
reporting.  The norm-residual problem has ``9 + P`` unknowns instead of ``9 + P + 3n``, so the
hundreds of re-solves of a bootstrap and a k-fold selection stay fast, and the held-out
residual of a pose (the model inverted at its own measurement) is the same formula.

:class:`ExtendedProblem` builds the CasADi/IPOPT problem once per (n, loss) with *every*
possible coefficient as a variable and the data, weights, normalised temperature and time as
parameters; an effect set is chosen by fixing the unused coefficients to zero through the
bounds (IPOPT then removes them), so the bootstrap, the k-fold and the forward selection
build nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.model import AXES, LumpedModel
from optcal.poses import PoseTable

#: The vocabulary of model extensions, in the order they are reported.
EFFECTS: tuple[str, ...] = ("temperature_bias", "temperature_scale", "bias_drift", "scale_nonlinearity", "outliers")
#: Effects with coefficients in the forward model (``outliers`` has none).
PARAMETRIC: tuple[str, ...] = EFFECTS[:4]
#: Highest polynomial order of each parametric effect.
MAX_ORDER: dict[str, int] = {"temperature_bias": 3, "temperature_scale": 2, "bias_drift": 3, "scale_nonlinearity": 1}
#: Column each effect needs (``None``: none).
NEEDS: dict[str, str | None] = {
    "temperature_bias": "temp",
    "temperature_scale": "temp",
    "bias_drift": "t",
    "scale_nonlinearity": None,
    "outliers": None,
}
#: Units of the first-order coefficient (JSON ``estimate``).
UNITS: dict[str, str] = {
    "temperature_bias": "g/°C",
    "temperature_scale": "1/°C",
    "bias_drift": "g/s",
    "scale_nonlinearity": "g/g²",
    "outliers": "rows",
}
#: The regressor each effect adds to output axis i (for reports).
REGRESSOR_TEXT: dict[str, str] = {
    "temperature_bias": "ΔT",
    "temperature_scale": "ΔT·f_{axis}",
    "bias_drift": "Δt",
    "scale_nonlinearity": "f_{axis}²",
}
#: The physical cause each effect names, in plain words.
CAUSES: dict[str, str] = {
    "temperature_bias": "the zero offset moves with temperature (thermal stress in the package and MEMS structure)",
    "temperature_scale": "the sensitivity changes with temperature (thermal change of the spring stiffness and readout gain)",
    "bias_drift": "the zero offset wanders with time (bias instability, self-heating or mechanical settling after power-on)",
    "scale_nonlinearity": "the output is not proportional to the force (a second-order response of the sensing element)",
    "outliers": "some poses were not static or are corrupt (the sensor moved, was bumped, or the interval was mis-detected)",
}
#: A temperature range below this (°C) is treated as constant: no temperature effect can be estimated.
MIN_TEMP_SPAN_C: float = 0.5


def _beta_layout() -> dict[tuple[str, int, int], int]:
    index: dict[tuple[str, int, int], int] = {}
    for effect in PARAMETRIC:
        for axis in range(3):
            for order in range(1, MAX_ORDER[effect] + 1):
                index[(effect, axis, order)] = len(index)
    return index


#: (effect, axis number, order) → index of its coefficient in β (after the nine entries of θ).
BETA_INDEX: dict[tuple[str, int, int], int] = _beta_layout()
N_BETA: int = len(BETA_INDEX)
N_X: int = 9 + N_BETA


def axis_number(axis: str | int) -> int:
    """0, 1, 2 for ``"x"``, ``"y"``, ``"z"`` (or the number itself)."""
    if isinstance(axis, (int, np.integer)) and 0 <= int(axis) < 3:
        return int(axis)
    if axis in AXES:
        return AXES.index(str(axis))
    raise InputError(f"unknown axis {axis!r}; use x, y or z")


def parse_effects(text: str | Iterable[str] | None) -> tuple[str, ...] | None:
    """Parse ``"temperature_bias,outliers"`` (or a list) into effect names.

    ``None``, ``""`` or ``"all"`` mean every effect (``None`` is returned); ``"none"`` means no
    candidate at all (an empty tuple: baseline and simulation check only).
    """
    if text is None:
        return None
    names = [s.strip() for s in (text.split(",") if isinstance(text, str) else text) if s.strip()]
    if names == ["none"]:
        return ()
    if not names or names == ["all"]:
        return None
    unknown = [s for s in names if s not in EFFECTS]
    if unknown:
        raise InputError(f"unknown effect(s) {', '.join(unknown)}; choose from {', '.join(EFFECTS)}")
    return tuple(e for e in EFFECTS if e in names)


# ----------------------------------------------------------------------------- regressors
@dataclass(frozen=True)
class Regressors:
    """Temperature and time of each pose, centred and scaled to [−1, 1].

    Attributes
    ----------
    tau, s : ndarray, shape (n,)
        ``(temp − T_ref)/temp_half`` and ``(t − t_ref)/t_half`` (zeros when absent).
    temp_ref, temp_half : float
        Mid-point and half-span of the temperature, °C (``nan``/0 when absent or constant).
    t_ref, t_half : float
        Mid-point and half-span of the pose times, s.
    has_temp, has_time : bool
        Whether a temperature (non-constant) and a time column are usable.
    notes : list of str
        Why a column is unusable (for the report).
    """

    tau: NDArray[np.float64]
    s: NDArray[np.float64]
    temp_ref: float
    temp_half: float
    t_ref: float
    t_half: float
    has_temp: bool
    has_time: bool
    notes: tuple[str, ...] = ()

    @classmethod
    def of(cls, poses: PoseTable) -> "Regressors":
        n = poses.n
        notes: list[str] = []
        tau, s = np.zeros(n), np.zeros(n)
        temp_ref, temp_half, t_ref, t_half = float("nan"), 0.0, float("nan"), 0.0
        has_temp = has_time = False
        if poses.temp is None:
            notes.append("no temperature column: temperature effects cannot be tested")
        else:
            lo, hi = float(np.min(poses.temp)), float(np.max(poses.temp))
            temp_ref = 0.5 * (lo + hi)
            if hi - lo < MIN_TEMP_SPAN_C:
                notes.append(
                    f"the temperature is constant (range {hi - lo:.2g} °C < {MIN_TEMP_SPAN_C:g} °C): "
                    "temperature effects cannot be estimated"
                )
            else:
                has_temp, temp_half = True, 0.5 * (hi - lo)
                tau = (poses.temp - temp_ref) / temp_half
        if poses.t is None:
            notes.append("no time column: bias_drift cannot be tested")
        else:
            lo, hi = float(np.min(poses.t)), float(np.max(poses.t))
            t_ref = 0.5 * (lo + hi)
            if hi <= lo:
                notes.append("all poses have the same time: bias_drift cannot be tested")
            else:
                has_time, t_half = True, 0.5 * (hi - lo)
                s = (poses.t - t_ref) / t_half
        return cls(tau, s, temp_ref, temp_half, t_ref, t_half, has_temp, has_time, tuple(notes))

    def supports(self, effect: str) -> bool:
        """Whether the columns ``effect`` needs are usable."""
        need = NEEDS[effect]
        return need is None or (need == "temp" and self.has_temp) or (need == "t" and self.has_time)

    def reason_unsupported(self, effect: str) -> str:
        need = NEEDS[effect]
        word = "temperature" if need == "temp" else "time"
        hits = [note for note in self.notes if word in note]
        return hits[0] if hits else f"{effect} needs a {word} column"

    def half_span(self, effect: str) -> float:
        """The scale turning a normalised coefficient into physical units (1 for the nonlinearity)."""
        need = NEEDS[effect]
        return self.temp_half if need == "temp" else self.t_half if need == "t" else 1.0

    def correlation(self) -> float | None:
        """Pearson correlation of temperature and time (``None`` unless both are usable)."""
        if not (self.has_temp and self.has_time):
            return None
        return float(np.corrcoef(self.tau, self.s)[0, 1])


# ----------------------------------------------------------------------------- forward model
def _inverse_lower(L: Any) -> list[list[Any]]:
    """Entries of the inverse of the lower-triangular 3×3 matrix ``L`` (works for CasADi and numpy)."""
    c00 = 1 / L[0][0]
    c11 = 1 / L[1][1]
    c22 = 1 / L[2][2]
    c10 = -L[1][0] * c00 * c11
    c21 = -L[2][1] * c11 * c22
    c20 = (L[1][0] * L[2][1] - L[1][1] * L[2][0]) * c00 * c11 * c22
    return [[c00, 0, 0], [c10, c11, 0], [c20, c21, c22]]


def invert_axis(z: Any, S: Any, bias: Any, scale: Any, k2: Any, sqrt: Callable, fmax: Callable) -> Any:
    """Linear output ``y_i`` of one axis from ``z_i = a_i − o_i`` (module docstring, inverted).

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


def simulate_extended(
    model: ExtendedModel,
    directions: ArrayLike,
    sigma: float | ArrayLike,
    *,
    temp: ArrayLike | None = None,
    t: ArrayLike | None = None,
    rng: np.random.Generator | int | None = None,
    units: str = "g",
    record_sigma: bool = True,
) -> PoseTable:
    """A pose table from the extended model with white noise per pose (raw units, per axis)."""
    rng = np.random.default_rng(rng)
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    n = len(d)
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (n,)).copy()
    acc = model.measure(d, temp, t) + rng.standard_normal((n, 3)) * sig[:, None]
    return PoseTable(
        acc=acc,
        sigma=sig if record_sigma and np.all(sig > 0) else None,
        t=None if t is None else np.asarray(t, float),
        temp=None if temp is None else np.asarray(temp, float),
        units=units,
        source="simulation",
        extra={"true_dx": d[:, 0], "true_dy": d[:, 1], "true_dz": d[:, 2]},
    )


def distort_recording(frame: Any, model: ExtendedModel) -> Any:
    """Apply the extensions of ``model`` to a raw recording made with ``model.base``.

    ``frame`` is a pandas DataFrame with ``ax, ay, az`` (and ``t``, ``temp`` as the model
    needs), e.g. :attr:`optcal.data.synthetic.SyntheticRecording.frame` made with the same
    base model; each sample's linear output ``a − o`` (noise included) passes through the
    extended model.  Returns a new frame.
    """
    out = frame.copy()
    acc = out[["ax", "ay", "az"]].to_numpy(dtype=float)
    temp = out["temp"].to_numpy(dtype=float) if "temp" in out else None
    t = out["t"].to_numpy(dtype=float) if "t" in out else None
    new = model.distort(acc - model.base.o, temp, t)
    out["ax"], out["ay"], out["az"] = new[:, 0], new[:, 1], new[:, 2]
    return out


# ----------------------------------------------------------------------------- CasADi problem
def extended_residual_function() -> Any:
    """``r(x, a, τ, s) = ‖T y(a)‖ − 1`` for one pose as a CasADi Function (normalised units).

    ``x = [θ (9), β (N_BETA)]``; the coefficients β multiply powers of the normalised
    temperature ``τ`` and time ``s`` (:class:`Regressors`), so each is a number in g (bias
    terms), a relative scale (temperature scale) or g/g² (nonlinearity).
    """
    import casadi as ca

    from optcal.norm_residual import casadi_lower_triangular as lower_triangular

    x = ca.SX.sym("x", N_X)
    a = ca.SX.sym("a", 3)
    tau = ca.SX.sym("tau")
    s = ca.SX.sym("s")
    T = lower_triangular(x[:6])
    L = [[x[0], 0, 0], [x[1], x[2], 0], [x[3], x[4], x[5]]]
    C = _inverse_lower(L)
    S = [ca.sqrt(sum(C[i][j] ** 2 for j in range(i + 1))) for i in range(3)]
    beta = x[9:]
    y = []
    for i in range(3):
        b = lambda effect, p: beta[BETA_INDEX[(effect, i, p)]]  # noqa: E731
        bias = sum(b("temperature_bias", p) * tau**p for p in range(1, MAX_ORDER["temperature_bias"] + 1))
        bias += sum(b("bias_drift", p) * s**p for p in range(1, MAX_ORDER["bias_drift"] + 1))
        scale = sum(b("temperature_scale", p) * tau**p for p in range(1, MAX_ORDER["temperature_scale"] + 1))
        y.append(invert_axis(a[i] - x[6 + i], S[i], bias, scale, b("scale_nonlinearity", 1), ca.sqrt, ca.fmax))
    v = ca.mtimes(T, ca.vertcat(*y))
    return ca.Function("extended_norm_residual", [x, a, tau, s], [ca.norm_2(v) - 1.0])


@dataclass
class PoseData:
    """The data of an extended fit in normalised units (built once per data set).

    Attributes
    ----------
    u : ndarray, shape (n, 3)
        Normalised measurements ``(a − centre)/scale`` (:class:`optcal.estimators.base.Normaliser`).
    tau, s : ndarray, shape (n,)
        Normalised temperature and time.
    """

    u: NDArray[np.float64]
    tau: NDArray[np.float64]
    s: NDArray[np.float64]

    @property
    def n(self) -> int:
        return int(self.u.shape[0])

    def parameters(self, w: NDArray, delta: float = 1.0) -> NDArray[np.float64]:
        """The parameter vector of :class:`ExtendedProblem` for weights ``w`` (passed as √w)."""
        return np.concatenate([self.u.ravel(), np.sqrt(w), self.tau, self.s, [delta]])


#: IPOPT options of :class:`ExtendedProblem`.  The norm residual ``‖v‖ − 1`` loses about
#: 1e-16 absolutely to cancellation, so near the optimum the cost is only known to ~1e-13
#: relatively and the gradient cannot be driven below ~√(curvature × that); the solve is
#: therefore accepted once the objective stops changing (relative change < 1e-12 for two
#: iterations) with the scaled optimality error below 1e-2 (which bounds the parameter error
#: at ~1e-10 of the parameters' size, far inside any standard error).
SOLVER_OPTIONS: dict[str, Any] = {
    "ipopt.tol": 1e-9,
    "ipopt.acceptable_tol": 1e-2,
    "ipopt.acceptable_obj_change_tol": 1e-12,
    "ipopt.acceptable_iter": 2,
    "ipopt.max_iter": 200,
    "calc_lam_p": False,
}


class ExtendedProblem:
    """``min_x Σ_k ρ(√w_k r_k(x))`` over θ and every coefficient, data as parameters (built once).

    Unused coefficients are fixed at zero through the bounds (see :meth:`bounds`).  Also
    provides the residuals and their Jacobian as CasADi Functions (for held-out residuals and
    the Fisher information).
    """

    _cache: dict[tuple[int, str], "ExtendedProblem"] = {}

    def __init__(self, n: int, loss: str = "squared") -> None:
        import casadi as ca

        from optcal.estimators.mle import IPOPT_DEFAULTS, robust_loss

        self.n, self.loss = n, loss
        r = extended_residual_function()
        # the squared loss is re-solved hundreds of times (bootstrap, k-fold): one expanded SX graph
        # (slower to build, ~4x faster to solve); the robust losses are solved a few times: MX map
        sym = ca.SX if loss == "squared" else ca.MX
        x = sym.sym("x", N_X)
        A = sym.sym("a", 3, n)
        sqrt_w = sym.sym("sqrt_w", 1, n)
        tau = sym.sym("tau", 1, n)
        s = sym.sym("s", 1, n)
        delta = sym.sym("delta")
        res = (r.map(n) if n > 1 else r)(x, A, tau, s)  # 1 x n
        cost = ca.sum2(robust_loss(res * sqrt_w, loss, delta))
        p = ca.vertcat(ca.vec(A), sqrt_w.T, tau.T, s.T, delta)
        opts = dict(IPOPT_DEFAULTS)
        opts.update(SOLVER_OPTIONS)
        self.solver = ca.nlpsol(f"extended_{loss}", "ipopt", {"x": x, "p": p, "f": cost}, opts)
        self.residuals = ca.Function("residuals", [x, p], [res.T])
        self.jacobian = ca.Function("jacobian", [x, p], [ca.jacobian(res.T, x)])

    @classmethod
    def get(cls, n: int, loss: str = "squared") -> "ExtendedProblem":
        key = (n, loss)
        if key not in cls._cache:
            if len(cls._cache) > 64:
                cls._cache.clear()
            cls._cache[key] = cls(n, loss)
        return cls._cache[key]

    @staticmethod
    def bounds(active: NDArray[np.bool_]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bounds fixing every inactive coefficient (``active`` over β) at zero."""
        lb = np.full(N_X, -np.inf)
        ub = np.full(N_X, np.inf)
        lb[9:][~active] = 0.0
        ub[9:][~active] = 0.0
        return lb, ub

    def solve(self, x0: NDArray, p: NDArray, active: NDArray[np.bool_]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``x0`` with parameters ``p`` and the coefficients ``active`` free."""
        lb, ub = self.bounds(active)
        x0 = np.clip(x0, lb, ub)
        sol = self.solver(x0=x0, p=p, lbx=lb, ubx=ub)
        return np.asarray(sol["x"]).ravel(), self.solver.stats()

    def residual_values(self, x: NDArray, p: NDArray) -> NDArray[np.float64]:
        return np.asarray(self.residuals(x, p)).ravel()

    def jacobian_values(self, x: NDArray, p: NDArray) -> NDArray[np.float64]:
        return np.asarray(self.jacobian(x, p))


def active_mask(terms: Mapping[tuple[str, int], int]) -> NDArray[np.bool_]:
    """β mask of the coefficients of ``{(effect, axis): order}`` (orders 1..order)."""
    mask = np.zeros(N_BETA, dtype=bool)
    for (effect, axis), order in terms.items():
        for p in range(1, order + 1):
            mask[BETA_INDEX[(effect, axis, p)]] = True
    return mask


def to_model(x: NDArray, centre: NDArray, scale: float, reg: Regressors) -> ExtendedModel:
    """The physical :class:`ExtendedModel` of a solution ``x`` in normalised units."""
    from optcal.model import canonicalise, unpack_theta

    T_n, o_n = unpack_theta(x[:9])
    T = canonicalise(T_n / scale)
    o = centre + scale * o_n
    coefficients = {}
    for effect in PARAMETRIC:
        c = np.zeros((3, MAX_ORDER[effect]))
        h = reg.half_span(effect)
        for i in range(3):
            for p in range(1, MAX_ORDER[effect] + 1):
                value = x[9 + BETA_INDEX[(effect, i, p)]]
                c[i, p - 1] = value / h**p if value != 0 else 0.0
        coefficients[effect] = c
    temp_ref = reg.temp_ref if np.isfinite(reg.temp_ref) else 25.0
    t_ref = reg.t_ref if np.isfinite(reg.t_ref) else 0.0
    return ExtendedModel(LumpedModel.from_T(T, o), coefficients, temp_ref, t_ref)


def physical_factor(effect: str, order: int, reg: Regressors) -> float:
    """Factor turning a normalised coefficient of ``effect`` and ``order`` into physical units."""
    return 1.0 / reg.half_span(effect) ** order


def describe_term(effect: str, axis: int, order: int) -> str:
    """Readable name of a term, e.g. ``temperature_bias(z, order 2)``."""
    return f"{effect}({AXES[axis]}" + (f", order {order})" if order > 1 else ")")


def format_value(effect: str, value: float, stderr: float | None = None) -> str:
    """A coefficient in readable units (mg/°C, ppm/°C, µg/s, mg/g²) with its standard error."""
    factor, unit = {
        "temperature_bias": (1e3, "mg/°C"),
        "temperature_scale": (1e6, "ppm/°C"),
        "bias_drift": (1e6, "µg/s"),
        "scale_nonlinearity": (1e3, "mg/g²"),
    }[effect]
    text = f"{value * factor:+.3g}"
    if stderr is not None and np.isfinite(stderr):
        text += f" ± {stderr * factor:.2g}"
    return f"{text} {unit}"


# ----------------------------------------------------------------------------- measured-like recordings
#: Size of each effect in :func:`recording_with_effect` when none is given (first-order coefficient;
#: for ``bias_drift`` the drift over the whole recording in g; for ``outliers`` the number of poses).
DEMO_MAGNITUDE: dict[str, float] = {
    "temperature_bias": 0.8e-3,
    "temperature_scale": 400e-6,
    "bias_drift": 5e-3,
    "scale_nonlinearity": 6e-3,
    "outliers": 4,
}


def demo_sensor() -> LumpedModel:
    """A 16-bit MEMS accelerometer in counts (±2 g, about 16,400 counts per g; cf. the MPU-6050 data)."""
    return LumpedModel.from_physical(
        scale=[16300.0, 16450.0, 16700.0],
        rho=np.deg2rad(0.3),
        phi=np.deg2rad(-0.2),
        lam=np.deg2rad(0.4),
        bias=[700.0, -360.0, -1830.0],
    )


def warmup_cooldown(t: ArrayLike, start_c: float = 22.0, peak_c: float = 38.0, end_c: float = 27.0) -> NDArray[np.float64]:
    """A sensor warming up (first 55 % of the time) and cooling down again, °C at times ``t``."""
    t = np.asarray(t, dtype=float)
    u = (t - t.min()) / max(float(np.ptp(t)), 1e-12)
    knee = 0.55
    rise = start_c + (peak_c - start_c) * (1 - np.exp(-u / 0.15)) / (1 - np.exp(-knee / 0.15))
    at_knee = start_c + (peak_c - start_c)
    fall = end_c + (at_knee - end_c) * np.exp(-(u - knee) / 0.12)
    return np.where(u <= knee, rise, fall)


@dataclass
class HiddenEffect:
    """The truth of :func:`recording_with_effect` (for the check at the end, never for the fit).

    Attributes
    ----------
    effect : str
    axis : str or None
        ``None`` for outliers.
    value : float or None
        First-order coefficient in the units of :data:`UNITS` (``None`` for outliers).
    corrupt_times : list of (float, float)
        For outliers: the time span of each corrupted dwell.
    corrupt_radial_g : list of float
        For outliers: the part of each shift along the pose's direction, g (the only part a
        static calibration can see: a sideways shift changes the direction, not the magnitude).
    model : ExtendedModel
        The true sensor.
    """

    effect: str
    axis: str | None
    value: float | None
    corrupt_times: list[tuple[float, float]]
    model: ExtendedModel
    corrupt_radial_g: list[float] = field(default_factory=list)

    def describe(self) -> str:
        if self.effect == "outliers":
            return f"outliers: {len(self.corrupt_times)} poses shifted by 15-40 mg while the sensor rested"
        return f"{self.effect} on axis {self.axis}: {format_value(self.effect, float(self.value))}"

    def corrupt_rows(self, poses: PoseTable) -> list[int]:
        """Rows of the poses (static intervals) whose time falls in a corrupted dwell."""
        if poses.t is None:
            return []
        return [int(r) for r, t in zip(poses.rows, poses.t) if any(a <= t <= b for a, b in self.corrupt_times)]


def recording_with_effect(
    effect: str,
    axis: str | None = None,
    value: float | None = None,
    *,
    n_poses: int = 48,
    dwell_s: float = 4.0,
    transition_s: float = 2.0,
    rate_hz: float = 100.0,
    noise_g: float = 0.004,
    seed: int | None = 0,
) -> tuple[Any, HiddenEffect]:
    """A measured-like raw recording (counts, 100 Hz, warm-up then cool-down) with one hidden effect.

    The sensor (:func:`demo_sensor`) is set down in ``n_poses`` random orientations
    (:func:`optcal.data.synthetic.synthesize_recording`: rest, smooth turns, a gyro), its
    temperature follows :func:`warmup_cooldown`, the effect is applied to every sample through
    :class:`ExtendedModel`, and the output is rounded to integer counts.

    Parameters
    ----------
    effect : str
        One of :data:`EFFECTS`.
    axis : {"x", "y", "z"}, optional
        Axis of the effect (drawn at random when omitted; ignored for outliers).
    value : float, optional
        First-order coefficient (units of :data:`UNITS`); for ``bias_drift`` the default is
        :data:`DEMO_MAGNITUDE` spread over the recording; for ``outliers`` the number of poses.
    noise_g : float
        White noise per sample and axis, g.
    seed : int, optional

    Returns
    -------
    frame : pandas.DataFrame
        ``t, ax, ay, az, gx, gy, gz, temp``.
    truth : HiddenEffect
    """
    from optcal.data.synthetic import synthesize_recording
    from optcal.simulate import uniform_directions

    if effect not in EFFECTS:
        raise InputError(f"unknown effect {effect!r}; choose from {', '.join(EFFECTS)}")
    rng = np.random.default_rng(seed)
    base = demo_sensor()
    S = np.linalg.norm(base.C, axis=1)
    directions = uniform_directions(n_poses, rng)
    rec = synthesize_recording(
        base, directions, rate_hz=rate_hz, dwell_s=dwell_s, transition_s=transition_s,
        sigma=float(noise_g * S.mean()), units="counts", rng=rng,
    )
    frame = rec.frame.copy()
    t = frame["t"].to_numpy()
    frame["temp"] = warmup_cooldown(t) + 0.05 * rng.standard_normal(len(t))
    axis_name = AXES[int(rng.integers(3))] if axis is None else AXES[axis_number(axis)]
    corrupt: list[tuple[float, float]] = []
    if effect == "outliers":
        count = int(value if value is not None else DEMO_MAGNITUDE["outliers"])
        model = ExtendedModel(base, temp_ref=30.0, t_ref=float(t.mean()))
        acc = frame[["ax", "ay", "az"]].to_numpy(dtype=float, copy=True)
        radial: list[float] = []
        for k in sorted(rng.choice(len(rec.dwells), size=min(count, len(rec.dwells)), replace=False)):
            a, b = rec.dwells[k]
            shift = rng.standard_normal(3)
            shift *= rng.uniform(0.015, 0.040) / np.linalg.norm(shift)  # g
            acc[a:b] += S * shift
            corrupt.append((float(t[a]), float(t[b - 1])))
            radial.append(float(shift @ rec.directions[k]))
        frame["ax"], frame["ay"], frame["az"] = acc[:, 0], acc[:, 1], acc[:, 2]
        truth = HiddenEffect(effect, None, None, corrupt, model, radial)
    else:
        if value is None:
            value = DEMO_MAGNITUDE[effect] / (np.ptp(t) if effect == "bias_drift" else 1.0)
        model = ExtendedModel.with_effect(base, effect, axis_name, float(value), temp_ref=30.0, t_ref=float(t.mean()))
        frame = distort_recording(frame, model)
        truth = HiddenEffect(effect, axis_name, float(value), [], model)
    for c in ("ax", "ay", "az"):
        frame[c] = np.round(frame[c].to_numpy())
    return frame, truth
