"""Fisher information, identifiability and the Cramér–Rao bound of a pose set.

For static poses ``a_k = C ā_k + o + n_k`` with ``n_k ~ N(0, σ_k² I)`` and unknown unit
directions ``ā_k`` (nuisance parameters), eliminating the directions from the Fisher
information (Schur complement over the two tangent directions of each ``ā_k``) leaves, per
pose, only the component of the noise along the ellipsoid normal ``Tᵀ ā_k``::

    F = Σ_k  g_k g_kᵀ / (σ_k² ‖Tᵀ ā_k‖²),      g_k = ∂ r_k / ∂θ,   r_k = ‖T(a_k − o)‖ − 1

which is the Gauss–Newton matrix of the norm-residual cost (Lu 2017, eq. 14) with the noise
propagated to the norm.  ``F⁻¹`` is the Cramér–Rao bound of θ; a rank-deficient ``F`` means
that some combination of the parameters is not determined by the pose set.

:func:`rank_report` is the one rank test of an information matrix (correlation form, unexcited
parameters set apart) for both sensors: the accelerometer's Fisher information here
(:func:`analyse`) and the gyroscope's Gauss–Newton matrix
(:func:`optcal.families.gyro.identifiability.fisher_rank`).  Its :class:`RankReport` is the typed
identifiability record of every fit result (:class:`optcal.core.fit_result.FitRecord`);
:class:`IdentifiabilityReport` adds the accelerometer's named combinations.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.model import TRIL_INDEX, LumpedModel
from optcal.core.norm_residual import NormResidualKernel

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
#: The six unique entries of the symmetric ``A = TᵀT`` (Lu 2017, eq. 19): upper triangle, row-major.
A_INDEX: tuple[tuple[int, int], ...] = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def dA_dT_entry(T: NDArray[np.float64], i: int, j: int) -> NDArray[np.float64]:
    """Change of the unique entries of ``A = TᵀT`` (:data:`A_INDEX` order) per unit change of ``T[i, j]``.

    ``dA = EᵀT + TᵀE`` with ``E`` the unit matrix of entry ``(i, j)``; shape (6,).
    """
    E = np.zeros((3, 3))
    E[i, j] = 1.0
    dA = E.T @ T + T.T @ E
    return np.array([dA[a, b] for a, b in A_INDEX])


def dA_dtheta(T: NDArray[np.float64]) -> NDArray[np.float64]:
    """Jacobian of the 6 unique entries of ``A = TᵀT`` w.r.t. the 6 entries of lower-triangular T.

    Rows follow :data:`A_INDEX` (upper triangle of A, row-major); columns follow
    :data:`optcal.core.model.TRIL_INDEX`.
    """
    return np.column_stack([dA_dT_entry(T, i, j) for i, j in TRIL_INDEX])


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
    return np.linalg.pinv(F, rcond=1e-14, hermitian=True)  # type: ignore[return-value]  # numpy stubs type pinv of float64 as floating[Any]


@dataclass
class RankReport:
    """Rank and conditioning of an information matrix (:func:`rank_report`).

    Attributes
    ----------
    rank : int
        Numerical rank of the correlation-form matrix (out of ``n_params``).
    n_params : int
    condition_number : float
        Ratio of the extreme eigenvalues of the correlation-form matrix (``inf`` when singular).
    eigenvalues : list of float
        Its eigenvalues, ascending, relative to the largest (not written to files).
    """

    rank: int
    n_params: int
    condition_number: float
    eigenvalues: list[float] = field(default_factory=list)

    @property
    def identifiable(self) -> bool:
        """Whether the matrix determines every parameter."""
        return self.rank == self.n_params

    def describe(self) -> str:
        """One sentence: the rank and the condition number."""
        return f"rank {self.rank} of {self.n_params} parameters (condition number {self.condition_number:.3g})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record: rank, number of parameters, condition number."""
        return {"rank": self.rank, "n_params": self.n_params, "condition_number": self.condition_number}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "RankReport":
        """Rebuild from :meth:`to_dict` (a condition number written as ``null`` was not finite: ``inf``)."""
        return cls(int(d["rank"]), int(d["n_params"]), _condition_number(d.get("condition_number")))


def _condition_number(value: Any) -> float:
    """A condition number read from JSON, where a non-finite one was written as ``null``."""
    return float("inf") if value is None else float(value)


@dataclass
class IdentifiabilityReport(RankReport):
    """Rank and conditioning of the Fisher information of a pose set, with what it does not determine.

    Attributes
    ----------
    rank, n_params, condition_number, eigenvalues
        See :class:`RankReport` (of the scaled Fisher matrix).
    unidentified : list of dict
        One entry per null direction: ``entry`` (the entry of A or o it moves),
        ``combination`` (change of each entry of A and o), ``text`` (readable).
    weak : list of dict
        With full rank, the combinations determined only weakly (standard error above
        :data:`WEAK_STDERR`): as ``unidentified``, plus ``stderr`` (fraction of full scale).
    """

    unidentified: list[dict[str, Any]] = field(default_factory=list)
    weak: list[dict[str, Any]] = field(default_factory=list)
    #: Parameters the user held (fixed, or a bound active at the optimum): counted as exactly
    #: measured, so what the poses must determine is the rest (:mod:`optcal.core.constraints`).
    constrained: list[str] = field(default_factory=list)

    @property
    def identifiable(self) -> bool:
        """Full rank and no weakly determined combination."""
        return self.rank == self.n_params and not self.weak

    def describe(self) -> str:
        """One sentence: what the pose set determines, and what it does not."""
        if self.identifiable and self.constrained:
            return (f"all {self.n_params} parameters identifiable with {', '.join(self.constrained)} held by the user "
                    f"(the poses determine the other {self.n_params - len(self.constrained)} directions)")
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
        """JSON-ready record (the eigenvalues are left out)."""
        return {
            "rank": self.rank,
            "n_params": self.n_params,
            "identifiable": self.identifiable,
            "condition_number": self.condition_number,
            "unidentified": self.unidentified,
            "weak": self.weak,
            "constrained": list(self.constrained),
            "description": self.describe(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "IdentifiabilityReport":
        """Rebuild from :meth:`to_dict` (``identifiable`` and ``description`` follow from the rest)."""
        return cls(
            rank=int(d["rank"]),
            n_params=int(d["n_params"]),
            condition_number=_condition_number(d.get("condition_number")),
            unidentified=[dict(u) for u in d.get("unidentified") or []],
            weak=[dict(u) for u in d.get("weak") or []],
            constrained=[str(c) for c in d.get("constrained") or []],
        )


@dataclass(frozen=True)
class NullSpace:
    """The parameter directions an information matrix does not determine (:func:`rank_report`).

    Attributes
    ----------
    unexcited : ndarray of bool, shape (p,)
        Parameters no observation carries information on (:func:`scaled_information`):
        undetermined each on its own.
    combinations : ndarray, shape (p, k)
        The null combinations of the other parameters, in correlation-form coordinates
        (unit vectors of the scaled matrix; zero on the unexcited parameters).
    scale : ndarray, shape (p,)
        ``sqrt(diag F)`` (1 for the unexcited parameters), the correlation form's scale.
    """

    unexcited: NDArray[np.bool_]
    combinations: NDArray[np.float64]
    scale: NDArray[np.float64]

    @property
    def combinations_in_parameter_units(self) -> NDArray[np.float64]:
        """:attr:`combinations` as changes of the parameters themselves, shape (p, k)."""
        return self.combinations / self.scale[:, None]


def rank_report(information: NDArray, full_scale: ArrayLike | None = None,
                tol: float = RANK_TOL) -> tuple[RankReport, NullSpace]:
    """Rank, conditioning and null space of an information matrix, independent of the parameters' units.

    The matrix is scaled to correlation form (unit diagonal, :func:`scaled_information`), so
    that rank and condition number do not depend on units; a parameter that no observation
    excites is set apart (named alone), and the null combinations are those of the other
    parameters.

    Parameters
    ----------
    information : ndarray, shape (p, p)
        Fisher information or Gauss–Newton matrix ``JᵀJ`` of the parameters.
    full_scale : array_like, shape (p,), optional
        Each parameter's full scale (:func:`parameter_full_scale`), the yardstick of "no
        information"; default 1 for every parameter.
    tol : float
        Relative eigenvalue below which a direction counts as not determined.

    Returns
    -------
    report : RankReport
    null_space : NullSpace
        Empty (``k = 0``, nothing unexcited) at full rank.
    """
    F = np.asarray(information, dtype=float)
    p = F.shape[0]
    scale_of = np.ones(p) if full_scale is None else np.asarray(full_scale, dtype=float)
    S, d, unexcited = scaled_information(F, scale_of)
    evals = np.linalg.eigvalsh(S)
    rank = int(numerical_rank(evals, tol))
    top = max(evals[-1], 1e-300)
    combinations = np.zeros((p, 0))
    if rank < p:
        excited = np.flatnonzero(~unexcited)
        sub_evals, sub_evecs = np.linalg.eigh(S[np.ix_(excited, excited)])
        null = sub_evals < tol * top  # the combinations of the excited parameters (same test as the rank)
        combinations = np.zeros((p, int(np.sum(null))))
        combinations[excited] = sub_evecs[:, null]
    cond = float(top / evals[0]) if evals[0] > 0 else float("inf")
    report = RankReport(rank=rank, n_params=p, condition_number=cond, eigenvalues=[float(e / top) for e in evals])
    return report, NullSpace(unexcited, combinations, d)


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
    # An entry takes part in a combination when it moves by more than 1e-3 of its full scale per full
    # scale of the pivot entry: A's entries against the largest diagonal of A (1 g per raw unit, squared),
    # o's against 1 g in raw units (1 / min diag T), so that the same pose set names the same entries
    # whether the data are in g, m/s^2 or counts.
    full_scale = np.r_[np.full(6, np.max(np.diag(T.T @ T))), np.full(3, 1.0 / np.min(np.abs(np.diag(T))))]
    out = []
    for c in range(k):
        col = B[:, c]
        relative = np.abs(col) * full_scale[pivots[c]] / full_scale  # (Δ entry / its scale) per (Δ pivot / its scale)
        combo = {names[i]: float(col[i]) for i in np.flatnonzero(relative > 1e-3)}
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

    The rank test is :func:`rank_report`: the Fisher matrix in correlation form (unit diagonal),
    so that rank and condition number do not depend on units; a parameter no pose excites is
    named alone, and the null combinations are those of the other parameters.  ``jacobian``: see :func:`fisher_information`;
    ``information``: :func:`fisher_information` itself, when the caller already has it (then
    ``acc``, ``sigma`` and ``jacobian`` are not read).
    """
    F = fisher_information(T, o, acc, sigma, jacobian) if information is None else information
    theta_diag = np.diag(np.asarray(T, dtype=float))
    full_scale = parameter_full_scale(np.array([theta_diag[0], 0, theta_diag[1], 0, 0, theta_diag[2], 0, 0, 0]))
    ranks, null = rank_report(F, full_scale, tol)
    unid: list[dict[str, Any]] = []
    if ranks.rank < ranks.n_params:
        unid = _describe_null_space(null.combinations_in_parameter_units, T, null.unexcited)
    return IdentifiabilityReport(
        rank=ranks.rank,
        n_params=ranks.n_params,
        condition_number=ranks.condition_number,
        eigenvalues=ranks.eigenvalues,
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
    "A_INDEX",
    "IdentifiabilityReport",
    "NullSpace",
    "RankReport",
    "analyse",
    "analyse_design",
    "cramer_rao_bound",
    "dA_dT_entry",
    "dA_dtheta",
    "fisher_information",
    "numerical_rank",
    "parameter_full_scale",
    "pseudo_inverse",
    "rank_report",
    "scaled_information",
]
