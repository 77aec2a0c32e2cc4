"""The planar (heading) magnetometer calibration: a sensor turned in one plane traces an ellipse.

A compass turned flat, a robot or vehicle turning on the floor, a phone turned about one axis: the field's
component in the plane of the turn traces ``|T₂ (P m − c)| = 1`` (``P`` the 2×3 basis of the plane, ``c`` the hard
iron in it, ``T₂`` the soft iron and scale in it, symmetric 2×2), while along the plane's normal ``n`` the samples
hold the field's normal component plus the hard iron along ``n``, which no turn in the plane tells apart; nor is the
dip (the angle of the field to the plane) seen.  So the calibration is a heading calibration:

* ``n`` is the raw samples' thinnest axis (:func:`optcal.families.mag.fit.planar_tilt`, the test that refuses a
  planar turn a 3-D form);
* the ellipse is fitted algebraically as a convex problem in cvxpy (``A ⪰ εI``, ``tr A = 2``: the 3-D fit's
  :class:`optcal.families.accel.ellipsoid.ConvexEllipsoidProblem` in two dimensions) and refined by maximum
  likelihood, ``Σ (|T₂(p − c)| − 1)²`` (Lu 2017, eq. 14 in the plane), by IPOPT in CasADi with numpy callbacks
  (:class:`optcal.solvers.nlp.CallbackNLP`, as :mod:`optcal.families.mag.refine` does), kept only inside the
  physical set (:data:`optcal.families.mag.refine.FIELD_FACTOR`, :data:`optcal.families.mag.refine.AXIS_STRETCH`);
* it is compared with the circle (``c`` and a radius: 3 parameters) held out over heading sectors by the rule the
  3-D forms use (:func:`optcal.families.mag.fit.choose_form`): the richer form is kept unless its held-out mean
  square exceeds the best usable form's by more than the paired difference's standard error.

In three dimensions the calibration is ``T = Pᵀ T₂ P + (1/H) n nᵀ``, ``o = Pᵀ c`` with ``H = det(T₂)^(−1/2)`` the
field's component in the plane: ``T`` stays symmetric positive definite and ``det(T)^(−1/3) = H``, so every
consumer of a 3-D calibration reads ``H`` as the field strength; ``H · T (m − o)`` is the in-plane field calibrated
and, along ``n``, the raw normal component ``n·m`` unchanged (its hard iron undetermined, taken as 0).  A hard iron
``ε`` along ``n`` leaks into the heading as about ``ε sin θ / H`` when the sensor is tilted by θ out of the plane.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import IdentifiabilityError, InputError, SolverError
from optcal.families.mag.fit import (MIN_HELDOUT_CELLS, NOT_A_FIELD_RMS, ONE_ORIENTATION_SHARE, PLANAR_SPREAD,
                                     RELEVANT_SHARE, USABLE_SHARE, HeldOut, _sphere_fit, batch_means_stderr,
                                     planar_tilt)
from optcal.families.mag.heldout_rule import richest_within_se
from optcal.families.mag.refine import AXIS_STRETCH, FIELD_FACTOR

#: The planar forms, richest last, with their parameter counts.
PLANAR_FORMS: dict[str, int] = {"circle": 3, "ellipse": 5}
#: Heading sectors of the held-out comparison and of the coverage: 30° each, the 3-D cells' angular size (their caps
#: are about 35° wide).  Leaving one out still leaves the ellipse's second harmonic (period 180°) seen six times over.
HEADING_SECTORS: int = 12
#: The convex fit's lower bound on the quadric's eigenvalues, normalised to ``tr A = 2`` (the 3-D fit's ε = 1e-3 at
#: ``tr A = 3``): it keeps the quadric an ellipse, an axis ratio of at most about 45, far beyond a soft iron's
#: (:data:`optcal.families.mag.refine.AXIS_STRETCH` = 5), so it never binds on a magnetometer's ellipse.
CONVEX_EPS: float = 1e-3


def plane_basis(normal: NDArray[np.float64]) -> NDArray[np.float64]:
    """The 2×3 orthonormal basis ``P`` of the plane normal to ``normal``: its first row the sensor axis most in the
    plane, projected into it; the second ``n × P₀`` (so that ``(P₀, P₁, n)`` is right-handed)."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    axis = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = axis - (axis @ n) * n
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(n, e1)])


def _residuals(p: NDArray[np.float64], x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``|T₂(p − c)| − 1`` for ``x = (a, b, d, c₀, c₁)``, ``T₂ = [[a, 0], [b, d]]`` (lower-triangular: the rotation
    the norm does not see removed), and its Jacobian (n, 5)."""
    a, b, d, c0, c1 = x
    q0, q1 = p[:, 0] - c0, p[:, 1] - c1
    v0, v1 = a * q0, b * q0 + d * q1
    r = np.sqrt(v0 * v0 + v1 * v1)
    e0, e1 = v0 / r, v1 / r
    J = np.column_stack([e0 * q0, e1 * q0, e1 * q1, -(e0 * a + e1 * b), -e1 * d])
    return r - 1.0, J


def _lower(T2: NDArray[np.float64]) -> NDArray[np.float64]:
    """A lower-triangular ``L`` with ``LᵀL = T₂ᵀT₂`` (the same norm): ``L = chol(T₂ᵀT₂)ᵀ`` reversed."""
    M = T2.T @ T2
    d = np.sqrt(M[1, 1])
    b = M[0, 1] / d
    a = np.sqrt(max(M[0, 0] - b * b, 1e-300))
    return np.array([a, b, d])


def _symmetric(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """The symmetric ``(T₂ᵀT₂)^½`` of ``x``'s lower-triangular ``T₂``: the same norm, no rotation."""
    L = np.array([[x[0], 0.0], [x[1], x[2]]])
    w, V = np.linalg.eigh(L.T @ L)
    S = (V * np.sqrt(w)) @ V.T
    return np.asarray(0.5 * (S + S.T))


def convex_ellipse(p: NDArray[np.float64], solver: str | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The algebraic ellipse ``pᵀAp + bᵀp + k = 0`` through the samples ``p`` (n, 2), ``A ⪰ εI``, ``tr A = 2``,
    least squares in cvxpy (the 3-D fit's convex problem in the plane, Lu 2017 eq. 18-30), on the samples centred
    and scaled to unit rms; returns the symmetric ``T₂`` and the centre ``c`` in ``p``'s units."""
    import cvxpy as cp

    mu = p.mean(axis=0)
    s = float(np.sqrt(np.mean(np.sum((p - mu) ** 2, axis=1)))) or 1.0
    q = (p - mu) / s
    D = np.column_stack([q[:, 0] ** 2, q[:, 1] ** 2, 2 * q[:, 0] * q[:, 1], q[:, 0], q[:, 1], np.ones(len(q))])
    R = np.linalg.qr(D, mode="r")  # ‖D η‖ = ‖R η‖: the problem's size is that of η, not of the samples
    A = cp.Variable((2, 2), symmetric=True)
    b = cp.Variable(2)
    k = cp.Variable()
    eta = cp.hstack([A[0, 0], A[1, 1], A[0, 1], b, k])
    problem = cp.Problem(cp.Minimize(cp.sum_squares(R @ eta)), [A >> CONVEX_EPS * np.eye(2), cp.trace(A) == 2.0])
    try:
        problem.solve(solver=solver) if solver else problem.solve()
    except cp.error.SolverError as exc:
        raise SolverError(f"the convex ellipse fit failed ({exc})") from exc
    if A.value is None or b.value is None or k.value is None:
        raise SolverError(f"the convex ellipse fit ended {problem.status}")
    Av, bv, kv = np.asarray(A.value), np.asarray(b.value), float(k.value)
    centre = -0.5 * np.linalg.solve(Av, bv)
    scale = float(centre @ Av @ centre) - kv  # (q − centre)ᵀ A (q − centre) = scale
    if not scale > 0:
        raise SolverError("the convex ellipse fit found no ellipse through the samples")
    w, V = np.linalg.eigh(Av / scale)
    T2 = (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T / s
    return 0.5 * (T2 + T2.T), mu + s * centre


def refine_ellipse(p: NDArray[np.float64], T2: NDArray[np.float64], c: NDArray[np.float64],
                   est: dict[str, Any]) -> tuple[NDArray[np.float64], NDArray[np.float64], str]:
    """``Σ (|T₂(p − c)| − 1)²`` minimised from ``(T₂, c)`` by IPOPT in CasADi (numpy callbacks: value, gradient and
    Gauss–Newton Hessian), on the samples centred and scaled to unit rms; ``est`` names the solver and its options.
    Returns the symmetric ``T₂``, ``c`` and the solver's status."""
    from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, CallbackNLP, NumpyObjective, cost_scale
    from optcal.solvers.registry import choose_nlp_solver

    mu = p.mean(axis=0)
    s = float(np.sqrt(np.mean(np.sum((p - mu) ** 2, axis=1)))) or 1.0
    q = (p - mu) / s
    x0 = np.concatenate([_lower(T2 * s), (c - mu) / s])
    r0, _ = _residuals(q, x0)
    scale = cost_scale(len(q), float(np.sqrt(np.mean(r0 ** 2))))

    def value(x: NDArray) -> float:
        r, _ = _residuals(q, np.asarray(x, float).ravel())
        return float(scale * (r @ r))

    def gradient(x: NDArray) -> tuple[float, NDArray]:
        r, J = _residuals(q, np.asarray(x, float).ravel())
        return float(scale * (r @ r)), 2.0 * scale * (J.T @ r)

    def hessian(x: NDArray, lam: float) -> NDArray:
        _, J = _residuals(q, np.asarray(x, float).ravel())
        return np.asarray(2.0 * scale * lam * (J.T @ J))

    choice = choose_nlp_solver(est.get("solver"), {**dict(est.get("ipopt_options") or {}),
                                                   **dict(est.get("solver_options") or {})})
    nlp = CallbackNLP("mag_planar_ml", 5, hessian_block_size=5, tuning=SCALED_COST_IPOPT_OPTIONS, solver=choice)
    x, stats = nlp.solve(NumpyObjective(value, gradient, hessian), x0=x0)
    return _symmetric(x) / s, mu + s * x[3:], str(stats.get("return_status", "unknown"))


def _ellipse_lm(p: NDArray[np.float64], x: NDArray[np.float64], iterations: int = 30) -> NDArray[np.float64]:
    """Levenberg–Marquardt on ``Σ (|T₂(p − c)| − 1)²`` from ``x`` (:func:`_residuals`' parameters): the held-out
    folds' maximum likelihood (the same model as :func:`refine_ellipse`, without a solver's set-up per fold)."""
    r, J = _residuals(p, x)
    cost, lam = float(r @ r), 1e-6
    for _ in range(iterations):
        A, g = J.T @ J, J.T @ r
        while lam < 1e6:
            try:
                step = np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-300), -g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            r_new, J_new = _residuals(p, x + step)
            if float(r_new @ r_new) <= cost:
                break
            lam *= 10.0
        else:
            break
        new = float(r_new @ r_new)
        done = cost - new <= 1e-7 * cost  # settled: far below the forms' held-out differences
        x, r, J, cost, lam = x + step, r_new, J_new, new, max(lam / 10.0, 1e-9)
        if done:
            break
    return x


def heading_sectors(p: NDArray[np.float64], c: NDArray[np.float64]) -> NDArray[np.int64]:
    """Each sample's heading sector (0 … :data:`HEADING_SECTORS` − 1) about ``c``."""
    ang = np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]) % (2 * np.pi)
    return np.minimum((ang / (2 * np.pi / HEADING_SECTORS)).astype(np.int64), HEADING_SECTORS - 1)


def heldout_planar(p: NDArray[np.float64], max_samples: int = 5000) -> HeldOut:
    """The circle's and the ellipse's mean square ``(|T₂(p − c)| − 1)²`` on each heading sector left out of their fit
    (maximum likelihood on the rest), on at most ``max_samples`` samples evenly spaced in time (the 3-D comparison's
    :data:`optcal.families.mag.fit.HELDOUT_SAMPLES`); ``cells`` are the sector indices."""
    stride = max(1, -(-len(p) // max_samples))
    pp = np.ascontiguousarray(p[::stride])
    sector = heading_sectors(pp, _sphere_fit(pp)[0])
    cells, counts = np.unique(sector, return_counts=True)
    mse = {f: np.full(len(cells), np.inf) for f in PLANAR_FORMS}
    for i, cell in enumerate(cells):
        out = sector == cell
        rest = pp[~out]
        if len(rest) <= PLANAR_FORMS["ellipse"]:
            continue
        try:
            c, r, _ = _sphere_fit(rest)
        except np.linalg.LinAlgError:
            continue
        mse["circle"][i] = float(np.mean((np.linalg.norm(pp[out] - c, axis=1) / r - 1.0) ** 2))
        x = _ellipse_lm(rest, np.array([1 / r, 0.0, 1 / r, c[0], c[1]]))
        mse["ellipse"][i] = float(np.mean(_residuals(pp[out], x)[0] ** 2))
    return HeldOut(cells.astype(np.int64), counts.astype(np.int64), mse, len(pp))


@dataclass(frozen=True)
class PlanarFit:
    """A planar calibration's fit and the evidence for it (module docstring).

    Attributes
    ----------
    normal : ndarray, shape (3,)
        The plane's normal ``n`` (the samples' thinnest axis), sign chosen with its largest component positive.
    basis : ndarray, shape (2, 3)
        ``P``, the plane's orthonormal basis (:func:`plane_basis`).
    form : str
        ``circle`` or ``ellipse`` (:data:`PLANAR_FORMS`).
    T2 : ndarray, shape (2, 2)
        Symmetric, per data unit.
    c : ndarray, shape (2,)
        The hard iron in the plane (``P``'s coordinates), data units.
    residuals : ndarray
        ``|T₂(P m − c)| − 1`` per sample.
    stderr : dict
        Standard errors of the form's parameters (batch means of correlated samples).
    worst_share : float
        The largest standard error as a share of the horizontal field.
    tilt_share, tilt_deg : float
        The samples' tilt out of the plane, less the noise, as a share of their spread and as an rms angle.
    sectors : tuple of int
        The heading sectors (of :data:`HEADING_SECTORS`) the calibrated samples reach.
    method, solver, reason : str
        How the ellipse was fitted, by which solver, and why this form (printed).
    heldout : HeldOut, optional
        The held-out comparison over heading sectors (``cells`` are sector indices).
    note : str, optional
        A refinement not kept, or another decision made on the way.
    """

    normal: NDArray[np.float64]
    basis: NDArray[np.float64]
    form: str
    T2: NDArray[np.float64]
    c: NDArray[np.float64]
    residuals: NDArray[np.float64]
    stderr: dict[str, float]
    worst_share: float
    tilt_share: float
    tilt_deg: float
    sectors: tuple[int, ...]
    method: str
    solver: str
    reason: str
    heldout: HeldOut | None = None
    note: str | None = None

    @property
    def horizontal_field(self) -> float:
        """``H = det(T₂)^(−1/2)``: the field's component in the plane (the radius of the circle of the ellipse's
        area), data units."""
        return float(np.linalg.det(self.T2) ** -0.5)

    @property
    def rms(self) -> float:
        """rms of ``|T₂(P m − c)| − 1``."""
        return float(np.sqrt(np.mean(self.residuals ** 2)))

    @property
    def T(self) -> NDArray[np.float64]:
        """The 3×3 ``Pᵀ T₂ P + (1/H) n nᵀ`` (module docstring): symmetric positive definite, ``det(T)^(−1/3) = H``."""
        return np.asarray(self.basis.T @ self.T2 @ self.basis + np.outer(self.normal, self.normal) / self.horizontal_field)

    @property
    def o(self) -> NDArray[np.float64]:
        """``Pᵀ c``: the hard iron in the plane; along ``n`` 0 (undetermined)."""
        return np.asarray(self.basis.T @ self.c)

    def tilt_heading_error(self) -> str:
        """The heading error a hard iron ``ε`` along the normal (undetermined) leaks at the recording's tilt, in words."""
        theta = np.radians(self.tilt_deg)
        if np.sin(theta) <= 0:
            return ("a hard iron ε along the normal moves the heading by about ε sin θ / H at a tilt θ out of the plane "
                    "(none while the sensor stays in it)")
        eps_1deg = self.horizontal_field * np.radians(1.0) / np.sin(theta)
        return (f"a hard iron ε along the normal moves the heading by about ε sin θ / H at a tilt θ out of the plane: at "
                f"this recording's {self.tilt_deg:.2g}° rms, 1° of heading per {eps_1deg:.3g} of ε "
                f"({100 * eps_1deg / self.horizontal_field:.3g} % of H)")


#: Dips at which :func:`vertical_field_heading_error` states the vertical field's share without ``--location``: from a
#: low latitude's to a high one's (the WMM's dip is within ±80° wherever people live but near the dip poles).
STATED_DIPS_DEG: tuple[float, ...] = (30.0, 60.0, 70.0, 80.0)


def vertical_field_heading_error(dip_deg: float | None = None, where: str = "at --location") -> str:
    """The heading error the vertical field ``Z`` brings in when the turn's plane tilts by θ from the horizontal, in
    words: about ``(Z/H) θ`` at most (``Z/H = tan I``, the dip ``I``), degrees of heading per degree of tilt.

    A level sensor reads the horizontal field ``H`` in its plane; tilted by a small θ about an axis in the plane, one
    in-plane axis also reads ``Z sin θ``, which turns the heading by up to ``(Z/H) sin θ`` radians (nothing when the
    tilt axis points along the field).  It is larger than the hard-iron leak (:meth:`PlanarFit.tilt_heading_error`)
    wherever ``Z`` exceeds the normal hard iron; the calibration does not see it (the dip is undetermined).

    Parameters
    ----------
    dip_deg : float, optional
        The dip at the place (the World Magnetic Model's at ``--location``); None states it for :data:`STATED_DIPS_DEG`.
    where : str
        Where the dip comes from (for the sentence).
    """
    head = ("a tilt θ of the turn's plane from the horizontal brings the vertical field Z in: the heading moves by up "
            "to (Z/H)·θ, tan(dip) degrees per degree of tilt")
    if dip_deg is None:
        per = ", ".join(f"{np.tan(np.radians(d)):.2g} at a dip of {d:g}°" for d in STATED_DIPS_DEG)
        return f"{head}: {per} (--location gives the place's)"
    return f"{head}: {abs(np.tan(np.radians(dip_deg))):.3g}° per degree {where} (dip {dip_deg:.2f}°)"


def planar_evidence(m: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
    """The planar test of :func:`optcal.families.mag.fit.planar_tilt` with the misfit of the circle fitted to the
    samples projected on their thinnest axis's plane (the noise bound the 3-D test takes from its sphere): the tilt's
    share of the spread and the plane's normal."""
    axis = np.linalg.eigh(np.cov(m.T))[1][:, 0]
    p = m @ plane_basis(axis).T
    try:
        c, r, _ = _sphere_fit(p)
        misfit = float(np.sqrt(np.mean((np.linalg.norm(p - c, axis=1) - r) ** 2)))
    except np.linalg.LinAlgError:
        misfit = np.inf
    return planar_tilt(m, misfit)


def plane_departure(m: NDArray[np.float64], normal: NDArray[np.float64]) -> tuple[float, float]:
    """How far samples ``m`` (n, 3) leave the plane normal to ``normal`` (a planar calibration's): their spread along
    it less the sensor's noise there, as a share of their whole spread, and as the angle ``asin √(2 share)`` of a plane
    they would turn in.  The planar test's (:func:`optcal.families.mag.fit.planar_tilt`) along a given axis instead of
    the samples' thinnest, the noise taken from consecutive samples' differences along it: a turn in the plane gives 0,
    one in a plane at α to it ``sin²α / 2`` (so the angle is α; a small wobble's, ``√(2 share)``, is the planar test's
    rms tilt), a full sphere 1/3 (55°)."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    C = np.cov(m.T)
    d = np.diff(m, axis=0) @ n
    noise2 = (1.4826 * float(np.median(np.abs(d - np.median(d))))) ** 2 / 2.0 if d.size else 0.0
    share = max(float(n @ C @ n) - noise2, 0.0) / max(float(np.trace(C)), 1e-300)
    return share, float(np.degrees(np.arcsin(min(np.sqrt(2 * share), 1.0))))


def _form_fit(p: NDArray[np.float64], form: str, est: dict[str, Any], method: str
              ) -> tuple[NDArray[np.float64], NDArray[np.float64], dict[str, float], float, str, str, str | None]:
    """One form's fit to ``p``: ``T₂``, ``c``, the standard errors, the worst as a share of H, method, solver, note."""
    if form == "circle":
        c, r, _ = _sphere_fit(p)
        d = p - c
        n = np.linalg.norm(d, axis=1)
        se = batch_means_stderr(np.column_stack([-d / (n * r)[:, None], -n / r ** 2]), n / r - 1.0)
        stderr = {"c_0": float(se[0]), "c_1": float(se[1]), "r": float(se[2])}
        return np.eye(2) / r, c, stderr, float(np.max(se) / r), "circle", "numpy least squares + Gauss-Newton", None
    T2, c = convex_ellipse(p, est.get("conic_solver"))
    solver, note, fitted = "cvxpy (convex ellipse)", None, "convex"
    if method in ("default", "mle"):
        try:
            T2r, cr, status = refine_ellipse(p, T2, c, est)
            H0, H = np.linalg.det(T2) ** -0.5, np.linalg.det(T2r) ** -0.5
            stretch = np.linalg.eigvalsh(T2r) * H
            mse0 = np.mean(_residuals(p, np.concatenate([_lower(T2), c]))[0] ** 2)
            mse = np.mean(_residuals(p, np.concatenate([_lower(T2r), cr]))[0] ** 2)
            if not H0 / FIELD_FACTOR <= H <= FIELD_FACTOR * H0:
                note = f"its field {H:.4g} is {H / H0:.3g} times the convex fit's (beyond {FIELD_FACTOR:g})"
            elif stretch.max() > AXIS_STRETCH or stretch.min() < 1 / AXIS_STRETCH:
                note = f"it stretches an axis by {max(stretch.max(), 1 / stretch.min()):.3g} (a soft iron: at most {AXIS_STRETCH:g})"
            elif mse > mse0:
                note = f"its rms {np.sqrt(mse):.6g} is above the convex fit's {np.sqrt(mse0):.6g}"
            else:
                T2, c, solver, fitted = T2r, cr, f"CasADi nlpsol, {status}", "mle"
        except SolverError as exc:
            note = f"it failed ({exc})"
        if note is not None:
            note = f"the ellipse's maximum-likelihood refinement is not kept: {note}; the convex fit is (--method convex gives it)"
    x = np.concatenate([_lower(T2), c])
    res, J = _residuals(p, x)
    se = batch_means_stderr(J, res)
    H = float(np.linalg.det(T2) ** -0.5)
    stderr = dict(zip(("T_00", "T_10", "T_11", "c_0", "c_1"), map(float, se)))
    shares = [v * H for v in se[:3]] + [v / H for v in se[3:]]  # T₂ is 1/field per unit; c is in the field's units
    return T2, c, stderr, float(max(shares)), fitted, solver, note


def fit_planar(m: NDArray[np.float64], form: str = "auto", est: dict[str, Any] | None = None, method: str = "default",
               accept_fit: bool = False, allow_degenerate: bool = False) -> PlanarFit:
    """The planar calibration of raw samples ``m`` (n, 3) (module docstring); ``form`` ``auto`` (held out),
    ``circle`` or ``ellipse``.

    Raises
    ------
    InputError
        A method other than default, mle or convex, too few samples, one heading only, or samples that are no field in the plane (``accept_fit`` keeps them).
    """
    est = dict(est or {})
    if method not in ("default", "mle", "convex"):
        raise InputError(f"--method {method} fits a 3-D ellipsoid; a planar calibration takes --method default, mle "
                         f"(the convex ellipse refined by maximum likelihood) or convex")
    need = PLANAR_FORMS["ellipse"] + 1
    if len(m) < need:
        raise InputError(f"{len(m)} magnetometer samples: the planar form needs at least {need}; record the sensor "
                         f"turning through a full circle")
    tilt, n = planar_evidence(m)
    n = n * np.sign(n[np.argmax(np.abs(n))])
    P = plane_basis(n)
    p = m @ P.T
    spread = float(np.sqrt(np.max(np.linalg.eigvalsh(np.cov(p.T)))))
    size = float(np.median(np.linalg.norm(m, axis=1)))
    if spread < ONE_ORIENTATION_SHARE * max(size, 1e-300):
        raise InputError(f"the magnetometer samples hold one heading only (they spread by {spread:.3g}, "
                         f"{100 * spread / max(size, 1e-300):.2g} % of |m| = {size:.4g}); turn the sensor through a full "
                         f"circle in its plane; --allow-degenerate with --mag-form offsets fits anyway")
    heldout = heldout_planar(p) if form == "auto" else None
    if heldout is not None and len(heldout.cells) < MIN_HELDOUT_CELLS:
        heldout = None
    fits = {f: _form_fit(p, f, est, method) for f in (PLANAR_FORMS if form == "auto" else (form,))}
    usable = [f for f in fits if fits[f][3] < USABLE_SHARE]
    if form != "auto":
        chosen, reason = form, f"given with --mag-form planar-{form}"
    elif heldout is not None and usable:
        # the richer form is kept unless it predicts the left-out headings worse by more than the paired difference's
        # standard error (the 3-D forms' rule, heldout_rule.richest_within_se: a soft iron is always present)
        chosen = str(richest_within_se(heldout, list(PLANAR_FORMS), lambda f: f in usable)[0])
        gain, se = heldout.gain("circle", "ellipse")
        worse = -gain
        reason = (f"held out by heading ({len(heldout.cells)} of {HEADING_SECTORS} {360 // HEADING_SECTORS}° sectors left "
                  f"out in turn, {heldout.n_samples} samples): rms circle {100 * heldout.rms('circle'):.3g} %, ellipse "
                  f"{100 * heldout.rms('ellipse'):.3g} %; the ellipse's mean-square excess over the circle {worse:.2g} ± {se:.2g}: "
                  + ("the ellipse, within its standard error" if chosen == "ellipse" else
                     "the circle (the ellipse predicts the left-out headings worse, or is not determined)"))
    else:
        chosen = "ellipse" if fits["ellipse"][3] < RELEVANT_SHARE else "circle"
        reason = (f"too few heading sectors to compare held out (at least {MIN_HELDOUT_CELLS}); parameters determined "
                  f"to " + ", ".join(f"{f} {100 * fits[f][3]:.2g} %" for f in fits) + " of H")
    T2, c, stderr, worst, fitted, solver, note = fits[chosen]
    if worst >= USABLE_SHARE:
        if not allow_degenerate:
            # the 3-D forms' rule (fit.USABLE_SHARE): a parameter uncertain by a tenth of the field is about 6° of heading
            raise IdentifiabilityError(
                f"the samples determine the planar {chosen}'s parameters only to {100 * worst:.2g} % of the field in the "
                f"plane (a form is usable below {100 * USABLE_SHARE:g} %, about 6° of heading); turn the sensor through a "
                f"full circle in one plane; --allow-degenerate keeps the fit")
        reason += f" (determined only to {100 * worst:.2g} % of H, kept with --allow-degenerate)"
    r = _residuals(p, np.concatenate([_lower(T2), c]))[0]
    rms = float(np.sqrt(np.mean(r ** 2)))
    if rms > NOT_A_FIELD_RMS and not accept_fit:
        raise InputError(f"the samples are not a magnetic field in their plane: they leave the fitted {chosen} by "
                         f"{100 * rms:.3g} % rms (a field with hard and soft iron: a few %); check that --columns maps "
                         f"mx, my, mz to the magnetometer; --accept-mag-fit keeps it")
    sectors = tuple(int(s) for s in np.unique(heading_sectors(p, c)))
    tilt_deg = float(np.degrees(np.sqrt(2 * tilt)))  # a tilt θ rms about the plane leaves θ²/2 of the spread
    return PlanarFit(n, P, chosen, T2, c, r, stderr, worst, tilt, tilt_deg, sectors, fitted, solver, reason, heldout, note)


def planar_decision(tilt: float, normal: NDArray[np.float64]) -> str:
    """The line that says why a recording gets the planar form (its evidence and the override)."""
    if tilt >= PLANAR_SPREAD:
        return (f"given with --mag-form although the samples tilt out of their plane (along "
                f"[{', '.join(f'{v:+.2f}' for v in normal)}]) by {100 * tilt:.2g} % of their spread, "
                f"{np.degrees(np.sqrt(2 * tilt)):.2g}° rms (a planar turn: below {100 * PLANAR_SPREAD:g} %): the heading "
                f"calibration holds in that plane only")
    return (f"the samples turn in one plane (their tilt out of it, along [{', '.join(f'{v:+.2f}' for v in normal)}], less "
            f"the noise, is {100 * tilt:.2g} % of their spread, a tilt of {np.degrees(np.sqrt(2 * tilt)):.2g}° rms; below "
            f"{100 * PLANAR_SPREAD:g} %, a 3-D form's field and normal hard iron are not determined): a heading calibration "
            f"in that plane")
