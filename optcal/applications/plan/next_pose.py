"""The next best pose: the one orientation that adds the most information to the poses taken.

For poses with information ``M₀`` (normalised units, unit noise; :mod:`optcal.applications.plan.information`)
a new pose in direction ``d`` raises ``log det`` by ``log(1 + h(d)ᵀ M₀⁻¹ h(d))`` (the matrix
determinant lemma).  The maximum is searched on the candidate grid and refined on the sphere
(IPOPT, :func:`optcal.applications.plan.rounding.refine` with one pose).  While ``M₀`` is singular (fewer
poses than parameters, or a degenerate set), the pose that fills an undetermined combination
comes first, and the gain is reported as infinite with the rank before and after.

This is the step of a guided capture loop::

    poses = []
    while True:
        step = next_pose(np.array(poses).reshape(-1, 3), sigma=1e-3, target_stderr=1e-3)
        if step.stop:
            break
        poses.append(capture(step.description))
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.model import PARAM_NAMES
from optcal.applications.plan.candidates import CandidateSet
from optcal.applications.plan.describe import describe_direction
from optcal.applications.plan.information import Criterion, Prior, covariance, criterion_value, information, named
from optcal.applications.plan.planner import resolve_inputs
from optcal.applications.plan.rounding import refine, sequential
from optcal.core.poses import PoseTable


@dataclass
class NextPose:
    """The recommended next pose and what it is expected to bring.

    Attributes
    ----------
    direction : ndarray, shape (3,)
        Gravity direction of the pose in the sensor frame.
    description : str
        How to hold the device.
    label : str
        Turntable gimbal angles (empty unless planned on a turntable).
    gain_logdet : float
        Increase of log det of the information (inf when the pose determines a new combination).
    rank_before, rank_after : int
        Rank of the information before and after the pose.
    stderr_before, stderr_after : dict of str to float
        Standard error of each parameter of θ (prior units) with the poses taken and with the
        new pose added (inf where undetermined).
    stderr_normalised : dict of str to float
        ``stderr_before`` in normalised units (T relative to 1, o in g), compared to the target.
    target_stderr : float or None
        The target in normalised units.
    stop : bool
        Every standard error is already below the target.
    n_poses, sigma, units, prior_source : for the report.
    """

    direction: NDArray[np.float64]
    description: str
    label: str
    gain_logdet: float
    rank_before: int
    rank_after: int
    stderr_before: dict[str, float]
    stderr_after: dict[str, float]
    stderr_normalised: dict[str, float]
    target_stderr: float | None
    stop: bool
    n_poses: int
    sigma: float
    units: str
    prior_source: str
    given_directions: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def stop_message(self) -> str:
        """``"stop: every standard error is below X"`` once the target is met, else empty."""
        return f"stop: every standard error is below {self.target_stderr:g}" if self.stop else ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (an infinite gain or standard error becomes null)."""
        return {
            "direction": self.direction.tolist(),
            "description": self.description,
            **({"turntable": self.label} if self.label else {}),
            "gain_logdet": self.gain_logdet,
            "rank_before": self.rank_before,
            "rank_after": self.rank_after,
            "stderr_before": self.stderr_before,
            "stderr_after": self.stderr_after,
            "stderr_normalised": self.stderr_normalised,
            "target_stderr": self.target_stderr,
            "stop": self.stop,
            "message": self.stop_message,
            "n_poses": self.n_poses,
            "sigma": self.sigma,
            "units": self.units,
            "prior": self.prior_source,
        }

    def report(self) -> str:
        """Readable recommendation."""
        gain = (f"{self.gain_logdet:.4g}" if math.isfinite(self.gain_logdet)
                else f"∞ (rank {self.rank_before} → {self.rank_after} of {len(PARAM_NAMES)})")
        lines = [
            f"after {self.n_poses} poses (prior: {self.prior_source}; pose noise {self.sigma:g} {self.units})",
            f"next pose: {self.description}  "
            f"(gravity direction {self.direction[0]:+.4f} {self.direction[1]:+.4f} {self.direction[2]:+.4f})"
            + (f"  [{self.label}]" if self.label else ""),
            f"expected gain in log det of the information: {gain}",
            f"{'':5} {'stderr now':>12} {'after':>12}",
        ]
        for p in PARAM_NAMES:
            lines.append(f"{p:<5} {self.stderr_before[p]:12.4g} {self.stderr_after[p]:12.4g}")
        if self.stop:
            lines.append(self.stop_message)
        elif self.target_stderr is not None:
            worst = max(self.stderr_normalised, key=lambda k: self.stderr_normalised[k])
            lines.append(f"continue: {worst} has standard error {self.stderr_normalised[worst]:.3g} "
                         f"(normalised) above the target {self.target_stderr:g}")
        return "\n".join(lines)


def next_pose(
    poses: PoseTable | ArrayLike,
    *,
    prior: Prior | None = None,
    sigma: float | None = None,
    candidates: CandidateSet | None = None,
    target_stderr: float | None = None,
    solver: str | None = None,
    solver_options: dict[str, Any] | None = None,
) -> NextPose:
    """The single orientation that adds the most information (D criterion) to ``poses``.

    Parameters
    ----------
    poses : PoseTable or array_like, shape (n, 3)
        The poses taken so far (pose means in the prior's units; n may be 0).
    prior : Prior, optional
        The sensor (nominal ``T = I``, ``o = 0`` in g when omitted).
    sigma : float, optional
        Pose noise per axis in the prior's units (the table's own noise is used for its poses
        when it has one); 1 mg when omitted.
    candidates : CandidateSet, optional
        Feasible directions (free orientations when omitted).
    target_stderr : float, optional
        Stop once every standard error is below this, in normalised units (T relative to 1, o in
        g).
    solver, solver_options : str and dict, optional
        The NLP solver of the refinement on the sphere (a CasADi ``nlpsol`` plugin, IPOPT by default)
        and its options.

    Returns
    -------
    NextPose
    """
    from optcal.errors import InputError

    if target_stderr is not None and not (np.isfinite(target_stderr) and target_stderr > 0):
        raise InputError(f"target_stderr must be positive, not {target_stderr}")
    if not isinstance(poses, PoseTable):
        poses = np.asarray(poses, float).reshape(-1, 3)
    prior, sigma, candidates, given = resolve_inputs(prior, sigma, candidates, poses)
    M0 = given.information
    H = prior.information_vectors(candidates.directions)
    index = int(sequential(H, 1, Criterion.D, M0)[0])
    direction = candidates.directions[index]
    full_before = np.isfinite(criterion_value(M0, Criterion.D))
    if candidates.continuous and full_before:
        direction = refine(prior.information_vectors, direction[None, :], Criterion.D, M0, candidates.cap,
                           ipopt_options=solver_options, solver=solver)[0][0]
    M1 = information(prior.information_vectors(direction), base=M0)
    rank = [int(np.linalg.matrix_rank(M, tol=1e-10 * max(np.abs(M).max(), 1e-300))) for M in (M0, M1)]
    gain = criterion_value(M1, Criterion.D) - criterion_value(M0, Criterion.D) if full_before else math.inf
    normalised = np.sqrt(np.diag(covariance(M0, sigma)))
    stop = target_stderr is not None and bool(np.all(normalised < target_stderr))
    return NextPose(
        direction=direction,
        description=describe_direction(direction),
        label=candidates.labels[index] if candidates.labels and not candidates.continuous else "",
        gain_logdet=float(gain),
        rank_before=rank[0],
        rank_after=rank[1],
        stderr_before=named(prior.stderr_raw(M0, sigma)),
        stderr_after=named(prior.stderr_raw(M1, sigma)),
        stderr_normalised=named(normalised),
        target_stderr=target_stderr,
        stop=stop,
        n_poses=given.n,
        sigma=sigma,
        units=prior.units,
        prior_source=prior.source,
        given_directions=given.directions,
    )


__all__ = ["NextPose", "next_pose"]
