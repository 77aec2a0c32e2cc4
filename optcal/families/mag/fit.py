"""The magnetometer's calibration: hard and soft iron as the accelerometer's ellipsoid problem.

A magnetometer turned through many orientations in a constant field traces the ellipsoid
``m̄ = T (m − o)``, ``‖m̄‖ = 1`` (hard iron ``o``, soft iron and scale ``T``; the field strength
is ``det(T)^(−1/3)`` in the data's units): the accelerometer's lumped model (Lu 2017, eq. 6,
13) with the local field in place of gravity and every raw sample as a "pose" (no rests are
needed, the noise is per sample).  So the same estimators fit it: the algebraic ellipsoid fit
as a convex problem in cvxpy (``A ⪰ εI``), refined by maximum likelihood in CasADi
(:mod:`optcal.families.accel.mle`: IPOPT or any solver by name, losses, ``fix``/``bounds``), and
the paper's gradient-descent baseline (``method="gd"``), all through
:func:`optcal.families.accel.calibration.calibrate`.

Reduced forms, chosen by evidence (:func:`choose_form`): ``full`` (9 parameters), ``diagonal``
(T diagonal: ``fix`` the three off-diagonal entries at 0, 6 parameters) and ``offsets`` (a
sphere, ``T = I/r``: 4 parameters, solved by linear least squares then Gauss–Newton).  The form
kept is the richest whose parameters are determined to :data:`USABLE_SHARE` of the field and
which predicts ``‖T(m − o)‖ = 1`` in directions left out of its fit (:func:`heldout_forms`: each
direction cell left out in turn) no worse than the best such form by more than the standard error
of the paired difference.  The physical model: a magnetometer always has some soft iron and scale
mismatch (a sphere is the approximation), so the comparison protects against a richer form that
predicts unseen directions worse, not against one the cells cannot tell apart; where the cells are too few (or
the user constrains the fit), the richest form whose every parameter is determined to
:data:`RELEVANT_SHARE` of the field: a parameter uncertain by 1 % of the field moves the
calibrated field by that much, about 0.6° of heading at the equator (more where the field dips).

The ellipsoid fit fixes ``T`` only up to a rotation (``‖R T u‖ = ‖T u‖``): the calibration
holds the symmetric ``T = (TᵀT)^½`` (no rotation: the form the firmware's soft-iron matrix
takes), and with an accelerometer the rotation between the two sensors' frames is estimated
from the constant angle between field and gravity (:mod:`optcal.families.mag.dip`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from optcal.core.poses import PoseTable
from optcal.errors import IdentifiabilityError, InputError, SolverError
# the names below moved to their own modules (one concept each) and stay importable from here, where the callers
# (calibration, planar, dip, the diagnosis, the command line, the tests, the benchmarks) import them
from optcal.families.mag.batch_means import BATCH_START, MIN_BATCHES, batch_means_stderr, correlation_inflation
from optcal.families.mag.coverage import (COVERAGE_CAP_DEG, COVERAGE_DIRECTIONS, COVERAGE_NAMES, COVERAGE_SAMPLES,
                                          PLANAR_SPREAD, Coverage, coverage, coverage_notes, planar_tilt)
from optcal.families.mag.ellipsoid import (FORM_BASIS, FORMS, SYMMETRIC_ENTRIES, SYMMETRIC_NAMES, fit_symmetric,
                                           norm_residual_jacobian, sphere_fit, symmetric_T)
from optcal.families.mag.heldout import HELDOUT_SAMPLES, MIN_HELDOUT_CELLS, HeldOut, heldout_forms
from optcal.families.mag.heldout_rule import richest_within_se
from optcal.families.mag.refine import ML_METHODS, START_SOLVER, SensorUnitsFit, refine_ml, solver_name
from optcal.families.mag.samples import MagSamples

#: The sphere's fit under its former private name (:mod:`optcal.families.mag.planar` and the benchmarks import it).
_sphere_fit = sphere_fit

#: A form is kept when the standard error of each of its parameters (by batch means of correlated
#: samples, :func:`batch_means_stderr`) is below this share of the field: an error of 1 % of the
#: field in a calibrated component is about 0.6° of heading at the equator (1/cos(dip) more
#: elsewhere), the accuracy a consumer compass is quoted at.
RELEVANT_SHARE: float = 0.01
#: Without a form determined to :data:`RELEVANT_SHARE`, the best determined one is kept when its
#: worst parameter is within a tenth of the field (about 6° of heading at the equator, the error of
#: an uncalibrated phone compass): beyond it no form is a calibration, and the samples are refused.
USABLE_SHARE: float = 0.1
#: Samples whose raw values spread by less than this share of their magnitude hold one
#: orientation: a rotation of θ moves the field by 2 sin(θ/2) of its magnitude, so 5 % is a turn
#: of about 3° (hand tremor, not a calibration's rotation), while a hard iron of three fields
#: still leaves a full rotation 15 % of the raw magnitude.
ONE_ORIENTATION_SHARE: float = 0.05
#: The largest rms of ‖T(m − o)‖ − 1 a magnetic field leaves: a field distorted by hard and soft
#: iron lies on an ellipsoid (shared recordings: 0.3-1.3 %), and a local disturbance or motor
#: current of a fifth of the field over the whole session is already no calibration.  Samples
#: beyond it are not a field (a gyro or an accelerometer in motion mapped as mx, my, mz).
NOT_A_FIELD_RMS: float = 0.2
#: A field turned through the orientations of a calibration spans a large share of its strength
#: (a full sphere: a standard deviation of 58 % of it along every axis; a ±30° cap still 20 %):
#: samples that spread by less than 10 % of the fitted field strength are a cloud that a huge
#: ellipsoid passes through, not a field seen from many sides (a gyro's or accelerometer's
#: columns mapped as mx, my, mz).
NOT_A_FIELD_SPAN: float = 0.1

#: The accelerometer's methods that need known orientations or rests (:mod:`optcal.families.accel.nominal`,
#: Ferraris' faces): a magnetometer turned freely has neither, and self-calibrates.
ORIENTATION_METHODS: tuple[str, ...] = ("sixpos", "nominal", "ferraris")


def refuse_orientation_method(method: str, option: str = "--method") -> None:
    """Refuse a method of :data:`ORIENTATION_METHODS` (an :class:`InputError` naming the self-calibrating ones,
    spelled as ``option``: the command's flag, or Python's keyword)."""
    if method in ORIENTATION_METHODS:
        raise InputError(f"{option} {method} needs known orientations or rests; a magnetometer self-calibrates: "
                         f"use {option} default, convex, mle, exact, gd or svd")


@dataclass(frozen=True)
class MagSettings:
    """How to fit: the estimator, the form and the solver settings.

    Attributes
    ----------
    method : str
        Any method of :data:`optcal.families.accel.calibration.ESTIMATORS` that self-calibrates
        (``default`` = convex then ML, ``convex``, ``mle``, ``exact``, ``gd``, ``svd``).
    form : str
        ``auto`` (by evidence), ``offsets``, ``diagonal`` or ``full``.
    allow_degenerate : bool
        Fit even when the samples do not determine the form's parameters.
    accept_fit : bool
        Keep a fit whose residual says the samples are not a field.
    estimator : dict
        Further estimator settings (``solver``, ``solver_options``, ``conic_solver``, ``loss``, ``fix``, ``bounds``).
    gyro_units : str, optional
        The gyroscope's units (``--gyro-units``) for the dip's near rest, instead of the decision from its samples.
    """

    method: str = "default"
    form: str = "auto"
    allow_degenerate: bool = False
    accept_fit: bool = False
    estimator: dict[str, Any] = field(default_factory=dict)
    gyro_units: str | None = None


@dataclass(frozen=True)
class FormFit:
    """One form's fit: ``T`` (symmetric), ``o``, the residuals and the standard errors (``note``: what was
    decided on the way, printed, e.g. a maximum-likelihood refinement not kept,
    :func:`optcal.families.mag.refine.refinement_departure`; ``ml_left``: the convex start was kept because the
    maximum likelihood left the physical set under both noise models, so the samples do not determine the form
    whatever its standard errors, linearised at the start, say)."""

    form: str
    T: NDArray[np.float64]
    o: NDArray[np.float64]
    residuals: NDArray[np.float64]
    stderr: dict[str, float]
    worst_share: float
    method: str
    solver: str
    note: str | None = None
    ml_left: bool = False

    @property
    def field_strength(self) -> float:
        """``det(T)^(−1/3)``: the radius of the sphere of the ellipsoid's volume, data units."""
        return float(np.linalg.det(self.T) ** (-1.0 / 3.0))

    @property
    def rms(self) -> float:
        """rms of ``‖T(m − o)‖ − 1``."""
        return float(np.sqrt(np.mean(self.residuals ** 2)))


def fit_form(samples: MagSamples, form: str, settings: MagSettings) -> FormFit:
    """Fit one form (module docstring) to the samples."""
    from optcal.families.accel.calibration import calibrate

    m = samples.m
    if form == "offsets":
        o, r, _ = sphere_fit(m)
        T = np.eye(3) / r
        resid = np.linalg.norm((m - o) @ T.T, axis=1) - 1.0
        d = m - o
        n = np.linalg.norm(d, axis=1)
        # ‖m − o‖/r − 1 differentiated by o and r; its standard errors by batch means (correlated samples)
        se = batch_means_stderr(np.column_stack([-d / (n * r)[:, None], -n / r**2]), resid)
        stderr = {"o_x": se[0], "o_y": se[1], "o_z": se[2], "r": se[3]}
        return FormFit(form, T, o, resid, {k: float(v) for k, v in stderr.items()}, float(np.max(se) / r),
                       "sphere", "numpy least squares + Gauss-Newton")
    est = dict(settings.estimator)
    method = settings.method
    if form == "diagonal":
        method = "mle" if method in ("default", "convex", "svd") else method
        est["fix"] = {**dict(est.get("fix") or {}), "T_yx": 0.0, "T_zx": 0.0, "T_zy": 0.0}
        if method not in ("mle",):
            raise InputError(f"--mag-form diagonal fixes T's off-diagonal entries, which the mle method does; "
                             f"not {method} (use --method mle or --mag-form full)")
    poses = PoseTable(acc=m, units="counts", source="raw recording")
    note = None
    if method in ML_METHODS:
        result, note = refine_ml(poses, form, method, est)
    else:
        result = calibrate(poses, method=method, allow_degenerate=True, **est)
    refined = isinstance(result, SensorUnitsFit)
    T = symmetric_T(result.T)
    o = np.asarray(result.o, dtype=float)
    resid = np.linalg.norm((m - o) @ T.T, axis=1) - 1.0
    r = float(np.linalg.det(T) ** (-1.0 / 3.0))
    if refined or (not settings.estimator.get("fix") and not settings.estimator.get("bounds")):
        # the stored symmetric T's entries and o, their standard errors by batch means; the diagonal form's
        # off-diagonal entries are fixed at 0 (not parameters)
        J = norm_residual_jacobian(m, T, o)
        keep = [0, 1, 2, 3, 4, 5, 6, 7, 8] if form == "full" else [0, 3, 5, 6, 7, 8]
        names = [(list(SYMMETRIC_NAMES) + [f"o_{a}" for a in "xyz"])[j] for j in keep]
        se = batch_means_stderr(J[:, keep], resid)
        stderr = dict(zip(names, map(float, se)))
        shares = [v / r if k.startswith("o_") else v * r for k, v in stderr.items()]  # T: 1/field per unit
        if not np.all(np.isfinite(shares)):
            shares.append(np.inf)
        return FormFit(form, T, o, resid, stderr, float(max(shares)), result.method, solver_name(result), note,
                       refined and solver_name(result) == START_SOLVER)
    assert not isinstance(result, SensorUnitsFit)
    infl = correlation_inflation(resid)
    stderr = {k: float(v) * infl for k, v in result.stderr.items() if np.isfinite(v)}
    shares = []
    for name, se in stderr.items():
        if name.startswith("o_"):
            shares.append(se / r)
        elif name.startswith("T_") and name not in est.get("fix", {}):
            shares.append(se * r)  # T is 1/field per unit: r·δT is the share of the field
    if len(stderr) < len(result.stderr) or not shares:
        shares.append(np.inf)
    return FormFit(form, T, o, resid, stderr, float(max(shares)), result.method, solver_name(result), note)


@dataclass(frozen=True)
class MagFit:
    """The chosen form's fit with the evidence for it.

    Attributes
    ----------
    fit : FormFit
    form_reason : str
        Why this form (printed, with ``--mag-form`` to override).
    tried : dict of str to FormFit
        Every form fitted on the way.
    coverage : Coverage
    notes : list of str
        Identifiability and coverage notes.
    heldout : HeldOut, optional
        The forms' errors on direction cells left out of their fit, where ``auto`` compared them.
    """

    fit: FormFit
    form_reason: str
    tried: dict[str, FormFit]
    coverage: Coverage
    notes: list[str]
    heldout: HeldOut | None = None


def check_samples(samples: MagSamples, settings: MagSettings) -> None:
    """Refuse samples no fit can use, in one line with the option that fixes or overrides it."""
    need = FORMS["offsets"] if settings.form in ("auto", "offsets") else FORMS[settings.form]
    if samples.n < max(need, 1) + 1:
        raise InputError(f"{samples.n} magnetometer samples: the {settings.form if settings.form != 'auto' else 'smallest'} "
                         f"form needs more than {need}; record the sensor turning through many orientations "
                         f"(optcal plan --sensor mag)")
    spread = float(np.sqrt(np.max(np.linalg.eigvalsh(np.cov(samples.m.T)))))
    size = float(np.median(np.linalg.norm(samples.m, axis=1)))
    if not settings.allow_degenerate and spread < ONE_ORIENTATION_SHARE * max(size, 1e-300):
        raise InputError(f"the magnetometer samples hold one orientation only (they spread by {spread:.3g}, "
                         f"{100 * spread / max(size, 1e-300):.2g} % of |m| = {size:.4g}; a calibration needs the sensor turned "
                         f"through many orientations: optcal plan --sensor mag); --allow-degenerate fits anyway")
    # an axis that reads one value in every sample while the others turn never saw the field turn (a 2-axis
    # compass logged with a third column of zeros, a dead axis): no ellipsoid through such samples is determined
    # (the sphere's normal equations are singular), whatever --allow-degenerate asks
    dead = [f"m{a}" for a, c in zip("xyz", samples.m.T) if np.ptp(c) == 0.0]
    if dead and spread > 0.0:
        value = ", ".join(f"{k} = {samples.m[0, 'xyz'.index(k[1])]:.6g}" for k in dead)
        raise InputError(f"the magnetometer's {', '.join(dead)} column reads one value in every sample ({value}) while "
                         f"the others turn: a 2-axis compass's log or a dead axis, and a field in three axes cannot be "
                         f"fitted to it; map three axes that measured the field with --columns mx=NAME,my=NAME,mz=NAME")


def choose_form(samples: MagSamples, settings: MagSettings) -> MagFit:
    """Fit the form that predicts the field best in directions left out of its fit, or the one asked for.

    ``auto``: the forms are compared held out over direction cells (:func:`heldout_forms`).  A form is
    usable when its fit to all the samples succeeds with its parameters determined to
    :data:`USABLE_SHARE` of the field (not a planar turn's full form); the best is the usable form with
    the smallest held-out error, and the richest usable form whose held-out mean square exceeds the
    best's by no more than the standard error of the paired difference is kept (a soft iron is
    always present: the comparison rejects a richer form only where it predicts the left-out
    directions worse).  With fewer than :data:`MIN_HELDOUT_CELLS` cells, or with the user's
    ``fix``/``bounds`` (a model the comparison does not fit), the richest form whose parameters are
    determined to :data:`RELEVANT_SHARE` of the field is kept.

    Raises
    ------
    InputError
        Samples no fit can use (:func:`check_samples`) or that are not a field.
    IdentifiabilityError
        No form's parameters are determined to :data:`USABLE_SHARE` (unless ``allow_degenerate``).
    """
    check_samples(samples, settings)
    tried: dict[str, FormFit] = {}
    failed: list[str] = []
    heldout: HeldOut | None = None

    def fit(form: str) -> FormFit | None:
        if form not in tried and samples.n > FORMS[form] and not any(f.startswith(f"the {form} form") for f in failed):
            try:
                tried[form] = fit_form(samples, form, settings)
            except SolverError as exc:
                failed.append(f"the {form} form's fit failed ({exc}); the other forms were tried")
        return tried.get(form)

    chosen: FormFit | None = None
    if settings.form != "auto":
        if settings.form not in FORMS:
            raise InputError(f"unknown --mag-form {settings.form!r}; use auto, {', '.join(FORMS)}")
        chosen = fit_form(samples, settings.form, settings)
        tried[settings.form] = chosen
        reason = "given with --mag-form"
    else:
        forms = tuple(f for f in FORMS if samples.n > FORMS[f])
        if not (settings.estimator.get("fix") or settings.estimator.get("bounds")) and len(forms) > 1:
            heldout = heldout_forms(samples.m, forms)
            if len(heldout.cells) < MIN_HELDOUT_CELLS:
                heldout = None
        if heldout is not None:
            chosen, evidence = _choose_heldout(heldout, fit)
        if chosen is not None and heldout is not None:
            reason = evidence + "; parameters determined to " + ", ".join(
                f"{f} {100 * t.worst_share:.2g} %" for f, t in tried.items()) + " of the field"
            reason += _heldout_model_line(settings)
            passed = [f for f in tried if tried[f].worst_share >= USABLE_SHARE]
            if passed:
                reason += (f" ({', '.join(passed)} not kept: {100 * USABLE_SHARE:g} % or worse is no calibration "
                           "in the directions left out)")
            left = [f for f in tried if tried[f].ml_left]
            if left:
                reason += (f" ({', '.join(left)} not kept: its maximum likelihood leaves the physical set under both noise "
                           "models, so the samples do not determine it)")
        else:
            for form in ("full", "diagonal", "offsets"):
                fit(form)
            if not tried:
                raise SolverError("; ".join(failed))
            _check_is_field(tried.get("offsets") or fit_form(samples, "offsets", settings), settings, samples.m)  # before "not determined"
            chosen, reason = _by_determination(tried)
            if chosen.worst_share >= USABLE_SHARE and not settings.allow_degenerate:
                _refuse_undetermined(samples, tried)
            if heldout is None and len(forms) > 1 and not (settings.estimator.get("fix") or settings.estimator.get("bounds")):
                reason += f"; the samples fill too few direction cells to compare the forms held out (at least {MIN_HELDOUT_CELLS})"
            elif chosen.worst_share >= USABLE_SHARE:
                reason += "; kept with --allow-degenerate"
    assert chosen is not None
    _check_is_field(chosen, settings, samples.m)
    cov = coverage((samples.m - chosen.o) @ chosen.T.T)
    notes = failed + ([chosen.note] if chosen.note else []) + coverage_notes(cov)
    return MagFit(chosen, reason + " (override with --mag-form offsets|diagonal|full)", tried, cov, notes, heldout)


def _heldout_model_line(settings: MagSettings) -> str:
    """What the held-out comparison fits with, where the user asked for another loss or method (:func:`heldout_forms`
    fits every form by plain maximum likelihood, the squared loss; the user's settings fit the chosen form only)."""
    given = []
    loss = str(settings.estimator.get("loss") or "squared")
    if loss != "squared":
        given.append(f"--loss {loss}")
    if settings.method not in ML_METHODS:
        given.append(f"--method {settings.method}")
    if not given:
        return ""
    return (f"; the forms compared under plain maximum likelihood (squared loss), not {' and '.join(given)}, "
            "which fit the chosen form only")


def _by_determination(tried: dict[str, FormFit]) -> tuple[FormFit, str]:
    """The richest form whose every parameter is determined to :data:`RELEVANT_SHARE` of the field, else the best determined."""
    for form in ("full", "diagonal", "offsets"):
        if form in tried and tried[form].worst_share < RELEVANT_SHARE:
            chosen = tried[form]
            richer = [f for f in ("full", "diagonal") if f in tried and FORMS[f] > FORMS[form]]
            reason = (f"every parameter determined to {100 * chosen.worst_share:.2g} % of the field "
                      f"(< {100 * RELEVANT_SHARE:g} %)")
            if richer:
                reason += "; " + ", ".join(f"{f}: {100 * tried[f].worst_share:.2g} %" for f in richer)
            return chosen, reason
    chosen = min(tried.values(), key=lambda f: f.worst_share)
    return chosen, (f"no form is determined to {100 * RELEVANT_SHARE:g} % of the field; the best determined one, to "
                    f"{100 * chosen.worst_share:.2g} % (" + ", ".join(f"{f}: {100 * t.worst_share:.2g} %" for f, t in tried.items())
                    + ")")


def _choose_heldout(heldout: HeldOut, fit: Callable[[str], FormFit | None]) -> tuple[FormFit | None, str]:
    """The richest usable form whose held-out error is within its paired standard error of the best usable form's
    (:func:`choose_form`), with the evidence in words; ``None`` when no form is usable (``fit`` fits a form once,
    ``None`` where its fit failed)."""
    forms = list(heldout.mse)  # simplest first (FORMS' order)

    def usable(form: str) -> FormFit | None:
        f = fit(form)
        # a form whose maximum likelihood leaves the physical set under both noise models is not determined (generated
        # 60° caps with a 6 % soft iron: the convex start kept, 9.3-9.8 % by its standard errors, 22-26 % of the field
        # wrong in the uncovered directions, where the sphere is 6 % wrong)
        return f if f is not None and f.worst_share < USABLE_SHARE and not f.ml_left else None

    rms = ", ".join(f"{f} {100 * heldout.rms(f):.3g} %" for f in forms)
    gain = ", ".join(f"{f} {g:.2g} ± {se:.2g}" for f, (g, se) in ((f, heldout.gain(forms[0], f)) for f in forms[1:]))
    evidence = (f"held out by direction ({len(heldout.cells)} of {len(COVERAGE_NAMES)} cells left out of the fit in turn, "
                f"{heldout.n_samples} samples): rms {rms}; mean-square gain over {forms[0]}: {gain}; ")
    form, best, excess = richest_within_se(heldout, forms, lambda f: usable(f) is not None)
    if form is None:
        return None, evidence
    if excess is None:
        return usable(form), evidence + (f"{form}: the smallest held-out error of the usable forms; no richer usable "
                                         "form within its standard error of it")
    return usable(form), (evidence + f"{form}: the richest usable form within its standard error of the best held out "
                                     f"({best}; {100 * heldout.rms(form):.3g} % against {100 * heldout.rms(str(best)):.3g} "
                                     f"%, a mean-square excess {excess[0]:.2g} ± {excess[1]:.2g})")


def _refuse_undetermined(samples: MagSamples, tried: dict[str, FormFit]) -> None:
    cov = coverage((samples.m - tried[next(iter(tried))].o) @ tried[next(iter(tried))].T.T)
    worst = ", ".join(f"{f}: {100 * t.worst_share:.2g} %" for f, t in tried.items())
    raise IdentifiabilityError(
        f"the samples determine no form's parameters to {100 * USABLE_SHARE:g} % of the field ({worst}); "
        f"{coverage_notes(cov)[0] if coverage_notes(cov) else 'turn the sensor through more orientations'}; "
        f"--allow-degenerate or --mag-form offsets fits anyway"
    )



def _check_is_field(fit: FormFit, settings: MagSettings, m: NDArray[np.float64]) -> None:
    if settings.accept_fit:
        return
    not_field = ("check that --columns maps mx, my, mz to the magnetometer (not a gyro or accelerometer); "
                 "--accept-mag-fit keeps it")
    if fit.rms > NOT_A_FIELD_RMS:
        raise InputError(f"the samples are not a magnetic field: they leave the fitted ellipsoid by {100 * fit.rms:.3g} % rms "
                         f"(a field with hard and soft iron: a few %); {not_field}")
    eig = np.linalg.eigvalsh(np.cov(m.T))
    spread = float(np.sqrt(np.max(eig)))
    dwarfed = spread < NOT_A_FIELD_SPAN * fit.field_strength
    cloud = InputError(f"the samples are not a magnetic field: they spread by {spread:.3g}, {100 * spread / fit.field_strength:.2g} % "
                       f"of the fitted field strength {fit.field_strength:.4g} (a field turned through a calibration spans "
                       f"tens of % of its strength); {not_field}")
    if dwarfed and eig[0] >= PLANAR_SPREAD * np.sum(eig):  # a cloud, not a circle: a huge ellipsoid passes through it
        raise cloud
    tilt, axis = planar_tilt(m, fit.rms * fit.field_strength)
    if tilt < PLANAR_SPREAD:
        if settings.allow_degenerate:
            return
        # the turns do not span the sphere: the field strength and the hard iron along the axis are not determined,
        # whatever the fit's standard errors say (a sphere through a circle may be of any size)
        raise IdentifiabilityError(
            f"the magnetometer samples turn in one plane (their tilt out of it, along [{', '.join(f'{c:+.2f}' for c in axis)}], "
            f"less the noise, is {100 * tilt:.2g} % of their spread, a tilt of {np.degrees(np.sqrt(2 * tilt)):.2g}° rms): "
            f"the field strength (fitted {fit.field_strength:.4g}, the circle's) and the hard iron along that axis are not "
            f"determined; turn the sensor about a second axis (roll it 90° and turn it again: optcal plan --sensor mag); --mag-form "
            f"planar calibrates the heading; --allow-degenerate fits the hard iron in the plane anyway, --accept-mag-fit keeps the fit")
    if dwarfed:
        raise cloud
