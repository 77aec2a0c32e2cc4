"""The magnetometer's calibration: hard and soft iron as the accelerometer's ellipsoid problem.

A magnetometer turned through many orientations in a constant field traces the ellipsoid
``m̄ = T (m − o)``, ``‖m̄‖ = 1`` (hard iron ``o``, soft iron and scale ``T``; the field strength
is ``det(T)^(−1/3)`` in the data's units): the accelerometer's lumped model (Lu 2017, eq. 6,
13) with the local field in place of gravity and every raw sample as a "pose" (no rests are
needed, the noise is per sample).  So the same estimators fit it: the algebraic ellipsoid fit
as a convex problem in cvxpy (``A ⪰ εI``), refined by maximum likelihood in CasADi
(:mod:`optcal.families.accel.mle`: IPOPT or any solver by name, losses, ``fix``/``bounds``), and
the paper's gradient-descent baseline (``method="gd"``), all through
:func:`optcal.families.accel.calibration.calibrate`.

Reduced forms, chosen by evidence (:func:`choose_form`): ``full`` (9 parameters), ``diagonal``
(T diagonal: ``fix`` the three off-diagonal entries at 0, 6 parameters) and ``offsets`` (a
sphere, ``T = I/r``: 4 parameters, solved by linear least squares then Gauss–Newton).  The form
kept is the richest whose parameters are determined to :data:`USABLE_SHARE` of the field and
which predicts ``‖T(m − o)‖ = 1`` in directions left out of its fit (:func:`heldout_forms`: each
direction cell left out in turn) no worse than the best such form by more than the standard error
of the paired difference.  The physical model: a magnetometer always has some soft iron and scale
mismatch (a sphere is the approximation), so the comparison protects against a richer form that
predicts unseen directions worse, not against one the cells cannot tell apart; where the cells are too few (or
the user constrains the fit), the richest form whose every parameter is determined to
:data:`RELEVANT_SHARE` of the field: a parameter uncertain by 1 % of the field moves the
calibrated field by that much, about 0.6° of heading at the equator (more where the field dips).

The ellipsoid fit fixes ``T`` only up to a rotation (``‖R T u‖ = ‖T u‖``): the calibration
holds the symmetric ``T = (TᵀT)^½`` (no rotation: the form the firmware's soft-iron matrix
takes), and with an accelerometer the rotation between the two sensors' frames is estimated
from the constant angle between field and gravity (:mod:`optcal.families.mag.dip`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from optcal.core.poses import PoseTable
from optcal.core.stats import mean_and_se
from optcal.errors import IdentifiabilityError, InputError, SolverError
from optcal.families.mag.heldout_rule import richest_within_se
from optcal.families.mag.refine import ML_METHODS, START_SOLVER, SensorUnitsFit, refine_ml, solver_name
from optcal.families.mag.samples import MagSamples

#: The reduced forms, richest last, with their parameter counts.
FORMS: dict[str, int] = {"offsets": 4, "diagonal": 6, "full": 9}
#: A form is kept when the standard error of each of its parameters (by batch means of correlated
#: samples, :func:`batch_means_stderr`) is below this share of the field: an error of 1 % of the
#: field in a calibrated component is about 0.6° of heading at the equator (1/cos(dip) more
#: elsewhere), the accuracy a consumer compass is quoted at.
RELEVANT_SHARE: float = 0.01
#: Without a form determined to :data:`RELEVANT_SHARE`, the best determined one is kept when its
#: worst parameter is within a tenth of the field (about 6° of heading at the equator, the error of
#: an uncalibrated phone compass): beyond it no form is a calibration, and the samples are refused.
USABLE_SHARE: float = 0.1
#: Samples whose raw values spread by less than this share of their magnitude hold one
#: orientation: a rotation of θ moves the field by 2 sin(θ/2) of its magnitude, so 5 % is a turn
#: of about 3° (hand tremor, not a calibration's rotation), while a hard iron of three fields
#: still leaves a full rotation 15 % of the raw magnitude.
ONE_ORIENTATION_SHARE: float = 0.05
#: The largest rms of ‖T(m − o)‖ − 1 a magnetic field leaves: a field distorted by hard and soft
#: iron lies on an ellipsoid (shared recordings: 0.3-1.3 %), and a local disturbance or motor
#: current of a fifth of the field over the whole session is already no calibration.  Samples
#: beyond it are not a field (a gyro or an accelerometer in motion mapped as mx, my, mz).
NOT_A_FIELD_RMS: float = 0.2
#: A field turned through the orientations of a calibration spans a large share of its strength
#: (a full sphere: a standard deviation of 58 % of it along every axis; a ±30° cap still 20 %):
#: samples that spread by less than 10 % of the fitted field strength are a cloud that a huge
#: ellipsoid passes through, not a field seen from many sides (a gyro's or accelerometer's
#: columns mapped as mx, my, mz).
NOT_A_FIELD_SPAN: float = 0.1
#: Coverage directions (the cube's 6 faces, 12 edges and 8 corners) and the angular radius within
#: which a calibrated sample covers one: 30° leaves no point of the sphere farther than 30° from
#: a covered direction when all are covered (the largest gap between the 26 directions is 35°).
COVERAGE_CAP_DEG: float = 30.0
#: Coverage is judged on at most this many samples, evenly spaced in time: a turn through a
#: 30° cap at any hand speed leaves hundreds of samples in it at 10⁵ of a session.
COVERAGE_SAMPLES: int = 100_000


def _directions() -> tuple[NDArray[np.float64], list[str]]:
    dirs, names = [], []
    for v in np.array(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij")).reshape(3, -1).T:
        if not v.any():
            continue
        dirs.append(v / np.linalg.norm(v))
        names.append("".join(f"{'+' if c > 0 else '-'}{a}" for c, a in zip(v, "xyz") if c))
    return np.array(dirs), names


COVERAGE_DIRECTIONS, COVERAGE_NAMES = _directions()


#: The accelerometer's methods that need known orientations or rests (:mod:`optcal.families.accel.nominal`,
#: Ferraris' faces): a magnetometer turned freely has neither, and self-calibrates.
ORIENTATION_METHODS: tuple[str, ...] = ("sixpos", "nominal", "ferraris")


def refuse_orientation_method(method: str, option: str = "--method") -> None:
    """Refuse a method of :data:`ORIENTATION_METHODS` (an :class:`InputError` naming the self-calibrating ones,
    spelled as ``option``: the command's flag, or Python's keyword)."""
    if method in ORIENTATION_METHODS:
        raise InputError(f"{option} {method} needs known orientations or rests; a magnetometer self-calibrates: "
                         f"use {option} default, convex, mle, exact, gd or svd")


@dataclass(frozen=True)
class MagSettings:
    """How to fit: the estimator, the form and the solver settings.

    Attributes
    ----------
    method : str
        Any method of :data:`optcal.families.accel.calibration.ESTIMATORS` that self-calibrates
        (``default`` = convex then ML, ``convex``, ``mle``, ``exact``, ``gd``, ``svd``).
    form : str
        ``auto`` (by evidence), ``offsets``, ``diagonal`` or ``full``.
    allow_degenerate : bool
        Fit even when the samples do not determine the form's parameters.
    accept_fit : bool
        Keep a fit whose residual says the samples are not a field.
    estimator : dict
        Further estimator settings (``solver``, ``solver_options``, ``conic_solver``, ``loss``, ``fix``, ``bounds``).
    gyro_units : str, optional
        The gyroscope's units (``--gyro-units``) for the dip's near rest, instead of the decision from its samples.
    """

    method: str = "default"
    form: str = "auto"
    allow_degenerate: bool = False
    accept_fit: bool = False
    estimator: dict[str, Any] = field(default_factory=dict)
    gyro_units: str | None = None


@dataclass(frozen=True)
class FormFit:
    """One form's fit: ``T`` (symmetric), ``o``, the residuals and the standard errors (``note``: what was
    decided on the way, printed, e.g. a maximum-likelihood refinement not kept,
    :func:`optcal.families.mag.refine.refinement_departure`; ``ml_left``: the convex start was kept because the
    maximum likelihood left the physical set under both noise models, so the samples do not determine the form
    whatever its standard errors, linearised at the start, say)."""

    form: str
    T: NDArray[np.float64]
    o: NDArray[np.float64]
    residuals: NDArray[np.float64]
    stderr: dict[str, float]
    worst_share: float
    method: str
    solver: str
    note: str | None = None
    ml_left: bool = False

    @property
    def field_strength(self) -> float:
        """``det(T)^(−1/3)``: the radius of the sphere of the ellipsoid's volume, data units."""
        return float(np.linalg.det(self.T) ** (-1.0 / 3.0))

    @property
    def rms(self) -> float:
        """rms of ``‖T(m − o)‖ − 1``."""
        return float(np.sqrt(np.mean(self.residuals ** 2)))


@dataclass(frozen=True)
class Coverage:
    """Which directions of the sphere the calibrated samples reach.

    Attributes
    ----------
    covered, missing : tuple of str
        Direction names (``+z``, ``-x+y``, ...) with a sample within :data:`COVERAGE_CAP_DEG`, and without.
    spread : ndarray, shape (3,)
        Eigenvalues of the covariance of the unit directions, ascending (0 along the axis of a planar turn).
    thinnest_axis : ndarray, shape (3,)
        The eigenvector of the smallest eigenvalue.
    nearest_cos : ndarray, shape (26,)
        Per coverage direction, the cosine of the angle to its nearest sample.
    """

    covered: tuple[str, ...]
    missing: tuple[str, ...]
    spread: NDArray[np.float64]
    thinnest_axis: NDArray[np.float64]
    nearest_cos: NDArray[np.float64]

    @property
    def share(self) -> float:
        """Share of the 26 directions covered."""
        return len(self.covered) / len(COVERAGE_NAMES)


def coverage(unit: NDArray[np.float64]) -> Coverage:
    """The :class:`Coverage` of calibrated samples ``unit`` (n, 3), any norm (they are normalised)."""
    stride = max(1, len(unit) // COVERAGE_SAMPLES)
    u = unit[::stride] / np.linalg.norm(unit[::stride], axis=1, keepdims=True)
    cos_cap = np.cos(np.radians(COVERAGE_CAP_DEG))
    best = np.max(u @ COVERAGE_DIRECTIONS.T, axis=0)
    hit = best >= cos_cap
    values, vectors = np.linalg.eigh(np.cov(u.T))
    return Coverage(tuple(n for n, h in zip(COVERAGE_NAMES, hit) if h), tuple(n for n, h in zip(COVERAGE_NAMES, hit) if not h),
                    values, vectors[:, 0], best)


def symmetric_T(T: NDArray) -> NDArray[np.float64]:
    """The symmetric positive definite ``(TᵀT)^½``: the same ‖T u‖ for every u, no rotation."""
    w, V = np.linalg.eigh(T.T @ T)
    S: NDArray[np.float64] = (V * np.sqrt(w)) @ V.T
    return 0.5 * (S + S.T)


def correlation_inflation(residuals: NDArray) -> float:
    """``√((1 + ρ)/(1 − ρ))``, ρ the lag-1 autocorrelation of the residuals in sample order.

    Samples of a turned sensor are not independent (filters, slow turns, a model error that
    changes smoothly with orientation): the variance of a mean of AR(1) samples is that of
    independent ones times ``(1 + ρ)/(1 − ρ)``, so the standard errors are inflated by its root.
    Kept for the fits the user constrains (``--fix``/``--bound``); the forms' own standard errors
    are by batch means (:func:`batch_means_stderr`).
    """
    r = residuals - residuals.mean()
    den = float(r @ r)
    rho = float(r[1:] @ r[:-1]) / den if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.999)  # 0.999: at most a 45-fold inflation (an effective sample every 2000)
    return float(np.sqrt((1 + rho) / (1 - rho)))


#: The shortest batch of :func:`batch_means_stderr`, samples (a magnetometer's filter and a hand's
#: slow turn correlate at least this many samples of a 10-100 Hz sensor).
BATCH_START: int = 25
#: Fewest batches of :func:`batch_means_stderr`: a variance from k batch scores is itself
#: uncertain by about √(2/(k − 1)), a standard error by half that, 24 % at 10.
MIN_BATCHES: int = 10


def batch_means_stderr(J: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard errors of least-squares parameters with Jacobian ``J`` (n, p) and residuals ``r`` (n,)
    in sample order, by batch means: the sandwich ``(JᵀJ)⁻¹ (Σ_b g_b g_bᵀ) (JᵀJ)⁻¹`` with the
    score ``g_b = J_bᵀ r_b`` of each batch of consecutive samples (correlation within a batch
    counted, none assumed between batches), for batch lengths :data:`BATCH_START` · 2^j with at
    least :data:`MIN_BATCHES` batches, each parameter's largest (a standard error grows with the
    batches' length until they are longer than the residuals' correlation: a filter, a slow turn
    through a misfit, a drift; the largest is the conservative choice), and never below the white
    one ``√(diag (JᵀJ)⁻¹ · rᵀr/(n − p))``.
    """
    n, k = J.shape
    # columns scaled to unit norm first: in counts T's entries are ~1e-4 and o's ~1e3, so JᵀJ's condition number
    # (~1e15) put o's directions below pinv's cut-off and their standard errors at ~1e-14 (ybabs's counts)
    col = np.sqrt(np.einsum("ij,ij->j", J, J))
    col = np.where(col > 0, col, 1.0)
    J = J / col
    H = np.linalg.pinv(J.T @ J)
    se2 = np.diag(H) * float(r @ r) / max(n - k, 1)
    b = n // BATCH_START
    g = np.einsum("bli,bl->bi", J[: b * BATCH_START].reshape(b, BATCH_START, k), r[: b * BATCH_START].reshape(b, BATCH_START))
    while g.shape[0] >= MIN_BATCHES:
        se2 = np.maximum(se2, np.einsum("ij,jk,ki->i", H, g.T @ g, H))
        half = g.shape[0] // 2
        g = g[0 : 2 * half : 2] + g[1 : 2 * half : 2]  # the scores of batches twice as long (n // 2L of them)
    return np.asarray(np.sqrt(np.clip(se2, 0.0, None)) / col)


#: The six entries of a symmetric ``T`` (upper triangle) and their names.
SYMMETRIC_ENTRIES: tuple[tuple[int, int], ...] = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
SYMMETRIC_NAMES: tuple[str, ...] = ("T_xx", "T_xy", "T_xz", "T_yy", "T_yz", "T_zz")


def norm_residual_jacobian(m: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]
                           ) -> NDArray[np.float64]:
    """Jacobian of ``|T(m − o)| − 1`` with respect to the symmetric ``T``'s six entries
    (:data:`SYMMETRIC_ENTRIES`) and ``o`` (Lu 2017, eq. 13 differentiated)."""
    d = m - o
    v = np.einsum("kj,ij->ki", d, T)  # T d per row (numpy's matmul of (n, 3) by (3, 3) is several times slower)
    e = v / np.sqrt(np.einsum("ki,ki->k", v, v))[:, None]
    J = np.empty((m.shape[0], 9))
    for c, (i, j) in enumerate(SYMMETRIC_ENTRIES):  # ∂|T d|/∂T_ij = e_i d_j + e_j d_i (i ≠ j), e_i d_i
        np.multiply(e[:, i], d[:, j], out=J[:, c])
        if i != j:
            J[:, c] += e[:, j] * d[:, i]
    J[:, 6:] = -np.einsum("kj,ji->ki", e, T)
    return J


def _sphere_fit(m: NDArray) -> tuple[NDArray, float, NDArray]:
    """Offsets-only fit: ``‖m − o‖ = r`` (m in any dimension: a circle in a plane) by linear least squares, refined by Gauss–Newton; o, r, cov of (o, r)."""
    J = np.column_stack([2 * m, np.ones(len(m))])
    sol = np.linalg.lstsq(J, np.sum(m * m, axis=1), rcond=None)[0]
    o = sol[:-1]
    r = float(np.sqrt(max(sol[-1] + o @ o, 1e-300)))
    for _ in range(20):  # Gauss-Newton on the geometric residuals ‖m − o‖ − r
        d = m - o
        n = np.linalg.norm(d, axis=1)
        res = n - r
        G = np.column_stack([-d / n[:, None], -np.ones(len(m))])
        step = np.linalg.solve(G.T @ G, -(G.T @ res))  # normal equations: 4×4, linear in the samples
        o, r = o + step[:-1], r + float(step[-1])
        if np.linalg.norm(step) < 1e-10 * r:  # far below any standard error of a field's offset
            break
    d = m - o
    n = np.linalg.norm(d, axis=1)
    G = np.column_stack([-d / n[:, None], -np.ones(len(m))])
    res = n - r
    dof = max(len(m) - 4, 1)
    cov = np.linalg.pinv(G.T @ G) * float(res @ res) / dof
    return o, r, cov


#: The held-out comparison of the forms (:func:`heldout_forms`) is made on at most this many samples, evenly
#: spaced in time: a cell of the 26 then keeps about 200 samples (its mean square known to about a tenth of
#: itself under white noise, far less than the cells differ), and the 26 × 3 refits stay under a second.
#: Measured on the peers' files: 5,000 against 20,000 samples moved the held-out rms by at most 2 % of itself
#: and no form's paired gain by more than 0.1 of its standard error.
HELDOUT_SAMPLES: int = 5_000
#: Fewest direction cells the held-out comparison needs: the standard error of a paired difference from k
#: cells is itself uncertain by about 1/√(2(k − 1)), 41 % at 4; with fewer, the forms are chosen by how well
#: their parameters are determined alone (:data:`RELEVANT_SHARE`).
MIN_HELDOUT_CELLS: int = 4
#: Each form's free parameters mapped onto the symmetric ``T``'s six entries (:data:`SYMMETRIC_ENTRIES`).
FORM_BASIS: dict[str, NDArray[np.float64]] = {
    "offsets": np.array([[1.0], [0.0], [0.0], [1.0], [0.0], [1.0]]),  # T = s I: a sphere
    "diagonal": np.eye(6)[:, [0, 3, 5]],
    "full": np.eye(6),
}


@dataclass(frozen=True)
class HeldOut:
    """The forms' errors on direction cells left out of their fit (:func:`heldout_forms`).

    Attributes
    ----------
    cells : ndarray of int, shape (C,)
        The coverage directions (indices into :data:`COVERAGE_NAMES`) holding samples: each a fold.
    counts : ndarray of int, shape (C,)
        Samples per cell.
    mse : dict of str to ndarray, shape (C,)
        Per form, the mean square of ``‖T(m − o)‖ − 1`` over each cell's samples, ``T`` and ``o`` fitted
        without that cell.
    n_samples : int
        Samples compared (at most :data:`HELDOUT_SAMPLES`).
    """

    cells: NDArray[np.int64]
    counts: NDArray[np.int64]
    mse: dict[str, NDArray[np.float64]]
    n_samples: int

    def rms(self, form: str) -> float:
        """The held-out rms of ``‖T(m − o)‖ − 1`` of ``form`` over all the cells' samples."""
        return float(np.sqrt(np.sum(self.counts * self.mse[form]) / np.sum(self.counts)))

    def summary(self) -> dict[str, Any]:
        """The evidence for the JSON: the cells left out, the samples, each form's held-out rms and each richer
        form's mean-square gain over the simplest with its standard error."""
        forms = list(self.mse)
        return {"cells": [COVERAGE_NAMES[c] for c in self.cells], "n_samples": self.n_samples,
                "rms": {f: self.rms(f) for f in forms}, "fit": "maximum likelihood, squared loss",
                "gain_over_" + forms[0]: {f: dict(zip(("gain", "se"), self.gain(forms[0], f))) for f in forms[1:]}}

    def gain(self, simpler: str, richer: str) -> tuple[float, float]:
        """The paired difference of the held-out mean squares, ``simpler`` less ``richer``, and its standard
        error with the cells as the independent units (their samples correlated within, the weights the
        cells' shares of the samples)."""
        return mean_and_se(self.mse[simpler] - self.mse[richer], self.counts)


def _fit_symmetric(m: NDArray[np.float64], basis: NDArray[np.float64], sphere: tuple[NDArray[np.float64], float],
                   iterations: int = 30) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``T`` (symmetric, its entries ``basis @ θ``) and ``o`` minimising Σ (‖T(m − o)‖ − 1)², by
    Levenberg–Marquardt from ``sphere`` (o, r), the sphere's fit of the same samples (Lu 2017, eq. 13; the Jacobian of
    :func:`norm_residual_jacobian`).  Starting from the samples' own sphere, a direction the samples do not
    determine stays at the sphere's value instead of at a fit that saw other samples."""
    o, r = sphere
    theta = np.linalg.lstsq(basis, np.array([1 / r, 0, 0, 1 / r, 0, 1 / r]), rcond=None)[0]

    def unpack(th: NDArray[np.float64]) -> NDArray[np.float64]:
        e = basis @ th
        return np.array([[e[0], e[1], e[2]], [e[1], e[3], e[4]], [e[2], e[4], e[5]]])

    def residual(T: NDArray[np.float64], oo: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.einsum("kj,ij->ki", m - oo, T)
        return np.asarray(np.sqrt(np.einsum("ki,ki->k", v, v)) - 1.0)

    T = unpack(theta)
    res = residual(T, o)
    cost = float(res @ res)
    lam = 1e-6  # Marquardt's damping, relative to JᵀJ's diagonal; grown tenfold on a step that does not descend
    for _ in range(iterations):
        J = norm_residual_jacobian(m, T, o)
        J = np.column_stack([J[:, :6] @ basis, J[:, 6:]])
        A, g = J.T @ J, J.T @ res
        improved = False
        while lam < 1e6:
            try:
                step = np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-300), -g)
            except np.linalg.LinAlgError:  # a direction the samples do not see at all: damp it more
                lam *= 10.0
                continue
            T_new, o_new = unpack(theta + step[:-3]), o + step[-3:]
            res_new = residual(T_new, o_new)
            cost_new = float(res_new @ res_new)
            if cost_new <= cost:
                improved = True
                break
            lam *= 10.0
        if not improved:
            break
        done = cost - cost_new <= 1e-7 * cost  # settled: far below the forms' held-out differences (1e-3 of the cost and more)
        theta, T, o, res, cost, lam = theta + step[:-3], T_new, o_new, res_new, cost_new, max(lam / 10.0, 1e-9)
        if done:
            break
    return T, o


def heldout_forms(m: NDArray[np.float64], forms: tuple[str, ...]) -> HeldOut:
    """Each form's error on the directions it did not see: cross-validation over direction cells.

    The model: a calibration is used in the directions the sensor will see, so a form is worth its
    parameters when it predicts ``‖T(m − o)‖ = 1`` in a direction left out of its fit, not only in the
    samples it fitted.  The samples (at most :data:`HELDOUT_SAMPLES`, evenly spaced in time) are put in
    the cell of their nearest coverage direction (:data:`COVERAGE_DIRECTIONS`, caps of about 35°), their
    direction taken from the sphere fitted to them all (determined whenever any form is);
    each cell in turn is left out, every form fitted on the rest (:func:`_fit_symmetric`: maximum
    likelihood under white norm noise, the estimator's model) and its mean square residual measured
    on the cell.  A form that extrapolates badly into directions the others do not determine loses
    there, which is what the parameters' standard errors alone stand for.
    """
    stride = max(1, -(-len(m) // HELDOUT_SAMPLES))
    mm = np.ascontiguousarray(m[::stride])
    try:
        u = mm - _sphere_fit(mm)[0]
    except np.linalg.LinAlgError:  # no sphere through them all (not a field): the cells about their mean
        u = mm - mm.mean(axis=0)
    cell = np.argmax(u @ COVERAGE_DIRECTIONS.T / np.linalg.norm(u, axis=1, keepdims=True), axis=1)
    cells, counts = np.unique(cell, return_counts=True)
    mse: dict[str, NDArray[np.float64]] = {f: np.empty(len(cells)) for f in forms}
    for i, c in enumerate(cells):
        out = cell == c
        try:
            o_s, r_s, _ = _sphere_fit(mm[~out])
        except np.linalg.LinAlgError:  # the rest hold no sphere (not a field): no form predicts the cell
            for f in forms:
                mse[f][i] = np.inf
            continue
        for f in forms:
            if (~out).sum() <= FORMS[f]:
                mse[f][i] = np.inf
                continue
            T, o = _fit_symmetric(mm[~out], FORM_BASIS[f], (o_s, r_s))
            v = (mm[out] - o) @ T.T
            mse[f][i] = float(np.mean((np.linalg.norm(v, axis=1) - 1.0) ** 2))
    return HeldOut(cells.astype(np.int64), counts.astype(np.int64), mse, len(mm))


def fit_form(samples: MagSamples, form: str, settings: MagSettings) -> FormFit:
    """Fit one form (module docstring) to the samples."""
    from optcal.families.accel.calibration import calibrate

    m = samples.m
    if form == "offsets":
        o, r, _ = _sphere_fit(m)
        T = np.eye(3) / r
        resid = np.linalg.norm((m - o) @ T.T, axis=1) - 1.0
        d = m - o
        n = np.linalg.norm(d, axis=1)
        # ‖m − o‖/r − 1 differentiated by o and r; its standard errors by batch means (correlated samples)
        se = batch_means_stderr(np.column_stack([-d / (n * r)[:, None], -n / r**2]), resid)
        stderr = {"o_x": se[0], "o_y": se[1], "o_z": se[2], "r": se[3]}
        return FormFit(form, T, o, resid, {k: float(v) for k, v in stderr.items()}, float(np.max(se) / r),
                       "sphere", "numpy least squares + Gauss-Newton")
    est = dict(settings.estimator)
    method = settings.method
    if form == "diagonal":
        method = "mle" if method in ("default", "convex", "svd") else method
        est["fix"] = {**dict(est.get("fix") or {}), "T_yx": 0.0, "T_zx": 0.0, "T_zy": 0.0}
        if method not in ("mle",):
            raise InputError(f"--mag-form diagonal fixes T's off-diagonal entries, which the mle method does; "
                             f"not {method} (use --method mle or --mag-form full)")
    poses = PoseTable(acc=m, units="counts", source="raw recording")
    note = None
    if method in ML_METHODS:
        result, note = refine_ml(poses, form, method, est)
    else:
        result = calibrate(poses, method=method, allow_degenerate=True, **est)
    refined = isinstance(result, SensorUnitsFit)
    T = symmetric_T(result.T)
    o = np.asarray(result.o, dtype=float)
    resid = np.linalg.norm((m - o) @ T.T, axis=1) - 1.0
    r = float(np.linalg.det(T) ** (-1.0 / 3.0))
    if refined or (not settings.estimator.get("fix") and not settings.estimator.get("bounds")):
        # the stored symmetric T's entries and o, their standard errors by batch means; the diagonal form's
        # off-diagonal entries are fixed at 0 (not parameters)
        J = norm_residual_jacobian(m, T, o)
        keep = [0, 1, 2, 3, 4, 5, 6, 7, 8] if form == "full" else [0, 3, 5, 6, 7, 8]
        names = [(list(SYMMETRIC_NAMES) + [f"o_{a}" for a in "xyz"])[j] for j in keep]
        se = batch_means_stderr(J[:, keep], resid)
        stderr = dict(zip(names, map(float, se)))
        shares = [v / r if k.startswith("o_") else v * r for k, v in stderr.items()]  # T: 1/field per unit
        if not np.all(np.isfinite(shares)):
            shares.append(np.inf)
        return FormFit(form, T, o, resid, stderr, float(max(shares)), result.method, solver_name(result), note,
                       refined and solver_name(result) == START_SOLVER)
    assert not isinstance(result, SensorUnitsFit)
    infl = correlation_inflation(resid)
    stderr = {k: float(v) * infl for k, v in result.stderr.items() if np.isfinite(v)}
    shares = []
    for name, se in stderr.items():
        if name.startswith("o_"):
            shares.append(se / r)
        elif name.startswith("T_") and name not in est.get("fix", {}):
            shares.append(se * r)  # T is 1/field per unit: r·δT is the share of the field
    if len(stderr) < len(result.stderr) or not shares:
        shares.append(np.inf)
    return FormFit(form, T, o, resid, stderr, float(max(shares)), result.method, solver_name(result), note)


@dataclass(frozen=True)
class MagFit:
    """The chosen form's fit with the evidence for it.

    Attributes
    ----------
    fit : FormFit
    form_reason : str
        Why this form (printed, with ``--mag-form`` to override).
    tried : dict of str to FormFit
        Every form fitted on the way.
    coverage : Coverage
    notes : list of str
        Identifiability and coverage notes.
    heldout : HeldOut, optional
        The forms' errors on direction cells left out of their fit, where ``auto`` compared them.
    """

    fit: FormFit
    form_reason: str
    tried: dict[str, FormFit]
    coverage: Coverage
    notes: list[str]
    heldout: HeldOut | None = None


def check_samples(samples: MagSamples, settings: MagSettings) -> None:
    """Refuse samples no fit can use, in one line with the option that fixes or overrides it."""
    need = FORMS["offsets"] if settings.form in ("auto", "offsets") else FORMS[settings.form]
    if samples.n < max(need, 1) + 1:
        raise InputError(f"{samples.n} magnetometer samples: the {settings.form if settings.form != 'auto' else 'smallest'} "
                         f"form needs more than {need}; record the sensor turning through many orientations "
                         f"(optcal plan --sensor mag)")
    spread = float(np.sqrt(np.max(np.linalg.eigvalsh(np.cov(samples.m.T)))))
    size = float(np.median(np.linalg.norm(samples.m, axis=1)))
    if not settings.allow_degenerate and spread < ONE_ORIENTATION_SHARE * max(size, 1e-300):
        raise InputError(f"the magnetometer samples hold one orientation only (they spread by {spread:.3g}, "
                         f"{100 * spread / max(size, 1e-300):.2g} % of |m| = {size:.4g}; a calibration needs the sensor turned "
                         f"through many orientations: optcal plan --sensor mag); --allow-degenerate fits anyway")
    # an axis that reads one value in every sample while the others turn never saw the field turn (a 2-axis
    # compass logged with a third column of zeros, a dead axis): no ellipsoid through such samples is determined
    # (the sphere's normal equations are singular), whatever --allow-degenerate asks
    dead = [f"m{a}" for a, c in zip("xyz", samples.m.T) if np.ptp(c) == 0.0]
    if dead and spread > 0.0:
        value = ", ".join(f"{k} = {samples.m[0, 'xyz'.index(k[1])]:.6g}" for k in dead)
        raise InputError(f"the magnetometer's {', '.join(dead)} column reads one value in every sample ({value}) while "
                         f"the others turn: a 2-axis compass's log or a dead axis, and a field in three axes cannot be "
                         f"fitted to it; map three axes that measured the field with --columns mx=NAME,my=NAME,mz=NAME")


def choose_form(samples: MagSamples, settings: MagSettings) -> MagFit:
    """Fit the form that predicts the field best in directions left out of its fit, or the one asked for.

    ``auto``: the forms are compared held out over direction cells (:func:`heldout_forms`).  A form is
    usable when its fit to all the samples succeeds with its parameters determined to
    :data:`USABLE_SHARE` of the field (not a planar turn's full form); the best is the usable form with
    the smallest held-out error, and the richest usable form whose held-out mean square exceeds the
    best's by no more than the standard error of the paired difference is kept (a soft iron is
    always present: the comparison rejects a richer form only where it predicts the left-out
    directions worse).  With fewer than :data:`MIN_HELDOUT_CELLS` cells, or with the user's
    ``fix``/``bounds`` (a model the comparison does not fit), the richest form whose parameters are
    determined to :data:`RELEVANT_SHARE` of the field is kept.

    Raises
    ------
    InputError
        Samples no fit can use (:func:`check_samples`) or that are not a field.
    IdentifiabilityError
        No form's parameters are determined to :data:`USABLE_SHARE` (unless ``allow_degenerate``).
    """
    check_samples(samples, settings)
    tried: dict[str, FormFit] = {}
    failed: list[str] = []
    heldout: HeldOut | None = None

    def fit(form: str) -> FormFit | None:
        if form not in tried and samples.n > FORMS[form] and not any(f.startswith(f"the {form} form") for f in failed):
            try:
                tried[form] = fit_form(samples, form, settings)
            except SolverError as exc:
                failed.append(f"the {form} form's fit failed ({exc}); the other forms were tried")
        return tried.get(form)

    chosen: FormFit | None = None
    if settings.form != "auto":
        if settings.form not in FORMS:
            raise InputError(f"unknown --mag-form {settings.form!r}; use auto, {', '.join(FORMS)}")
        chosen = fit_form(samples, settings.form, settings)
        tried[settings.form] = chosen
        reason = "given with --mag-form"
    else:
        forms = tuple(f for f in FORMS if samples.n > FORMS[f])
        if not (settings.estimator.get("fix") or settings.estimator.get("bounds")) and len(forms) > 1:
            heldout = heldout_forms(samples.m, forms)
            if len(heldout.cells) < MIN_HELDOUT_CELLS:
                heldout = None
        if heldout is not None:
            chosen, evidence = _choose_heldout(heldout, fit)
        if chosen is not None and heldout is not None:
            reason = evidence + "; parameters determined to " + ", ".join(
                f"{f} {100 * t.worst_share:.2g} %" for f, t in tried.items()) + " of the field"
            reason += _heldout_model_line(settings)
            passed = [f for f in tried if tried[f].worst_share >= USABLE_SHARE]
            if passed:
                reason += (f" ({', '.join(passed)} not kept: {100 * USABLE_SHARE:g} % or worse is no calibration "
                           "in the directions left out)")
            left = [f for f in tried if tried[f].ml_left]
            if left:
                reason += (f" ({', '.join(left)} not kept: its maximum likelihood leaves the physical set under both noise "
                           "models, so the samples do not determine it)")
        else:
            for form in ("full", "diagonal", "offsets"):
                fit(form)
            if not tried:
                raise SolverError("; ".join(failed))
            _check_is_field(tried.get("offsets") or fit_form(samples, "offsets", settings), settings, samples.m)  # before "not determined"
            chosen, reason = _by_determination(tried)
            if chosen.worst_share >= USABLE_SHARE and not settings.allow_degenerate:
                _refuse_undetermined(samples, tried)
            if heldout is None and len(forms) > 1 and not (settings.estimator.get("fix") or settings.estimator.get("bounds")):
                reason += f"; the samples fill too few direction cells to compare the forms held out (at least {MIN_HELDOUT_CELLS})"
            elif chosen.worst_share >= USABLE_SHARE:
                reason += "; kept with --allow-degenerate"
    assert chosen is not None
    _check_is_field(chosen, settings, samples.m)
    cov = coverage((samples.m - chosen.o) @ chosen.T.T)
    notes = failed + ([chosen.note] if chosen.note else []) + coverage_notes(cov)
    return MagFit(chosen, reason + " (override with --mag-form offsets|diagonal|full)", tried, cov, notes, heldout)


def _heldout_model_line(settings: MagSettings) -> str:
    """What the held-out comparison fits with, where the user asked for another loss or method (:func:`heldout_forms`
    fits every form by plain maximum likelihood, the squared loss; the user's settings fit the chosen form only)."""
    given = []
    loss = str(settings.estimator.get("loss") or "squared")
    if loss != "squared":
        given.append(f"--loss {loss}")
    if settings.method not in ML_METHODS:
        given.append(f"--method {settings.method}")
    if not given:
        return ""
    return (f"; the forms compared under plain maximum likelihood (squared loss), not {' and '.join(given)}, "
            "which fit the chosen form only")


def _by_determination(tried: dict[str, FormFit]) -> tuple[FormFit, str]:
    """The richest form whose every parameter is determined to :data:`RELEVANT_SHARE` of the field, else the best determined."""
    for form in ("full", "diagonal", "offsets"):
        if form in tried and tried[form].worst_share < RELEVANT_SHARE:
            chosen = tried[form]
            richer = [f for f in ("full", "diagonal") if f in tried and FORMS[f] > FORMS[form]]
            reason = (f"every parameter determined to {100 * chosen.worst_share:.2g} % of the field "
                      f"(< {100 * RELEVANT_SHARE:g} %)")
            if richer:
                reason += "; " + ", ".join(f"{f}: {100 * tried[f].worst_share:.2g} %" for f in richer)
            return chosen, reason
    chosen = min(tried.values(), key=lambda f: f.worst_share)
    return chosen, (f"no form is determined to {100 * RELEVANT_SHARE:g} % of the field; the best determined one, to "
                    f"{100 * chosen.worst_share:.2g} % (" + ", ".join(f"{f}: {100 * t.worst_share:.2g} %" for f, t in tried.items())
                    + ")")


def _choose_heldout(heldout: HeldOut, fit: Callable[[str], FormFit | None]) -> tuple[FormFit | None, str]:
    """The richest usable form whose held-out error is within its paired standard error of the best usable form's
    (:func:`choose_form`), with the evidence in words; ``None`` when no form is usable (``fit`` fits a form once,
    ``None`` where its fit failed)."""
    forms = list(heldout.mse)  # simplest first (FORMS' order)

    def usable(form: str) -> FormFit | None:
        f = fit(form)
        # a form whose maximum likelihood leaves the physical set under both noise models is not determined (generated
        # 60° caps with a 6 % soft iron: the convex start kept, 9.3-9.8 % by its standard errors, 22-26 % of the field
        # wrong in the uncovered directions, where the sphere is 6 % wrong)
        return f if f is not None and f.worst_share < USABLE_SHARE and not f.ml_left else None

    rms = ", ".join(f"{f} {100 * heldout.rms(f):.3g} %" for f in forms)
    gain = ", ".join(f"{f} {g:.2g} ± {se:.2g}" for f, (g, se) in ((f, heldout.gain(forms[0], f)) for f in forms[1:]))
    evidence = (f"held out by direction ({len(heldout.cells)} of {len(COVERAGE_NAMES)} cells left out of the fit in turn, "
                f"{heldout.n_samples} samples): rms {rms}; mean-square gain over {forms[0]}: {gain}; ")
    form, best, excess = richest_within_se(heldout, forms, lambda f: usable(f) is not None)
    if form is None:
        return None, evidence
    if excess is None:
        return usable(form), evidence + (f"{form}: the smallest held-out error of the usable forms; no richer usable "
                                         "form within its standard error of it")
    return usable(form), (evidence + f"{form}: the richest usable form within its standard error of the best held out "
                                     f"({best}; {100 * heldout.rms(form):.3g} % against {100 * heldout.rms(str(best)):.3g} "
                                     f"%, a mean-square excess {excess[0]:.2g} ± {excess[1]:.2g})")


def _refuse_undetermined(samples: MagSamples, tried: dict[str, FormFit]) -> None:
    cov = coverage((samples.m - tried[next(iter(tried))].o) @ tried[next(iter(tried))].T.T)
    worst = ", ".join(f"{f}: {100 * t.worst_share:.2g} %" for f, t in tried.items())
    raise IdentifiabilityError(
        f"the samples determine no form's parameters to {100 * USABLE_SHARE:g} % of the field ({worst}); "
        f"{coverage_notes(cov)[0] if coverage_notes(cov) else 'turn the sensor through more orientations'}; "
        f"--allow-degenerate or --mag-form offsets fits anyway"
    )


def planar_tilt(m: NDArray[np.float64], misfit: float = np.inf) -> tuple[float, NDArray[np.float64]]:
    """The share of the samples' spread that tilts out of their plane, and that plane's axis (the thinnest).

    A field turned about one axis traces a circle; along the axis the samples hold the field's component and the hard
    iron, which no turn about it tells apart (the sphere fit finds them only from the noise and the misfit).  The
    raw samples' covariance's smallest eigenvalue, less the sensor's noise along that axis, over the whole spread, is
    the tilt's share: a full sphere gives 1/3, a turn tilted by θ rms about the plane θ²/2.  The noise is the smaller
    of two bounds: half the variance of consecutive samples' differences along the axis (by their MAD: a turn about
    the axis moves the samples in the plane), and ``misfit``, a fit's rms distance from its surface (sensor units).
    """
    eig, axes = np.linalg.eigh(np.cov(m.T))
    d = np.diff(m, axis=0) @ axes[:, 0]
    noise2 = (1.4826 * float(np.median(np.abs(d - np.median(d))))) ** 2 / 2.0 if d.size else 0.0
    return max(float(eig[0]) - min(noise2, misfit**2), 0.0) / max(float(np.sum(eig)), 1e-300), axes[:, 0]


def _check_is_field(fit: FormFit, settings: MagSettings, m: NDArray[np.float64]) -> None:
    if settings.accept_fit:
        return
    not_field = ("check that --columns maps mx, my, mz to the magnetometer (not a gyro or accelerometer); "
                 "--accept-mag-fit keeps it")
    if fit.rms > NOT_A_FIELD_RMS:
        raise InputError(f"the samples are not a magnetic field: they leave the fitted ellipsoid by {100 * fit.rms:.3g} % rms "
                         f"(a field with hard and soft iron: a few %); {not_field}")
    eig = np.linalg.eigvalsh(np.cov(m.T))
    spread = float(np.sqrt(np.max(eig)))
    dwarfed = spread < NOT_A_FIELD_SPAN * fit.field_strength
    cloud = InputError(f"the samples are not a magnetic field: they spread by {spread:.3g}, {100 * spread / fit.field_strength:.2g} % "
                       f"of the fitted field strength {fit.field_strength:.4g} (a field turned through a calibration spans "
                       f"tens of % of its strength); {not_field}")
    if dwarfed and eig[0] >= PLANAR_SPREAD * np.sum(eig):  # a cloud, not a circle: a huge ellipsoid passes through it
        raise cloud
    tilt, axis = planar_tilt(m, fit.rms * fit.field_strength)
    if tilt < PLANAR_SPREAD:
        if settings.allow_degenerate:
            return
        # the turns do not span the sphere: the field strength and the hard iron along the axis are not determined,
        # whatever the fit's standard errors say (a sphere through a circle may be of any size)
        raise IdentifiabilityError(
            f"the magnetometer samples turn in one plane (their tilt out of it, along [{', '.join(f'{c:+.2f}' for c in axis)}], "
            f"less the noise, is {100 * tilt:.2g} % of their spread, a tilt of {np.degrees(np.sqrt(2 * tilt)):.2g}° rms): "
            f"the field strength (fitted {fit.field_strength:.4g}, the circle's) and the hard iron along that axis are not "
            f"determined; turn the sensor about a second axis (roll it 90° and turn it again: optcal plan --sensor mag); --mag-form "
            f"planar calibrates the heading; --allow-degenerate fits the hard iron in the plane anyway, --accept-mag-fit keeps the fit")
    if dwarfed:
        raise cloud


#: A planar turn leaves the direction covariance this small along its axis (a full sphere gives
#: 1/3 on every axis, a turn about one axis with the field at 30° from it 0 along the axis, 0.125
#: and 0.125 across): below 0.01 (a tilt of 8° rms about the plane) the axis is not seen; the raw
#: samples' tilt share (:func:`planar_tilt`) is held to the same.
PLANAR_SPREAD: float = 0.01


def coverage_notes(cov: Coverage) -> list[str]:
    """What the coverage leaves undetermined and the orientations that would fix it."""
    notes = []
    if cov.spread[0] < PLANAR_SPREAD:
        axis = ", ".join(f"{c:+.2f}" for c in cov.thinnest_axis)
        notes.append(f"the samples turn in one plane (direction spread {cov.spread[0]:.2g} along [{axis}]): the "
                     f"ellipsoid's extent along that axis, the field strength and the hard iron along it are not determined; add orientations that tilt that axis "
                     f"towards and away from the field (e.g. roll the sensor 90° and turn it again)")
    if cov.missing:
        notes.append(f"coverage {len(cov.covered)}/{len(COVERAGE_NAMES)} directions; missing: {', '.join(cov.missing)} "
                     f"(point those sensor directions along the field to fill them)")
    return notes
