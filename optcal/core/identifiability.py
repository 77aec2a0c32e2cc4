"""Fisher information, identifiability and the Cramér–Rao bound of a pose set.

For static poses ``a_k = C ā_k + o + n_k`` with ``n_k ~ N(0, σ_k² I)`` and unknown unit
directions ``ā_k`` (nuisance parameters), eliminating the directions from the Fisher
information (Schur complement over the two tangent directions of each ``ā_k``) leaves, per
pose, only the component of the noise along the ellipsoid normal ``Tᵀ ā_k``::

    F = Σ_k  g_k g_kᵀ / (σ_k² ‖Tᵀ ā_k‖²),      g_k = ∂ r_k / ∂θ,   r_k = ‖T(a_k − o)‖ − 1

which is the Gauss–Newton matrix of the norm-residual cost (Lu 2017, eq. 14) with the noise
propagated to the norm.  ``F⁻¹`` is the Cramér–Rao bound of θ; a rank-deficient ``F`` means
that some combination of the parameters is not determined by the pose set.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.model import LumpedModel
from optcal.core.norm_residual import NormResidualKernel
from optcal.core.fit_result import A_INDEX, dA_dtheta

#: Relative eigenvalue of the scaled Fisher matrix below which a direction counts as unidentified.
RANK_TOL: float = 1e-9
#: Fisher information of one parameter (its diagonal entry), relative to the largest, below which no
#: pose carries information on that parameter: it is undetermined on its own, whatever the others do.
#: Scaling such a column to correlation form would blow its rounding noise up to unit size and mix it
#: into the genuine null combinations of the other parameters.
UNEXCITED_TOL: float = 1e-13
#: Standard error (normalised units: T relative to 1, o relative to the 1 g radius) above which a
#: parameter combination counts as not determined by the data, however full the rank: 5 % of
#: full scale.  With noise, an exactly degenerate design is no longer numerically singular
#: (the fitted directions leave the degenerate set by the noise), but the standard error
#: along the missing direction stays of order one whatever the noise level.
WEAK_STDERR: float = 0.05


def fisher_information(
    T: NDArray, o: NDArray, acc: NDArray, sigma: ArrayLike | None = None, jacobian: NDArray | None = None
) -> NDArray[np.float64]:
    """Fisher information of θ with the directions eliminated (module docstring).

    ``sigma`` is the raw per-axis noise of each pose (scalar or (n,)); ``None`` means 1.
    ``jacobian`` is :func:`optcal.core.norm_residual.norm_residual_jacobian` at (T, o) when the
    caller already has it.
    """
    point = NormResidualKernel(acc).at(T, o)
    J = point.jacobian().T if jacobian is None else jacobian
    s = np.ones(len(acc)) if sigma is None else np.broadcast_to(np.asarray(sigma, float), (len(acc),))
    w = 1.0 / (s * point.normal_gain()) ** 2
    return J.T @ (J * w[:, None])


def cramer_rao_bound(model: LumpedModel, directions: ArrayLike, sigma: float | ArrayLike) -> NDArray[np.float64]:
    """Cramér–Rao bound on the covariance of θ for a design of true directions.

    Parameters
    ----------
    model : LumpedModel
        The true sensor.
    directions : array_like, shape (n, 3)
        True unit directions of the poses.
    sigma : float or array_like
        Per-axis white noise of each pose measurement, raw units.

    Returns
    -------
    ndarray, shape (9, 9)
        ``F⁻¹`` with the unknown directions as nuisance parameters (pseudo-inverse when
        ``F`` is singular, in which case the bound is infinite along the null space).
    """
    d = np.asarray(directions, float)
    T = model.T_canonical
    acc = model.measure(d)
    F = fisher_information(T, model.o, acc, sigma)
    return np.linalg.pinv(F, rcond=1e-14, hermitian=True)


@dataclass
class IdentifiabilityReport:
    """Rank and conditioning of the Fisher information of a pose set.

    Attributes
    ----------
    rank : int
        Numerical rank of the scaled Fisher matrix (out of ``n_params``).
    n_params : int
    condition_number : float
        Ratio of the extreme eigenvalues of the scaled (correlation-form) Fisher matrix.
    unidentified : list of dict
        One entry per null direction: ``entry`` (the entry of A or o it moves),
        ``combination`` (change of each entry of A and o), ``text`` (readable).
    weak : list of dict
        With full rank, the combinations determined only weakly (standard error above
        :data:`WEAK_STDERR`): as ``unidentified``, plus ``stderr`` (fraction of full scale).
    """

    rank: int
    n_params: int
    condition_number: float
    eigenvalues: list[float] = field(default_factory=list)
    unidentified: list[dict[str, Any]] = field(default_factory=list)
    weak: list[dict[str, Any]] = field(default_factory=list)

    @property
    def identifiable(self) -> bool:
        return self.rank == self.n_params and not self.weak

    def describe(self) -> str:
        if self.identifiable:
            return (
                f"all {self.n_params} parameters identifiable (Fisher condition number "
                f"{self.condition_number:.3g})"
            )
        if self.rank < self.n_params:
            parts = "; ".join(u["text"] for u in self.unidentified)
            return (
                f"the pose set identifies only {self.rank} of {self.n_params} parameter combinations; "
                f"not determined: {parts}"
            )
        parts = "; ".join(f"{u['text']} weakly determined (standard error {u['stderr']:.2g} of full scale)"
                          for u in self.weak)
        return (
            f"the pose set determines {len(self.weak)} parameter combination(s) only weakly (Fisher rank "
            f"{self.rank}/{self.n_params}, but a standard error above {WEAK_STDERR:.0%} of full scale): {parts}"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "rank": self.rank,
            "n_params": self.n_params,
            "identifiable": self.identifiable,
            "condition_number": self.condition_number,
            "unidentified": self.unidentified,
            "weak": self.weak,
            "description": self.describe(),
        }


def _describe_null_space(vectors: NDArray, T: NDArray, alone: NDArray | None = None) -> list[dict[str, Any]]:
    """Express null directions of θ as changes of the entries of A and o.

    The basis is rotated so that each direction moves one entry of (A, o) by 1 and the other
    pivot entries by 0, which makes it readable ("A_xy is not determined").  ``alone`` (bool,
    shape (9,)) marks the parameters of θ that no pose excites (:func:`scaled_information`):
    they are described first, apart from ``vectors`` (zero on them), the null combinations of
    the other parameters, so that the two never mix.
    """
    out: list[dict[str, Any]] = []
    if alone is not None and np.any(alone):
        unit = np.eye(len(alone))[:, np.flatnonzero(alone)]
        out += [{**item, "text": item["text"] + ": no pose carries information on it"}
                for item in _describe_directions(unit, T)]
    return out + _describe_directions(vectors, T)


def _describe_directions(vectors: NDArray, T: NDArray) -> list[dict[str, Any]]:
    """Changes of θ (columns of ``vectors``) as unit changes of pivot entries of (A, o)."""
    axes = "xyz"
    names = [f"A_{axes[i]}{axes[j]}" for i, j in A_INDEX] + ["o_x", "o_y", "o_z"]
    k = vectors.shape[1]
    if k == 0:
        return []
    M = np.vstack([dA_dtheta(T) @ vectors[:6], vectors[6:9]])  # (9, k) change of (A, o)
    import scipy.linalg  # only for a degenerate pose set: keeps scipy out of every fit's start-up

    _, _, piv = scipy.linalg.qr(M.T, pivoting=True)
    pivots = piv[:k]
    B = M @ np.linalg.inv(M[pivots, :])  # each column: unit change of one pivot entry
    out = []
    for c in range(k):
        col = B[:, c]
        combo = {names[i]: float(col[i]) for i in np.flatnonzero(np.abs(col) > 1e-3)}
        lead = names[pivots[c]]
        others = [f"{v:+.3g}·{n}" for n, v in combo.items() if n != lead]
        text = lead + (f" (together with {' '.join(others)})" if others else "")
        out.append({"entry": lead, "combination": combo, "text": text})
    return out


def parameter_full_scale(theta: NDArray) -> NDArray[np.float64]:
    """Full scale of each entry of θ (shape (..., 9)): the largest diagonal entry of T for T, 1 g (1/min diag T) for o.

    The yardstick of "equal to the solver tolerance" and of "no information": relative to each
    value, an off-diagonal entry near zero would make any difference look large.
    """
    diag = np.abs(np.asarray(theta, dtype=float)[..., [0, 2, 5]])
    top = np.max(diag, axis=-1, keepdims=True)
    bottom = np.min(diag, axis=-1, keepdims=True)
    return np.concatenate([np.repeat(top, 6, axis=-1), np.repeat(1.0 / bottom, 3, axis=-1)], axis=-1)


def scaled_information(
    information: NDArray, full_scale: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Correlation form of Fisher information matrices, with the unexcited parameters set apart.

    Parameters
    ----------
    information : ndarray, shape (..., p, p)
        One Fisher information matrix or a stack of them.
    full_scale : ndarray, shape (..., p)
        Each parameter's full scale (:func:`parameter_full_scale`): the information is compared
        across parameters in these units, so that an offset in counts and a scale factor in
        g/count are judged alike.

    Returns
    -------
    scaled : ndarray, shape (..., p, p)
        ``F_ij / (d_i d_j)`` with ``d = sqrt(diag F)`` (unit diagonal), so that rank and
        condition number do not depend on units; the rows and columns of the unexcited
        parameters are zero.
    d : ndarray, shape (..., p)
        The scale ``sqrt(diag F)`` (1 for the unexcited parameters).
    unexcited : ndarray of bool, shape (..., p)
        Parameters whose information in full-scale units is below :data:`UNEXCITED_TOL` times the
        largest: undetermined each on its own.
    """
    diag = np.diagonal(information, axis1=-2, axis2=-1)
    relative = diag * np.asarray(full_scale, dtype=float) ** 2
    top = np.maximum(np.max(relative, axis=-1, keepdims=True), 1e-300)
    unexcited = relative <= UNEXCITED_TOL * top
    d = np.sqrt(np.where(unexcited, 1.0, diag))
    scaled = information / (d[..., :, None] * d[..., None, :])
    scaled = np.where(unexcited[..., :, None] | unexcited[..., None, :], 0.0, scaled)
    return scaled, d, unexcited


def numerical_rank(eigenvalues: NDArray, tol: float = RANK_TOL) -> NDArray[np.int_]:
    """Rank from the ascending eigenvalues of :func:`scaled_information`'s matrices (..., p).

    Eigenvalues below ``tol`` times the largest count as zero; the unexcited parameters' rows
    are zero, so each of them takes one from the rank.
    """
    top = np.maximum(eigenvalues[..., -1:], 1e-300)
    return np.sum(eigenvalues >= tol * top, axis=-1)


def analyse(
    T: NDArray,
    o: NDArray,
    acc: NDArray,
    sigma: ArrayLike | None = None,
    tol: float = RANK_TOL,
    jacobian: NDArray | None = None,
    information: NDArray | None = None,
) -> IdentifiabilityReport:
    """Identifiability of θ at (T, o) for measurements ``acc``.

    The Fisher matrix is scaled to correlation form (unit diagonal) so that rank and
    condition number do not depend on units (:func:`scaled_information`); a parameter no pose
    excites is named alone, and the null combinations are those of the other parameters.  ``jacobian``: see :func:`fisher_information`;
    ``information``: :func:`fisher_information` itself, when the caller already has it (then
    ``acc``, ``sigma`` and ``jacobian`` are not read).
    """
    F = fisher_information(T, o, acc, sigma, jacobian) if information is None else information
    theta_diag = np.diag(np.asarray(T, dtype=float))
    full_scale = parameter_full_scale(np.array([theta_diag[0], 0, theta_diag[1], 0, 0, theta_diag[2], 0, 0, 0]))
    S, d, unexcited = scaled_information(F, full_scale)
    evals = np.linalg.eigvalsh(S)
    rank = int(numerical_rank(evals, tol))
    top = max(evals[-1], 1e-300)
    unid: list[dict[str, Any]] = []
    if rank < len(evals):
        excited = np.flatnonzero(~unexcited)
        sub_evals, sub_evecs = np.linalg.eigh(S[np.ix_(excited, excited)])
        null = sub_evals < tol * top  # the combinations of the excited parameters (same test as the rank)
        vectors = np.zeros((len(evals), int(np.sum(null))))
        vectors[excited] = sub_evecs[:, null] / d[excited, None]
        unid = _describe_null_space(vectors, T, unexcited)
    cond = float(top / evals[0]) if evals[0] > 0 else float("inf")
    return IdentifiabilityReport(
        rank=rank,
        n_params=len(evals),
        condition_number=cond,
        eigenvalues=[float(e / top) for e in evals],
        unidentified=unid,
    )


def add_weak_directions(report: IdentifiabilityReport, cov_normalised: NDArray, T_normalised: NDArray,
                        threshold: float = WEAK_STDERR,
                        eigen: tuple[NDArray, NDArray] | None = None) -> IdentifiabilityReport:
    """Record in ``report`` the combinations whose standard error exceeds ``threshold``.

    ``cov_normalised`` is the covariance of θ in the normalised coordinates of
    :class:`optcal.families.accel.base.Normaliser` (T ≈ rotation, o in units of the radius);
    ``eigen`` its eigenvalues and eigenvectors when the caller has them (from
    :func:`pseudo_inverse`), so that they are not computed again.
    """
    evals, evecs = np.linalg.eigh(0.5 * (cov_normalised + cov_normalised.T)) if eigen is None else eigen
    big = evals > threshold**2
    if np.any(big):
        described = _describe_null_space(evecs[:, big], T_normalised)
        for item, lam in zip(described, evals[big]):
            item["stderr"] = float(np.sqrt(lam))
        report.weak = described
    return report


def pseudo_inverse(information: NDArray, rcond: float = 1e-12) -> tuple[NDArray[np.float64], NDArray, NDArray]:
    """``F⁺`` of a symmetric information matrix, with its eigenvalues and eigenvectors.

    The pseudo-inverse of :func:`numpy.linalg.pinv` with ``hermitian=True`` (eigenvalues below
    ``rcond`` times the largest in magnitude count as zero), from one eigendecomposition; the
    eigenvalues of ``F⁺`` (``1/λ`` or 0) and ``F``'s eigenvectors are returned for
    :func:`add_weak_directions`.  Works on a stack of matrices (..., p, p).
    """
    lam, V = np.linalg.eigh(information)
    cutoff = rcond * np.max(np.abs(lam), axis=-1, keepdims=True)
    inv = np.where(np.abs(lam) > cutoff, 1.0 / np.where(lam == 0, 1.0, lam), 0.0)
    return (V * inv[..., None, :]) @ np.swapaxes(V, -1, -2), inv, V


def analyse_design(model: LumpedModel, directions: ArrayLike, tol: float = RANK_TOL) -> IdentifiabilityReport:
    """Identifiability of a noise-free design (true model and true directions)."""
    d = np.asarray(directions, float)
    return analyse(model.T_canonical, model.o, model.measure(d), None, tol)


__all__ = [
    "IdentifiabilityReport",
    "analyse",
    "analyse_design",
    "cramer_rao_bound",
    "fisher_information",
    "numerical_rank",
    "parameter_full_scale",
    "pseudo_inverse",
    "scaled_information",
]
