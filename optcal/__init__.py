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
    "apply",
    "calibrate",
    "cramer_rao_bound",
    "load",
    "load_calibration",
    "__version__",
]


#: The keywords of :func:`calibrate` passed to the estimator when given (``None``: the method's default).
_FIT_KEYWORDS: tuple[str, ...] = (
    "allow_degenerate", "loss", "scale_range", "weighting", "solver", "solver_options", "conic_solver", "fix", "bounds",
)


def calibrate(
    data: Any,
    method: str = "default",
    *,
    options: Any = None,
    allow_degenerate: bool | None = None,
    loss: str | None = None,
    scale_range: tuple[float, float] | None = None,
    weighting: str | None = None,
    solver: str | None = None,
    solver_options: dict[str, Any] | None = None,
    conic_solver: str | None = None,
    fix: dict[str, float] | None = None,
    bounds: dict[str, tuple[float, float]] | None = None,
    **settings: Any,
) -> Any:
    """Calibrate the accelerometer from DATA, as ``optcal calibrate DATA --method METHOD`` does.

    Parameters
    ----------
    data : Reading, PoseTable, str or Path
        What :func:`load` returned, a pose table, or a file (read with :func:`load` and ``options``).
    method : {"default", "mle", "convex", "svd", "exact", "gd", "sixpos"}
        ``default`` is ``mle`` (maximum likelihood, Lu 2017 eq. 14) started from the ``convex``
        ellipsoid fit; ``gd`` is the paper's gradient-descent baseline.
    options : ReadOptions, optional
        How a file is read (only when ``data`` is a path).
    allow_degenerate : bool, optional
        Fit poses that do not determine every parameter (all methods; refused by default).
    loss : {"squared", "huber", "cauchy", ...}, optional
        Robust loss of the residuals (``mle``, ``default``).
    scale_range : (float, float), optional
        Bounds on the scale factors (``mle``, ``default``).
    weighting : str, optional
        How the poses are weighted (``mle``, ``default``, ``gd``).
    solver, solver_options : optional
        The NLP solver by CasADi's name and its options (``mle``, ``default``; ``convex``:
        the conic solver's name).
    conic_solver : str, optional
        The conic solver of the convex fit or of ``mle``'s convex start.
    fix, bounds : dict, optional
        Parameters held fixed, or bounded, by name (``mle``, ``default``).
    **settings
        Any other setting of the method's estimator (e.g. ``gd``'s ``step``, ``tol``,
        ``max_iter``); an unknown one is an :class:`InputError` naming those the method takes.

    Returns
    -------
    CalibrationResult
        ``save(path)`` writes the JSON ``optcal calibrate -o`` writes; ``correct(raw)`` applies
        it; ``calibration`` is the typed calibration (:func:`load_calibration` reads it back).

    Raises
    ------
    InputError
        An unknown method or keyword, unreadable DATA, or too few poses.
    IdentifiabilityError
        Poses that do not determine every parameter (unless ``allow_degenerate``).
    """
    import inspect
    from pathlib import Path

    from optcal.core.poses import PoseTable
    from optcal.data.options import Reading, read
    from optcal.families.accel.calibration import calibrate as _calibrate, estimator_class

    given = {k: v for k, v in dict(
        allow_degenerate=allow_degenerate, loss=loss, scale_range=scale_range, weighting=weighting, solver=solver,
        solver_options=solver_options, conic_solver=conic_solver, fix=fix, bounds=bounds).items() if v is not None}
    given.update(settings)
    if method in ("default", "mle"):  # as `optcal calibrate`: the refinement kept only inside the physical set
        given.setdefault("keep_physical", True)
    estimator = estimator_class(method)  # an unknown method is an InputError naming the methods
    valid = [name for name in inspect.signature(estimator).parameters if name != "self"]
    unknown = sorted(set(given) - set(valid))
    if unknown:
        raise InputError(f"method {method!r} takes no {', '.join(unknown)}; it takes: {', '.join(valid)}")
    if isinstance(data, (str, Path)):
        data = read(data, options)
    elif options is not None:
        raise InputError("options= reads a file: give it with a path, or give optcal.load(path, options)")
    poses = data.poses if isinstance(data, Reading) else data
    if not isinstance(poses, PoseTable):
        raise InputError(f"calibrate() takes a Reading (optcal.load), a PoseTable or a path, not {type(data).__name__}")
    return _calibrate(poses, method=method, **given)


def load_calibration(path: Any, *, gyro: Any = None) -> Any:
    """Read a saved calibration: optcal's JSON (any type), imucal's JSON or imu_tk's ``.calib``.

    Parameters
    ----------
    path : str or Path
    gyro : str or Path, optional
        imu_tk's gyroscope ``.calib`` (with its accelerometer's as ``path``).

    Returns
    -------
    Calibration
        ``correct(acc, temp, t)`` corrects samples; :func:`apply` corrects a whole file.
    """
    from optcal.families.calibration_files import load as _load

    return _load(path, gyro=gyro)


def apply(calibration: Any, data: Any, output: Any = None, options: Any = None, *, units_out: str = "g",
          **overrides: Any) -> Any:
    """Correct every row of DATA with a calibration, as ``optcal apply CAL DATA -o OUT`` does.

    Parameters
    ----------
    calibration : Calibration, CalibrationResult, str or Path
        A calibration, the result of :func:`calibrate`, or a saved one (:func:`load_calibration`).
    data : str or Path
        The file to correct (any kind optcal reads).
    output : str or Path, optional
        Write the corrected rows here (``.csv`` or ``.parquet``).
    options : ReadOptions, optional
    units_out : {"g", "m/s^2"}
    **overrides
        Fields of :class:`ReadOptions` over ``options``.

    Returns
    -------
    AppliedFile
        ``frame`` (the corrected rows with their ``optcal_status``) and the counts.
    """
    from pathlib import Path

    from optcal.families.caltypes.apply import apply_to_file, write_table

    if isinstance(calibration, (str, Path)):
        calibration = load_calibration(calibration)
    calibration = getattr(calibration, "calibration", calibration)
    applied = apply_to_file(calibration, data, options, units_out=units_out, **overrides)
    if output is not None:
        write_table(applied, output)
    return applied


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
