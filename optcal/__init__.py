"""optcal: triaxial MEMS accelerometer calibration posed as optimisation problems.

The lumped model ``ā = T (a − o)`` (Lu et al. 2017) is fitted by an algebraic ellipsoid fit
(SVD, or a constrained convex problem in cvxpy), refined by maximum likelihood (IPOPT in
CasADi), and compared with the paper's gradient-descent baseline.  See :mod:`optcal.core.model`
for the conventions.
"""

from typing import Any

from optcal.errors import ConvergenceWarning, IdentifiabilityError, InputError, OptcalError, SolverError

__version__ = "0.1.0"

#: Names imported on first use (PEP 562), so that ``optcal --help`` does not import numpy.
_LAZY: dict[str, str] = {
    "LumpedModel": "optcal.core.model",
    "lu2017_reference_model": "optcal.core.model",
    "PoseTable": "optcal.core.poses",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'optcal' has no attribute {name!r}")

__all__ = [
    "ConvergenceWarning",
    "IdentifiabilityError",
    "InputError",
    "LumpedModel",
    "OptcalError",
    "PoseTable",
    "SolverError",
    "lu2017_reference_model",
    "calibrate",
    "cramer_rao_bound",
    "__version__",
]


def calibrate(poses, method: str = "default", **options):
    """Calibrate a :class:`PoseTable`; see :func:`optcal.families.accel.calibration.calibrate`."""
    from optcal.families.accel.calibration import calibrate as _calibrate

    return _calibrate(poses, method=method, **options)


def cramer_rao_bound(model, directions, sigma):
    """Cramér–Rao bound of θ with the gravity directions as nuisance parameters (Lu 2017, eq. 13-14).

    See :func:`optcal.core.identifiability.cramer_rao_bound`.

    Parameters
    ----------
    model : LumpedModel
        The sensor whose calibration is bounded.
    directions : array_like, shape (n, 3)
        The poses' gravity directions (unit vectors).
    sigma : float or array_like
        The noise of a pose mean, per pose or one for all, in the model's raw units.

    Returns
    -------
    ndarray, shape (9, 9)
        The smallest covariance of an unbiased estimate of θ.
    """
    from optcal.core.identifiability import cramer_rao_bound as _crlb

    return _crlb(model, directions, sigma)
