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
    "ReadOptions": "optcal.data.options",
    "Reading": "optcal.data.options",
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
    "ReadOptions",
    "Reading",
    "SolverError",
    "lu2017_reference_model",
    "calibrate",
    "cramer_rao_bound",
    "load",
    "__version__",
]


def calibrate(poses, method: str = "default", **options):
    """Calibrate a :class:`PoseTable`; see :func:`optcal.families.accel.calibration.calibrate`."""
    from optcal.families.accel.calibration import calibrate as _calibrate

    return _calibrate(poses, method=method, **options)


def cramer_rao_bound(model, directions, sigma):
    """Cramér–Rao bound of θ, directions as nuisance; see :func:`optcal.core.identifiability.cramer_rao_bound`."""
    from optcal.core.identifiability import cramer_rao_bound as _crlb

    return _crlb(model, directions, sigma)


def load(path: Any, options: Any = None, **overrides: Any) -> Any:
    """Read DATA, a pose table or a raw recording: see :func:`optcal.data.options.read`.

    Parameters
    ----------
    path : str or Path
        Any file optcal reads (CSV/text, Parquet, MAT/netCDF/HDF5, ROS bags, PX4 ULog).
    options : ReadOptions, optional
        The reading options; every one left out is decided from the file, with its reason.
    **overrides
        Any field of :class:`ReadOptions` (``rate=100``, ``units="counts"``, ``kind="raw"``,
        ``columns="ax=..."``) or static-detection setting (``min_dwell_s=1``).  An unknown
        keyword is an :class:`InputError` naming the valid ones.

    Returns
    -------
    Reading
        The poses, every decision with its reason, the recording and its segmentation, and
        every exclusion counted.
    """
    from optcal.data.options import read

    return read(path, options, **overrides)
