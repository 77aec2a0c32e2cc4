"""Choosing and running an estimator: the one function most users call.

Every estimator is a class whose constructor takes its settings and whose
``fit(poses) -> CalibrationResult`` does the work (imucal's split of algorithm and result).
``ESTIMATORS`` maps each ``--method`` name to its class; the default is ``convex`` followed
by ``mle`` (the convex algebraic fit gives the starting point of the maximum-likelihood
refinement, as the ellipsoid fit does in Lu 2017, section 2.2).
"""

from __future__ import annotations

import importlib
from typing import Any

from optcal.families.caltypes.base import FitPoses
from optcal.errors import InputError
from optcal.core.poses import PoseTable
from optcal.families.accel.result import CalibrationResult

#: method name -> "module:class".  One line per estimator.
ESTIMATORS: dict[str, str] = {
    "svd": "optcal.families.accel.ellipsoid:SVDEllipsoidFit",
    "convex": "optcal.families.accel.ellipsoid:ConvexEllipsoidFit",
    "mle": "optcal.families.accel.mle:MaximumLikelihood",
    "exact": "optcal.families.accel.exact:ExactMaximumLikelihood",
    "gd": "optcal.families.accel.gradient_descent:GradientDescent",
    "sixpos": "optcal.families.accel.sixpos:SixPositionLeastSquares",
    "nominal": "optcal.families.accel.nominal:NominalOrientationML",
}
DEFAULT_METHOD = "mle"
METHOD_CHOICES: tuple[str, ...] = ("default", *ESTIMATORS)


def estimator_class(method: str) -> type:
    """The estimator class registered under ``method``."""
    if method == "default":
        method = DEFAULT_METHOD
    target = ESTIMATORS.get(method)
    if target is None:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHOD_CHOICES)}")
    module, attr = target.split(":")
    return getattr(importlib.import_module(module), attr)


def make_estimator(method: str = "default", **settings: Any) -> Any:
    """Instantiate the estimator ``method`` with its settings."""
    return estimator_class(method)(**settings)


def calibrate(poses: PoseTable, method: str = "default", **settings: Any) -> CalibrationResult:
    """Calibrate a pose table.

    Parameters
    ----------
    poses : PoseTable
        Static poses (validated here).
    method : str
        ``default`` (= ``mle``, started from ``convex``), ``svd``, ``convex``, ``mle``,
        ``exact``, ``gd`` or ``sixpos``.
    **settings
        Passed to the estimator's constructor (e.g. ``allow_degenerate=True``,
        ``loss="huber"``).

    Returns
    -------
    CalibrationResult
        With ``fitted_on`` set to the poses; ``result.calibration`` is the typed calibration.
    """
    if not isinstance(poses, PoseTable):
        raise InputError("calibrate() takes a PoseTable; build one with optcal.PoseTable(acc=...)")
    result = make_estimator(method, **settings).fit(poses)
    result.fitted_on = FitPoses.of(poses)  # saved with the calibration, for the exporters' loss figures
    return result
