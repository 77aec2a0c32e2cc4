"""Which rotation axes a recording excites, and what a gyro calibration cannot determine.

The corrected rate ``ω = T_g w`` (``w = g − b_g``, the bias-free raw rate) enters the fit
only through the raw rates the recording actually produces.  If every move turns the
sensor about axes in one plane, all ``w`` lie in a plane of raw space with normal ``n``
and ``T_g n`` (three numbers: the scale and the two misalignments of rotations about that
axis) never matters: the fit cannot determine it.  :func:`excitation` measures this by the
eigenvalues of ``S = Σ_k w_k w_kᵀ dt_k`` (raw rates over every step of every move);
:func:`fisher_rank` checks the Gauss–Newton matrix of the fitted residuals as well
(rotations about gravity alone are invisible too), by the rank test the accelerometer uses
(:func:`optcal.core.identifiability.rank_report`).  Both speak the language of
:mod:`optcal.core.identifiability`: the combination that is not determined, by name.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.identifiability import RANK_TOL, RankReport, rank_report
from optcal.core.model import AXES

#: Smallest accepted ratio of the weakest to the strongest excitation eigenvalue: the rms
#: rate about the weakest axis must reach 3 % of that about the strongest.
MIN_EXCITATION_RATIO: float = 1e-3


@dataclass(frozen=True)
class Excitation:
    """Rotation excitation of a recording.

    Attributes
    ----------
    axes : ndarray, shape (3, 3)
        Rows: principal raw-rate directions, strongest first (unit vectors in raw space).
    rms_rate : ndarray, shape (3,)
        Rms raw rate about each principal direction over the moves, raw units.
    ratio : float
        Weakest over strongest eigenvalue of ``S``.
    """

    axes: NDArray[np.float64]
    rms_rate: NDArray[np.float64]
    ratio: float

    @property
    def sufficient(self) -> bool:
        return self.ratio >= MIN_EXCITATION_RATIO

    def weakest_axis_name(self) -> str:
        """The weakest raw direction as a readable vector, with the nearest gyro axis."""
        n = self.axes[2] * np.sign(self.axes[2][np.argmax(np.abs(self.axes[2]))])
        near = AXES[int(np.argmax(np.abs(n)))]
        return f"({n[0]:+.2f}, {n[1]:+.2f}, {n[2]:+.2f}), about the gyro's {near} axis"

    def describe(self) -> str:
        if self.sufficient:
            return (f"rotations excite all three axes (weakest/strongest rms rate "
                    f"{np.sqrt(self.ratio):.3g})")
        k = "xyz"[int(np.argmax(np.abs(self.axes[2])))]
        return (
            f"the moves rotate the sensor about two axes only (rms rate about the third, "
            f"{self.weakest_axis_name()}, is {np.sqrt(max(self.ratio, 0.0)):.2g} of the strongest); "
            f"not determined: T_g·n for that axis n, i.e. the scale and the two misalignments of the {k} gyro "
            f"(Tg_x{k}, Tg_y{k}, Tg_z{k})"
        )


def excitation(w: NDArray, dt: NDArray) -> Excitation:
    """Principal axes of the bias-free raw rates ``w`` (N, 3) weighted by the step lengths ``dt``."""
    S = (w * dt[:, None]).T @ w / max(float(np.sum(dt)), 1e-300)
    evals, evecs = np.linalg.eigh(0.5 * (S + S.T))
    order = np.argsort(evals)[::-1]
    evals = np.clip(evals[order], 0.0, None)
    return Excitation(evecs[:, order].T, np.sqrt(evals), float(evals[2] / evals[0]) if evals[0] > 0 else 0.0)


@dataclass
class GyroIdentifiability(RankReport):
    """Rank of the gyro fit's Gauss–Newton matrix and the excitation of the recording.

    Attributes
    ----------
    rank, n_params, condition_number, eigenvalues
        See :class:`~optcal.core.identifiability.RankReport` (of ``JᵀJ`` in correlation form).
    excitation_ratio : float
        :attr:`Excitation.ratio`: weakest over strongest excitation eigenvalue.
    excitation_rms_rate : ndarray, shape (3,)
        :attr:`Excitation.rms_rate`, raw units.
    unidentified : list of str
        Readable combinations not determined.
    description : str
        The whole verdict in words (:func:`describe_gyro`), kept as written: it names the weakest
        rotation axis, which the saved record does not hold.
    """

    excitation_ratio: float = 1.0
    excitation_rms_rate: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    unidentified: list[str] = field(default_factory=list)
    description: str = ""

    @property
    def identifiable(self) -> bool:
        """Full rank and rotations about three axes."""
        return self.rank == self.n_params and self.excitation_ratio >= MIN_EXCITATION_RATIO

    def describe(self) -> str:
        """The verdict in words (:attr:`description`)."""
        return self.description

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record."""
        return {
            "rank": self.rank,
            "n_params": self.n_params,
            "identifiable": self.identifiable,
            "condition_number": self.condition_number,
            "excitation_ratio": self.excitation_ratio,
            "excitation_rms_rate": self.excitation_rms_rate.tolist(),
            "unidentified": list(self.unidentified),
            "description": self.describe(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "GyroIdentifiability":
        """Rebuild from :meth:`to_dict`."""
        ranks = RankReport.from_dict(d)
        return cls(
            rank=ranks.rank,
            n_params=ranks.n_params,
            condition_number=ranks.condition_number,
            excitation_ratio=float(d["excitation_ratio"]),
            excitation_rms_rate=np.asarray(d["excitation_rms_rate"], dtype=float).reshape(3),
            unidentified=[str(u) for u in d.get("unidentified") or []],
            description=str(d.get("description", "")),
        )


def describe_gyro(ranks: RankReport, exc: Excitation, unidentified: list[str]) -> str:
    """The gyro verdict in words: identifiable, or what the recording does not determine."""
    if ranks.rank == ranks.n_params and exc.sufficient:
        return (f"all {ranks.n_params} gyro parameters identifiable (condition number "
                f"{ranks.condition_number:.3g}); {exc.describe()}")
    parts = ([] if exc.sufficient else [exc.describe()]) + unidentified
    return "the recording does not determine the gyro calibration: " + "; ".join(parts)


def gyro_identifiability(ranks: RankReport, exc: Excitation, unidentified: list[str]) -> GyroIdentifiability:
    """The gyro's record from a rank report, the recording's excitation and the named null combinations."""
    return GyroIdentifiability(
        rank=ranks.rank,
        n_params=ranks.n_params,
        condition_number=ranks.condition_number,
        eigenvalues=list(ranks.eigenvalues),
        excitation_ratio=exc.ratio,
        excitation_rms_rate=exc.rms_rate,
        unidentified=list(unidentified),
        description=describe_gyro(ranks, exc, unidentified),
    )


def fisher_rank(J: NDArray, names: list[str], exc: Excitation, tol: float = RANK_TOL) -> GyroIdentifiability:
    """Rank of ``JᵀJ`` in correlation form (:func:`~optcal.core.identifiability.rank_report`).

    A parameter no move excites is named alone; each null combination of the others by its
    largest entries (in correlation-form coordinates, scaled to a largest entry of 1).
    """
    ranks, null = rank_report(J.T @ J, None, tol)
    text = [names[k] for k in np.flatnonzero(null.unexcited)]
    for v in null.combinations.T:
        v = v / np.max(np.abs(v))
        text.append(" ".join(f"{c:+.2g}·{n}" for c, n in zip(v, names) if abs(c) > 0.05))
    return gyro_identifiability(ranks, exc, text)
