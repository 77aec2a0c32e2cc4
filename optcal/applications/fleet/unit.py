"""One unit of a fleet: read on a worker, calibrated exactly as ``optcal calibrate`` does.

The task functions here are what Dask runs; they take and return small typed objects
(:class:`~optcal.applications.fleet.inputs.UnitInput`, :class:`~optcal.core.poses.PoseTable`,
:class:`UnitOutcome`), never a user file.  :func:`fit_unit` calls the same code path as the
``calibrate`` command (:func:`optcal.data.load`, then :func:`optcal.families.accel.calibration.calibrate`
with the default method and settings), so a unit's numbers are identical to
``optcal calibrate`` on the same file.  No exception escapes: an unreadable file becomes a
``failed`` outcome, a pose set that does not identify the calibration a ``refused`` one,
each with its reason.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import FitError, IdentifiabilityError, InputError, OptcalError
from optcal.applications.fleet.inputs import UnitInput, is_url
from optcal.core.norm_residual import heldout_residuals
from optcal.core.poses import PoseTable
from optcal.core.stats import rms

if TYPE_CHECKING:
    from optcal.data.options import ReadOptions

#: Unit statuses, in the order of the report.
STATUSES: tuple[str, ...] = ("calibrated", "calibrated_with_prior", "refused", "failed")
#: Fewest poses a refused unit needs to be refitted with the population prior.
MIN_PRIOR_POSES: int = 3


@dataclass
class UnitOutcome:
    """What happened to one unit.

    Attributes
    ----------
    unit, path : str
        Identifier and where the data were read from.
    status : str
        ``calibrated`` (by its own data, as ``optcal calibrate``), ``calibrated_with_prior``
        (its data alone do not identify the calibration; the population prior completes it),
        ``refused`` (data read, no calibration) or ``failed`` (unreadable, or an error).
    reason : str
        Why the unit is not ``calibrated`` (empty otherwise), or the solver's remark.
    theta, stderr : ndarray, shape (9,), or None
        The calibration θ (:data:`optcal.core.model.PARAM_NAMES`, raw units) and its standard errors.
    covariance : ndarray, shape (9, 9), or None
    rms_g, heldout_rms_g : float
        Rms norm residual in g, and its leave-one-out counterpart (:func:`optcal.core.norm_residual.heldout_residuals`).
    n_poses : int
        Poses used.
    exclusions : dict of str to int
        Everything excluded while reading, counted.
    units : str
        Units of the raw data.
    sigma_known : bool
        Whether the data carried per-pose noise.
    prior_candidate : bool
        Whether the data were read and the unit may be refitted with the population prior.
    theta_with_prior, stderr_with_prior, prior_weight : ndarray, shape (9,), or None
        The refit with the population prior (:mod:`optcal.applications.fleet.prior`) and, per parameter, the
        share of the estimate that comes from the prior (0 = the data alone, 1 = the prior alone).
    flag : str
        Why the population statistics flag the unit (empty when not flagged).
    metadata : dict of str to str
        Manifest columns.
    """

    unit: str
    path: str
    status: str
    reason: str = ""
    theta: NDArray[np.float64] | None = None
    stderr: NDArray[np.float64] | None = None
    covariance: NDArray[np.float64] | None = None
    rms_g: float = float("nan")
    heldout_rms_g: float = float("nan")
    n_poses: int = 0
    exclusions: dict[str, int] = field(default_factory=dict)
    units: str = ""
    sigma_known: bool = False
    prior_candidate: bool = False
    theta_with_prior: NDArray[np.float64] | None = None
    stderr_with_prior: NDArray[np.float64] | None = None
    prior_weight: NDArray[np.float64] | None = None
    flag: str = ""
    metadata: dict[str, str] = field(default_factory=dict)

    @property
    def calibrated(self) -> bool:
        """Whether the unit has a calibration (by its data, or with the prior)."""
        return self.status in ("calibrated", "calibrated_with_prior")


@dataclass
class ReadFailure:
    """A unit whose data could not be read (the task's return value instead of a table)."""

    unit: UnitInput
    error: str


def _local_copy(url: str) -> str:
    """Copy an fsspec URL's bytes to a temporary local file with the same suffix."""
    import fsspec

    suffix = Path(url.split("?", 1)[0]).suffix
    fd, local = tempfile.mkstemp(suffix=suffix, prefix="optcal-fleet-")
    with os.fdopen(fd, "wb") as out, fsspec.open(url, "rb") as src:
        out.write(src.read())
    return local


def read_unit(unit: UnitInput, load_options: ReadOptions) -> PoseTable | ReadFailure:
    """Read a unit's data with :func:`optcal.data.read` (a local path or an fsspec URL)."""
    from optcal.data.options import read

    local = None
    try:
        path = unit.path
        if is_url(path):
            local = path = _local_copy(path)
        poses = read(path, load_options).poses
        poses.meta["fleet_path"] = unit.path
        return poses
    except OptcalError as exc:
        return ReadFailure(unit, str(exc))
    except Exception as exc:  # noqa: BLE001 - one bad file never stops the run; the reason is kept
        return ReadFailure(unit, f"{type(exc).__name__}: {exc}")
    finally:
        if local is not None:
            os.unlink(local)


def outcome_from_fit(unit: UnitInput, poses: PoseTable, theta: NDArray, covariance: NDArray | None, residuals: NDArray,
                     weights: NDArray, sigma_known: bool, reason: str = "", status: str = "calibrated") -> UnitOutcome:
    """A :class:`UnitOutcome` from a fit of the unit's poses: θ (raw units), its covariance, residuals and weights."""
    from optcal.core.model import unpack_theta
    from optcal.core.norm_residual import norm_residual_jacobian

    r = np.asarray(residuals, dtype=float)
    T, o = unpack_theta(np.asarray(theta, dtype=float)[:9])
    heldout = heldout_residuals(r, norm_residual_jacobian(T, o, poses.acc), np.asarray(weights))
    cov = None if covariance is None else np.asarray(covariance)[:9, :9]
    return UnitOutcome(
        unit=unit.unit,
        path=unit.path,
        status=status,
        reason=reason,
        theta=np.asarray(theta[:9], dtype=float),
        stderr=None if cov is None else np.sqrt(np.clip(np.diag(cov), 0.0, None)),
        covariance=cov,
        rms_g=rms(r),
        heldout_rms_g=rms(heldout),
        n_poses=poses.n,
        exclusions=dict(poses.exclusions),
        units=poses.units,
        sigma_known=bool(sigma_known),
        metadata=dict(unit.metadata),
    )


def outcome_from_result(unit: UnitInput, poses: PoseTable, result: Any, status: str = "calibrated") -> UnitOutcome:
    """A :class:`UnitOutcome` from a :class:`~optcal.families.accel.result.CalibrationResult` of the unit's poses."""
    return outcome_from_fit(unit, poses, result.params, result.covariance, result.residuals, result.weights,
                            result.sigma_known, "" if result.solver.success else f"solver: {result.solver.status}", status)


def fit_unit(unit: UnitInput, data: PoseTable | ReadFailure, settings: dict[str, Any] | None = None) -> UnitOutcome:
    """Calibrate one unit as ``optcal calibrate`` does (default method; ``settings`` for its estimator:
    ``solver``, ``solver_options``, ``fix``, ``bounds``, ``conic_solver``).

    Never raises: a read failure or an unexpected error gives status ``failed``; a pose set
    that does not identify the calibration (or too few poses, or a collapsed fit) gives
    ``refused``, marked as a candidate for the population prior.
    """
    from optcal.families.accel.calibration import calibrate

    if isinstance(data, ReadFailure):
        return UnitOutcome(unit.unit, unit.path, "failed", data.error, metadata=dict(unit.metadata))
    try:
        return outcome_from_result(unit, data, calibrate(data, **(settings or {})))
    except (IdentifiabilityError, FitError, InputError) as exc:
        usable = data.n >= MIN_PRIOR_POSES and bool(np.all(np.isfinite(data.acc)))
        return UnitOutcome(unit.unit, unit.path, "refused", str(exc), n_poses=data.n, exclusions=dict(data.exclusions),
                           units=data.units, sigma_known=data.sigma is not None, prior_candidate=usable,
                           metadata=dict(unit.metadata))
    except Exception as exc:  # noqa: BLE001 - one bad unit never stops the run; the reason is kept
        return UnitOutcome(unit.unit, unit.path, "failed", f"{type(exc).__name__}: {exc}", n_poses=data.n,
                           metadata=dict(unit.metadata))


def fit_units(units: list[UnitInput], data: list[PoseTable | ReadFailure],
              settings: dict[str, Any] | None = None) -> list[UnitOutcome]:
    """:func:`fit_unit` for many units, the readable ones solved together in batched IPOPT problems.

    With estimator ``settings`` (a solver by name, its options, fixed or bounded parameters)
    every unit is fitted alone by :func:`fit_unit` with them: the batch is IPOPT's, unconstrained.

    The default calibration of every unit whose table :meth:`PoseTable.validate` accepts is
    solved by :class:`optcal.families.accel.batched.BatchedMaximumLikelihood` (the same start,
    weights, passes, covariance and identifiability test as ``optcal calibrate``; its θ equal to
    the one-at-a-time fit to the solver tolerance, measured ≤ 1e-8 relative and ≤ 1e-7 standard
    errors, see ``studies/fleet_scale.md``).  Every unit the batch cannot take exactly as
    ``calibrate`` would — unreadable, refused by validation, not identifiable, a solver that
    did not report success, a collapsed T, no degrees of freedom — goes through
    :func:`fit_unit`, so its outcome and reason are the single-unit path's.  Never raises.
    """
    from optcal.families.accel.base import is_collapsed
    from optcal.families.accel.batched import BatchedMaximumLikelihood, invalid_tables
    from optcal.core.model import PARAM_NAMES, unpack_theta

    if settings:
        return [fit_unit(u, d, settings) for u, d in zip(units, data)]
    outcomes: list[UnitOutcome | None] = [None] * len(units)
    readable = {j: d for j, d in enumerate(data) if isinstance(d, PoseTable)}
    by_n: dict[int, list[int]] = {}
    for j, table in readable.items():
        if table.n > len(PARAM_NAMES):
            by_n.setdefault(table.n, []).append(j)
    batch: list[int] = []
    for group in by_n.values():
        refused = invalid_tables([readable[j] for j in group])
        batch += [j for k, j in enumerate(group) if k not in refused]
    tables = [readable[j] for j in batch]
    try:
        fit = BatchedMaximumLikelihood().fit_many(tables, validate=False) if batch else None
    except Exception:  # noqa: BLE001 - the single-unit path below says what went wrong, unit by unit
        fit = None
    if fit is not None:
        for k, j in enumerate(batch):
            if fit.identifiable[k] and fit.success[k] and not is_collapsed(unpack_theta(fit.theta[k])[0]):
                outcomes[j] = outcome_from_fit(units[j], tables[k], fit.theta[k], fit.covariance[k], fit.residuals[k],
                                               fit.weights[k], tables[k].sigma is not None)
    return [o if o is not None else fit_unit(u, d) for u, d, o in zip(units, data, outcomes)]
