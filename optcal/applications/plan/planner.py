"""``plan_poses``: the K orientations that determine the calibration best.

Steps: the feasible set (:mod:`optcal.applications.plan.candidates`), the convex relaxation and its bound
(:mod:`optcal.applications.plan.relaxation`), rounding to K poses from several starts and refinement on the
sphere (:mod:`optcal.applications.plan.rounding`), the expected standard errors at the given pose noise.  A
request that cannot determine the nine parameters (too few poses, a feasible set that is
degenerate or too narrow) is refused with the combinations it leaves undetermined, named by
:mod:`optcal.core.identifiability`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import IdentifiabilityError, InputError
from optcal.core.identifiability import IdentifiabilityReport, add_weak_directions, analyse
from optcal.core.model import N_PARAMS, PARAM_NAMES
from optcal.applications.plan.candidates import CandidateSet, sphere_candidates
from optcal.applications.plan.describe import describe_directions
from optcal.applications.plan.information import (
    Criterion,
    Prior,
    covariance,
    criterion_value,
    efficiency,
    information,
    named,
)
from optcal.applications.plan.relaxation import Relaxation, relax
from optcal.applications.plan.rounding import apportion, exchange, refine, sequential
from optcal.core.poses import PoseTable

#: Pose noise assumed when none is given, g per axis (a pose mean of a consumer MEMS part).
DEFAULT_SIGMA: float = 1e-3


@dataclass(frozen=True)
class GivenPoses:
    """Poses already taken, as the planner sees them.

    Attributes
    ----------
    acc : ndarray, shape (n, 3)
        Measured pose means, in the prior's units.
    sigma : ndarray, shape (n,)
        Their noise (the table's, else the planning noise).
    information : ndarray, shape (9, 9)
        Their information at unit planning noise (normalised coordinates).
    directions : ndarray, shape (n, 3)
        Their gravity directions under the prior.
    """

    acc: NDArray[np.float64]
    sigma: NDArray[np.float64]
    information: NDArray[np.float64]
    directions: NDArray[np.float64]

    @property
    def n(self) -> int:
        return len(self.acc)

    @classmethod
    def of(cls, poses: PoseTable | ArrayLike | None, prior: Prior, sigma: float) -> "GivenPoses":
        """Read ``poses`` (a pose table, or pose means (n, 3) in the prior's units)."""
        if poses is None:
            return cls(np.zeros((0, 3)), np.zeros(0), np.zeros((N_PARAMS, N_PARAMS)), np.zeros((0, 3)))
        if isinstance(poses, PoseTable):
            if poses.units != prior.units:
                raise InputError(
                    f"the poses are in {poses.units} but the prior calibration is in {prior.units}; "
                    "give a prior in the units of the data"
                )
            acc = poses.acc
            s = poses.sigma if poses.sigma is not None else np.full(poses.n, sigma)
        else:
            acc = np.asarray(poses, float)
            if acc.ndim != 2 or acc.shape[1] != 3 or not np.all(np.isfinite(acc)):
                raise InputError(f"poses must be a PoseTable or finite pose means of shape (n, 3), not shape {acc.shape}")
            s = np.full(len(acc), sigma)
        H = prior.measurement_vectors(acc)
        corrected = prior.model.correct(acc)
        return cls(acc, np.asarray(s, float), information(H, (sigma / s) ** 2),
                   corrected / np.linalg.norm(corrected, axis=1, keepdims=True))


@dataclass
class PosePlan:
    """A planned set of poses and what it is expected to achieve.

    Attributes
    ----------
    directions : ndarray, shape (K, 3)
        Gravity direction of each planned pose in the sensor frame.
    descriptions : list of str
        How to hold the device for each pose (:mod:`optcal.applications.plan.describe`).
    labels : list of str
        Turntable gimbal angles of each pose (empty unless planned on a turntable).
    criterion : Criterion
    value : float
        The criterion of the plan (with the given poses), normalised units, unit noise.
    relaxation_value : float
        The relaxation's optimum over the candidate grid.
    bound : float
        The certificate: no K poses in the feasible set reach more.
    efficiency : float
        The plan's efficiency relative to ``bound`` (D: ``exp((value − bound)/9)``).
    sigma : float
        Pose noise (per axis, prior units) the standard errors are computed for.
    stderr : dict of str to float
        Expected standard error of every parameter of θ (prior units) after the plan.
    stderr_given : dict of str to float
        The same from the given poses alone (inf where they do not determine it); empty without.
    prior_source, units, feasible_set : str
        For the report.
    n_given : int
    excluded_candidates : int
        Directions of the feasible source outside a cap.
    solver, refinement : str
        The relaxation's solver; IPOPT's status of the refinement ("not refined: ..." else).
    given_directions : ndarray, shape (n_given, 3)
    """

    directions: NDArray[np.float64]
    descriptions: list[str]
    labels: list[str]
    criterion: Criterion
    value: float
    relaxation_value: float
    bound: float
    efficiency: float
    sigma: float
    stderr: dict[str, float]
    stderr_given: dict[str, float]
    prior_source: str
    units: str
    feasible_set: str
    n_given: int
    excluded_candidates: int
    solver: str
    refinement: str
    given_directions: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def n_poses(self) -> int:
        return len(self.directions)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (numbers as floats, directions as lists)."""
        return {
            "n_poses": self.n_poses,
            "criterion": self.criterion.value,
            "poses": [
                {"direction": d.tolist(), "description": text, **({"turntable": lab} if lab else {})}
                for d, text, lab in zip(self.directions, self.descriptions, self.labels or [""] * self.n_poses)
            ],
            "value": self.value,
            "relaxation_value": self.relaxation_value,
            "bound": self.bound,
            "efficiency": self.efficiency,
            "sigma": self.sigma,
            "units": self.units,
            "stderr": self.stderr,
            "stderr_given": self.stderr_given,
            "prior": self.prior_source,
            "feasible_set": self.feasible_set,
            "n_given": self.n_given,
            "excluded_candidates": self.excluded_candidates,
            "solver": self.solver,
            "refinement": self.refinement,
        }

    def report(self) -> str:
        """Readable plan: the poses, the certificate, the expected standard errors."""
        name = {"D": "log det M", "A": "−tr M⁻¹", "E": "λ_min(M)"}[self.criterion.value]
        lines = [
            f"plan: {self.n_poses} poses, {self.criterion.value}-optimal"
            + (f", after {self.n_given} given poses" if self.n_given else ""),
            f"prior: {self.prior_source}",
            f"feasible set: {self.feasible_set}"
            + (f" ({self.excluded_candidates} directions outside the cap excluded)" if self.excluded_candidates else ""),
            "",
            f"{'pose':>4}  {'gravity direction (sensor frame)':>34}  orientation",
        ]
        for k, (d, text) in enumerate(zip(self.directions, self.descriptions), 1):
            lab = f"  [{self.labels[k - 1]}]" if self.labels else ""
            lines.append(f"{k:>4}  {d[0]:+10.4f} {d[1]:+10.4f} {d[2]:+10.4f}    {text}{lab}")
        lines += [
            "",
            f"{name} (normalised units, unit noise): plan {self.value:.6g}; relaxation over the grid "
            f"{self.relaxation_value:.6g} ({self.solver}); upper bound for any {self.n_poses} poses {self.bound:.6g}",
            f"{self.criterion.value}-efficiency of the plan against the bound: {100 * self.efficiency:.2f} %  "
            f"(refinement: {self.refinement})",
            "",
            f"expected standard errors at pose noise {self.sigma:g} {self.units}:",
        ]
        for p in PARAM_NAMES:
            before = f"  (given poses alone: {self.stderr_given[p]:.3g})" if self.stderr_given else ""
            lines.append(f"  {p:<5} {self.stderr[p]:.3g}{before}")
        return "\n".join(lines)


def refuse_if_undetermined(prior: Prior, acc: NDArray, sigma_ratio: NDArray, sigma: float, what: str) -> None:
    """Raise :class:`IdentifiabilityError` when poses ``acc`` (noise ``sigma·sigma_ratio``) leave θ undetermined.

    Rank and weak combinations (standard error above 5 % of full scale) are found and named by
    :mod:`optcal.core.identifiability`.
    """
    T, o = prior.model.T_canonical, prior.model.o
    report: IdentifiabilityReport = analyse(T, o, acc, sigma_ratio)
    if report.rank == report.n_params:
        M = information(prior.measurement_vectors(acc), 1.0 / sigma_ratio**2)
        add_weak_directions(report, covariance(M, sigma), T * prior.scale)
    if not report.identifiable:
        raise IdentifiabilityError(f"{what} cannot determine the calibration: {report.describe()}", report)


def resolve_inputs(prior: Prior | None, sigma: float | None, candidates: CandidateSet | None,
                   given: PoseTable | ArrayLike | None) -> tuple[Prior, float, CandidateSet, GivenPoses]:
    """Defaults of a planning request: nominal prior, 1 mg (in the prior's units), free orientations."""
    prior = Prior.nominal() if prior is None else prior
    sigma = DEFAULT_SIGMA * prior.scale if sigma is None else float(sigma)
    if not np.isfinite(sigma) or sigma <= 0:
        raise InputError(f"sigma (the pose noise) must be positive, not {sigma}")
    candidates = sphere_candidates() if candidates is None else candidates
    return prior, sigma, candidates, GivenPoses.of(given, prior, sigma)


def _check_feasible(prior: Prior, candidates: CandidateSet, given: GivenPoses, n_poses: int, sigma: float,
                    H: NDArray) -> None:
    """Refuse requests no K-pose design can satisfy, naming what stays undetermined."""
    if n_poses < 1:
        raise InputError(f"n_poses must be at least 1, not {n_poses}")
    total = n_poses + given.n
    if total < N_PARAMS:
        idx = sequential(H, n_poses, Criterion.D, given.information)
        acc = np.vstack([given.acc, prior.model.measure(candidates.directions[idx])])
        ratio = np.concatenate([given.sigma / sigma, np.ones(n_poses)])
        report = analyse(prior.model.T_canonical, prior.model.o, acc, ratio)
        have = f"{n_poses} poses" + (f" and {given.n} given" if given.n else "")
        raise IdentifiabilityError(
            f"{have} cannot determine the {N_PARAMS} parameters of the lumped model "
            f"({', '.join(PARAM_NAMES)}): at least {N_PARAMS - total} combination(s) stay undetermined, "
            f"e.g. with the best {n_poses}: {report.describe()}; plan at least {N_PARAMS - given.n} poses",
            report,
        )
    acc = np.vstack([given.acc, prior.model.measure(candidates.directions)])
    ratio = np.concatenate([given.sigma / sigma, np.full(len(candidates.directions), 1e-6)])
    report = analyse(prior.model.T_canonical, prior.model.o, acc, ratio)
    if report.rank < report.n_params:
        raise IdentifiabilityError(
            f"no poses in the feasible set ({candidates.description}) can determine the calibration: "
            f"{report.describe()}; widen the constraint",
            report,
        )


def plan_poses(
    n_poses: int,
    criterion: Criterion | str = Criterion.D,
    *,
    prior: Prior | None = None,
    sigma: float | None = None,
    candidates: CandidateSet | None = None,
    given: PoseTable | ArrayLike | None = None,
    random_starts: int = 1,
    seed: int = 0,
    solver: str | None = None,
    solver_options: dict[str, Any] | None = None,
) -> PosePlan:
    """Plan ``n_poses`` orientations that determine the lumped calibration best.

    Parameters
    ----------
    n_poses : int
        Number of new poses K.
    criterion : {"D", "A", "E"}
        D: maximise log det of the information; A: minimise the sum of the parameter variances
        (normalised units); E: maximise the information of the worst-determined combination.
    prior : Prior, optional
        The sensor to plan for (nominal ``T = I``, ``o = 0`` in g when omitted).
    sigma : float, optional
        Pose noise per axis in the prior's units (1 mg when omitted) for the standard errors.
    candidates : CandidateSet, optional
        Feasible directions (free orientations on a 2000-point grid when omitted).
    given : PoseTable or array_like (n, 3), optional
        Poses already taken (their pose means in the prior's units).
    solver, solver_options : str and dict, optional
        The NLP solver of the refinement on the sphere (a CasADi ``nlpsol`` plugin, IPOPT by default;
        :func:`optcal.solvers.registry.choose_nlp_solver`) and its options.
    random_starts : int
        Random K-subsets of the candidates rounded and refined besides the apportioned
        relaxation and the greedy design; the best is kept.
    seed : int
        Seed of the random starts.

    Returns
    -------
    PosePlan

    Raises
    ------
    IdentifiabilityError
        K (plus the given poses) below the nine parameters, a feasible set that cannot
        determine them, or one so narrow that even the best plan leaves a combination with a
        standard error above 5 % of full scale; the message names the combination.
    """
    crit = Criterion.parse(criterion)
    prior, sigma, candidates, given_poses = resolve_inputs(prior, sigma, candidates, given)
    H = prior.information_vectors(candidates.directions)
    _check_feasible(prior, candidates, given_poses, n_poses, sigma, H)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # cvxpy's "may be inaccurate": the bound is computed from w anyway
        relaxation: Relaxation = relax(H, n_poses, crit, candidates, prior.information_vectors, given_poses.information)
    support = relaxation.support
    refuse_if_undetermined(
        prior,
        np.vstack([given_poses.acc, prior.model.measure(candidates.directions[support])]),
        np.concatenate([given_poses.sigma / sigma, 1.0 / np.sqrt(n_poses * relaxation.weights[support])]),
        sigma,
        f"even the best {n_poses} poses in the feasible set ({candidates.description})",
    )
    rng = np.random.default_rng(seed)
    starts = [apportion(relaxation.weights, n_poses), sequential(H, n_poses, crit, given_poses.information)]
    starts += [rng.choice(len(H), n_poses, replace=len(H) < n_poses) for _ in range(random_starts)]
    designs = [exchange(H, start, crit, given_poses.information) for start in starts]
    if crit is not Criterion.D:
        # the D-optimal design as one more start: single swaps stall at the multiple eigenvalues
        # of A- and E-optimal designs, and D-optimal designs are usually good for both
        designs.append(exchange(H, starts[0], Criterion.D, given_poses.information))
    best_value, best_dirs, refinement, best_index = -np.inf, None, "not refined: a fixed set of directions", None
    for k, index in enumerate(designs):
        dirs, status = candidates.directions[index], refinement
        if candidates.continuous and k == len(starts) and crit is not Criterion.D:
            dirs = refine(prior.information_vectors, dirs, Criterion.D, given_poses.information, candidates.cap,
                          ipopt_options=solver_options, solver=solver)[0]
        if candidates.continuous and crit is Criterion.E:
            status = "not refined: λ_min is not differentiable at an E-optimal design (multiple eigenvalue)"
        elif candidates.continuous:
            dirs, status = refine(prior.information_vectors, dirs, crit, given_poses.information, candidates.cap,
                                  ipopt_options=solver_options, solver=solver)
        value = criterion_value(information(prior.information_vectors(dirs), base=given_poses.information), crit)
        if value > best_value:
            best_value, best_dirs, refinement, best_index = value, dirs, status, index
    assert best_dirs is not None and best_index is not None
    M = information(prior.information_vectors(best_dirs), base=given_poses.information)
    stderr = prior.stderr_raw(M, sigma)
    stderr_given = prior.stderr_raw(given_poses.information, sigma) if given_poses.n else None
    return PosePlan(
        directions=best_dirs,
        descriptions=describe_directions(best_dirs),
        labels=[candidates.labels[i] for i in best_index] if candidates.labels else [],
        criterion=crit,
        value=best_value,
        relaxation_value=relaxation.value,
        bound=relaxation.bound,
        efficiency=efficiency(best_value, relaxation.bound, crit),
        sigma=sigma,
        stderr=named(stderr),
        stderr_given=named(stderr_given) if stderr_given is not None else {},
        prior_source=prior.source,
        units=prior.units,
        feasible_set=candidates.description,
        n_given=given_poses.n,
        excluded_candidates=candidates.excluded,
        solver=relaxation.solver,
        refinement=refinement,
        given_directions=given_poses.directions,
    )


__all__ = ["DEFAULT_SIGMA", "GivenPoses", "PosePlan", "plan_poses", "refuse_if_undetermined", "resolve_inputs"]
