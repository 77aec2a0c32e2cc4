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
    "calibrate_ferraris",
    "calibrate_imu",
    "calibrate_mag",
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
    method : {"default", "mle", "convex", "svd", "exact", "gd", "sixpos", "nominal", "ferraris"}
        ``default`` is ``mle`` (maximum likelihood, Lu 2017 eq. 14) started from the ``convex``
        ellipsoid fit; ``gd`` is the paper's gradient-descent baseline; ``ferraris`` calibrates
        both sensors from a raw recording's six faces and three turns (:func:`calibrate_ferraris`,
        which takes ``sections``, ``turn_angle`` and ``gyro_units``).
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
    from optcal.core.poses import PoseTable
    from optcal.data.options import Reading
    from optcal.families.accel.calibration import calibrate as _calibrate

    given = {k: v for k, v in dict(
        allow_degenerate=allow_degenerate, loss=loss, scale_range=scale_range, weighting=weighting, solver=solver,
        solver_options=solver_options, conic_solver=conic_solver, fix=fix, bounds=bounds).items() if v is not None}
    if method == "ferraris":  # as `optcal calibrate --method ferraris`: both sensors from the faces and turns
        unknown = sorted(set(given) | (set(settings) - {"sections", "turn_angle", "gyro_units"}))
        if unknown:
            raise InputError(f"method 'ferraris' takes no {', '.join(unknown)}; it takes: options, sections, "
                             f"turn_angle, gyro_units")
        return calibrate_ferraris(data, options=options, **settings)
    given.update(settings)
    if method in ("default", "mle"):  # as `optcal calibrate`: the refinement kept only inside the physical set
        given.setdefault("keep_physical", True)
    _check_estimator_keywords(method, given)
    data = _read_if_path(data, options)
    poses = data.poses if isinstance(data, Reading) else data
    if not isinstance(poses, PoseTable):
        raise InputError(f"calibrate() takes a Reading (optcal.load), a PoseTable or a path, not {type(data).__name__}")
    return _calibrate(poses, method=method, **given)


def _read_if_path(data: Any, options: Any) -> Any:
    """DATA read with ``options`` when it is a path (:func:`load`); else DATA itself, which ``options`` cannot read."""
    from pathlib import Path

    from optcal.data.options import read

    if isinstance(data, (str, Path)):
        return read(data, options)
    if options is not None:
        raise InputError("options= reads a file: give it with a path, or give optcal.load(path, options)")
    return data


def _check_estimator_keywords(method: str, given: dict[str, Any]) -> None:
    """Refuse a keyword the method's estimator does not take, naming those it takes (:class:`InputError`)."""
    import inspect

    from optcal.families.accel.calibration import estimator_class

    estimator = estimator_class(method)  # an unknown method is an InputError naming the methods
    valid = [name for name in inspect.signature(estimator).parameters if name != "self"]
    unknown = sorted(set(given) - set(valid))
    if unknown:
        raise InputError(f"method {method!r} takes no {', '.join(unknown)}; it takes: {', '.join(valid)}")


def calibrate_imu(
    data: Any,
    method: str = "default",
    *,
    options: Any = None,
    gyro_units: str | None = None,
    joint: bool = False,
    g_sensitivity: bool = False,
    allow_degenerate: bool = False,
    accept_gyro_fit: bool = False,
    solver: str | None = None,
    solver_options: dict[str, Any] | None = None,
) -> Any:
    """Calibrate accelerometer and gyroscope from one raw recording, as ``optcal calibrate DATA --imu`` does.

    The accelerometer is fitted on the rests (``method``); the gyroscope's scale, misalignment
    and bias (Tedaldi 2014's model) by the gravity direction it must carry across each move.

    Parameters
    ----------
    data : Reading or str or Path
        What :func:`load` returned for a raw recording with gyro columns, or its file.
    method : str
        The accelerometer's estimator (as :func:`calibrate`).
    options : ReadOptions, optional
        How a file is read (only when ``data`` is a path).
    gyro_units : str, optional
        The gyro columns' units (``"rad/s"``, ``"deg/s"``, ``"counts"``...), instead of the decision
        from the file and the moves (``--gyro-units``).
    joint : bool
        Re-estimate the accelerometer jointly with the gyro (``--joint``).
    g_sensitivity : bool
        Model the gyro's g-sensitivity (``--g-sensitivity``).
    allow_degenerate : bool
        Proceed when the poses or the moves do not determine every parameter.
    accept_gyro_fit : bool
        Keep a gyro calibration the moves do not support, with its warning in ``fit_warning``.
    solver, solver_options : optional
        The NLP solver by CasADi's name and its options, for both sensors' problems.

    Returns
    -------
    ImuCalibration
        ``save(path)`` writes the JSON ``optcal calibrate --imu -o`` writes; ``fit_warning`` says
        what the moves do not support when ``accept_gyro_fit`` kept it.

    Raises
    ------
    InputError
        A pose table (no moves), no gyro columns, or moves that do not support the gyro's fit.
    """
    from optcal.data.options import Reading
    from optcal.families.gyro.estimator import GyroSettings, calibrate_imu_loaded

    data = _read_if_path(data, options)
    if not isinstance(data, Reading) or data.segmentation is None:
        raise InputError("calibrate_imu() takes a raw recording with gyro columns (optcal.load(path) of one, or "
                         "its path): a pose table has no moves to calibrate a gyroscope on")
    nlp: dict[str, Any] = {}
    if solver is not None:
        nlp["solver"] = solver
    if solver_options:
        nlp["solver_options"] = dict(solver_options)
    _check_estimator_keywords(method, nlp)
    settings = GyroSettings.from_flags(joint=joint, g_sensitivity=g_sensitivity, allow_degenerate=allow_degenerate,
                                       accept_gyro_fit=accept_gyro_fit, solver=solver, solver_options=solver_options)
    return calibrate_imu_loaded(data, gyro_units=gyro_units, method=method, settings=settings,
                                acc_settings={"allow_degenerate": allow_degenerate, **nlp})


def calibrate_ferraris(
    data: Any,
    *,
    options: Any = None,
    sections: str | None = None,
    turn_angle: float | None = None,
    gyro_units: str | None = None,
) -> Any:
    """Ferraris' calibration of both sensors (six faces, three turns), as ``optcal calibrate DATA --method ferraris``.

    Parameters
    ----------
    data : Reading or str or Path
        A raw recording with gyro columns (:func:`load` of it, or its file).
    options : ReadOptions, optional
        How a file is read (only when ``data`` is a path).
    sections : str, optional
        imucal's section list (a JSON or CSV file), else a ``part`` column of the file, else the
        sections found in the recording (``--sections``).
    turn_angle : float, optional
        Each turn's angle in degrees (default: the whole turns nearest the reading; one for counts).
    gyro_units : str, optional
        The gyro columns' units (``--gyro-units``).

    Returns
    -------
    ImuCalibration
        ``save(path)`` writes the JSON ``optcal calibrate --method ferraris -o`` writes.

    Raises
    ------
    InputError
        A pose table, no gyro columns, or sections that cannot be found.
    """
    from optcal.data.options import Reading
    from optcal.families.ferraris import ferraris_fit, regions_for

    data = _read_if_path(data, options)
    if not isinstance(data, Reading) or data.segmentation is None:
        raise InputError("the Ferraris method needs the raw recording (its turns calibrate the gyroscope), not a "
                         "pose table: give optcal.load(path) of one, with kind='raw' if it was read as a table")
    seg = data.segmentation
    fit = ferraris_fit(seg, regions_for(seg, sections), turn_angle_deg=turn_angle, gyro_units=gyro_units)
    return fit.calibration(seg.recording)


def calibrate_mag(
    data: Any,
    method: str = "default",
    *,
    form: str = "auto",
    units: str | None = None,
    columns: str | dict[str, str] | None = None,
    topic: str | None = None,
    gyro_units: str | None = None,
    allow_degenerate: bool = False,
    accept_fit: bool = False,
    loss: str | None = None,
    solver: str | None = None,
    solver_options: dict[str, Any] | None = None,
    conic_solver: str | None = None,
) -> Any:
    """Calibrate a magnetometer (hard and soft iron) from its raw samples, as ``optcal calibrate DATA --sensor mag``.

    The ellipsoid ``|T (m − o)| = 1`` is fitted as a convex problem and refined by maximum
    likelihood; ``form="auto"`` keeps the richest form the samples determine and that predicts
    left-out directions as well as the best.

    Parameters
    ----------
    data : str or Path
        The recording (any file :func:`optcal.families.mag.samples.read_mag` reads).
    method : {"default", "convex", "mle", "exact", "gd", "svd"}
    form : {"auto", "offsets", "diagonal", "full"}
        Hard iron only, hard iron with per-axis scale, or the full soft-iron matrix.
    units : str, optional
        The magnetometer's units, instead of the file's word or the decision from the magnitude
        (``--mag-units``).
    columns : str or dict, optional
        ``"mx=NAME,my=NAME,mz=NAME"`` (names or 1-based positions).
    topic : str, optional
        The variable of a container, the ULog topic or the bag's MagneticField topic.
    gyro_units : str, optional
        The gyroscope's units for the dip's near-rest test, when the file has a gyro.
    allow_degenerate, accept_fit : bool
        Fit samples that do not determine the form; keep a fit whose residual says the samples
        are not a field.
    loss : str, optional
        A robust loss (``default`` and ``mle``).
    solver, solver_options, conic_solver : optional
        The NLP solver by CasADi's name and its options; the convex fit's conic solver.

    Returns
    -------
    MagCalibrationResult
        ``save(path)`` writes the JSON ``optcal calibrate --sensor mag -o`` writes;
        ``calibration.correct(m)`` calibrates samples; ``fit`` and ``dip`` hold the evidence.

    Raises
    ------
    InputError
        Unreadable samples, a form the samples do not determine, or a keyword the method does not take.
    """
    from optcal.families.mag.calibration import calibrate_mag as _calibrate_mag
    from optcal.families.mag.fit import MagSettings, refuse_orientation_method
    from optcal.families.mag.samples import read_mag

    refuse_orientation_method(method, "method")
    given = {k: v for k, v in dict(solver=solver, solver_options=solver_options, conic_solver=conic_solver,
                                   loss=loss).items() if v is not None}
    _check_estimator_keywords(method, given)
    samples = read_mag(data, columns=columns, topic=topic, mag_units=units)
    return _calibrate_mag(samples, MagSettings(method=method, form=form, allow_degenerate=allow_degenerate,
                                               accept_fit=accept_fit, estimator=given, gyro_units=gyro_units))


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
