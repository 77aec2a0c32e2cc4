"""Gathering the evidence a verdict is made from: typed facts about one calibration.

Everything here is measured, nothing is judged (that is :mod:`optcal.applications.quality.verdict`):

* the **noise floor**: the rms of the per-pose noise propagated to the norm residual
  (:func:`optcal.applications.quality.validation.norm_noise`, first order, Lu 2017 eq. 13);
* the **held-out error**: k-fold over poses, each pose judged by a calibration that did not
  see it (:func:`optcal.applications.quality.validation.held_out_validation`, Lu 2017 section 3.2.2), or the
  diagnosis's own held-out error;
* the **model check**: χ² of the fit against its 99 % band under the model (the χ²
  distribution with the fit's degrees of freedom when the per-pose noise is given), or the
  residual rms against the band of the diagnosis's simulations; and χ² and the held-out rms
  against the band of simulations of the fitted model (:mod:`optcal.applications.quality.simulation_band`);
* **determination**: the parameter combinations the poses do not determine or determine only
  weakly (:mod:`optcal.core.identifiability`) and the next poses the pose planner recommends
  (:func:`optcal.applications.plan.next_pose`);
* **coverage**: where the poses point on the sphere;
* **outliers**: poses whose standardised residual exceeds a Bonferroni bound;
* **effects**: what the diagnosis found and its size over the recorded temperature/time range.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import ConvergenceWarning, InputError
from optcal.core.poses import PoseTable
from optcal.applications.quality.bands import BandCheck
from optcal.core.identifiability import IdentifiabilityReport
from optcal.families.accel.result import CalibrationResult
from optcal.core.stats import rms

#: Level of the model check's band and of the outlier test (family-wise over the poses).
BAND_LEVEL: float = 0.99
OUTLIER_ALPHA: float = 0.01
#: Folds of the held-out error (fewer when there are fewer poses).
HELDOUT_FOLDS: int = 10
#: Two unit directions closer than this count as the same orientation, degrees.
SAME_ORIENTATION_DEG: float = 15.0
#: Most pose suggestions made for undetermined or weak combinations.
MAX_SUGGESTIONS: int = 3


@dataclass(frozen=True)
class HeldOut:
    """Held-out error of the calibration (k-fold over poses).

    Attributes
    ----------
    rms_g : float
        rms of the held-out norm residuals, g (NaN when it could not be computed).
    rms_in_sample_g : float
        rms of the in-sample residuals, g.
    folds : int
    source : str
        How it was computed, in words.
    failure : str
        Why it could not be computed ("" when it was).
    """

    rms_g: float
    rms_in_sample_g: float
    folds: int
    source: str
    failure: str = ""

    @property
    def available(self) -> bool:
        return bool(np.isfinite(self.rms_g))


@dataclass(frozen=True)
class Combination:
    """A parameter combination the poses do not determine (or only weakly).

    Attributes
    ----------
    entry : str
        The entry of ``A`` or ``o`` it mainly moves (``"o_z"``).
    text : str
        The full combination in words (from :mod:`optcal.core.identifiability`).
    stderr : float
        Its standard error as a fraction of full scale (inf when not determined at all).
    """

    entry: str
    text: str
    stderr: float


@dataclass(frozen=True)
class Determination:
    """How well the poses determine the nine parameters.

    Attributes
    ----------
    rank, n_params : int
        Numerical rank of the Fisher information, out of ``n_params``.
    condition_number : float
    undetermined, weak : list of Combination
    suggestions : list of str
        How to hold the device for the next poses the pose planner recommends, in order.
    suggestion_directions : ndarray, shape (k, 3)
        Their gravity directions in sensor axes.
    """

    rank: int
    n_params: int
    condition_number: float
    undetermined: list[Combination] = field(default_factory=list)
    weak: list[Combination] = field(default_factory=list)
    suggestions: list[str] = field(default_factory=list)
    suggestion_directions: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))


@dataclass(frozen=True)
class Coverage:
    """Where the poses point.

    Attributes
    ----------
    directions : ndarray, shape (n, 3)
        Calibrated unit specific-force direction of each pose (sensor axes).
    distinct : int
        Distinct orientations (directions more than ``SAME_ORIENTATION_DEG`` apart).
    largest_gap_deg : float
        Radius of the largest cap of the sphere with no pose in it, degrees.
    """

    directions: NDArray[np.float64]
    distinct: int
    largest_gap_deg: float


@dataclass(frozen=True)
class Outliers:
    """Poses whose standardised residual exceeds the Bonferroni bound.

    Attributes
    ----------
    poses : list of str
        Names of the flagged poses (``"pose 12"``).
    z : list of float
        Their standardised residuals.
    residuals_g : list of float
        Their norm residuals, g.
    bound : float
        The bound on ``|z|``.
    source : str
        How they were found.
    """

    poses: list[str]
    z: list[float]
    residuals_g: list[float]
    bound: float
    source: str


@dataclass(frozen=True)
class EffectSize:
    """One effect found by the diagnosis and its size over the recorded range.

    Attributes
    ----------
    effect : str
        Name of the effect (``temperature_bias``).
    axis : str
        Sensor axis (``""`` for outliers).
    coefficient : str
        The first-order coefficient with its standard error, readable units.
    size_mg : float
        Largest change it makes over the recorded range, mg (NaN for outliers).
    over : str
        The range, in words (``"22.0-38.0 °C"``).
    cause : str
        The physical cause, in plain words.
    """

    effect: str
    axis: str
    coefficient: str
    size_mg: float
    over: str
    cause: str


@dataclass(frozen=True)
class Evidence:
    """Everything a verdict on one calibration is made from.

    Attributes
    ----------
    result : CalibrationResult
    n_poses : int
    noise_floor_g : float
        rms of the per-pose noise propagated to the norm, g (NaN when no per-pose noise is known).
    held_out : HeldOut
    model_check : BandCheck
    determination : Determination
    coverage : Coverage
    outliers : Outliers
    effects : list of EffectSize
        Findings of the diagnosis (empty when no diagnosis was run).
    diagnosed : bool
        Whether a diagnosis was run.
    solver_ok : bool
    solver_text : str
    simulated : list of BandCheck
        χ² and the held-out rms against the band of simulations of the fitted model
        (:mod:`optcal.applications.quality.simulation_band`; empty when not computed).
    simulation_note : str
        Why they were not computed ("" when they were).
    """

    result: CalibrationResult
    n_poses: int
    noise_floor_g: float
    held_out: HeldOut
    model_check: BandCheck
    determination: Determination
    coverage: Coverage
    outliers: Outliers
    effects: list[EffectSize] = field(default_factory=list)
    diagnosed: bool = False
    solver_ok: bool = True
    solver_text: str = ""
    simulated: list[BandCheck] = field(default_factory=list)
    simulation_note: str = ""


# ----------------------------------------------------------------------------- pieces
def pose_name(poses: PoseTable, k: int) -> str:
    """Name of pose ``k`` as the user sees it: its interval number (recordings) or file row (tables)."""
    row = int(poses.rows[k])
    return f"pose {row}" if poses.source == "raw recording" else f"pose {k + 1} (row {row})"


def noise_floor(result: CalibrationResult, poses: PoseTable) -> NDArray[np.float64] | None:
    """Per-pose noise of the norm residual, g (``None`` when the poses carry no σ)."""
    from optcal.applications.quality.validation import norm_noise

    if poses.sigma is None:
        return None
    return norm_noise(result.T, result.o, poses.acc, poses.sigma)


def held_out_error(poses: PoseTable, method: str, settings: dict[str, Any], in_sample_g: float,
                   method_name: str | None = None) -> HeldOut:
    """k-fold held-out rms of ``method`` with ``settings`` (the failure in words if a fold cannot be fitted)."""
    from optcal.applications.quality.validation import held_out_validation
    from optcal.core.poses import MIN_POSES

    folds = min(HELDOUT_FOLDS, poses.n)
    source = f"{folds}-fold over poses, method {method_name or method}"
    if poses.n - int(np.ceil(poses.n / folds)) < MIN_POSES:
        return HeldOut(float("nan"), in_sample_g, folds, source,
                       f"{poses.n} poses leave fewer than {MIN_POSES} to fit in each fold")
    try:
        with warnings.catch_warnings():  # a fold's fit that stops early still gives its held-out residuals
            warnings.simplefilter("ignore", ConvergenceWarning)
            ho = held_out_validation(poses, folds=folds, method=method, **settings)
    except InputError as exc:
        return HeldOut(float("nan"), in_sample_g, folds, source, f"a fold could not be fitted: {exc}")
    return HeldOut(ho.rms_held_out, in_sample_g, folds, source)


def chi_square_check(result: CalibrationResult) -> BandCheck:
    """χ² of the fit against the 99 % band of the χ² distribution with the fit's degrees of freedom."""
    from scipy import stats

    what = "χ² of the fit (sum of squared residuals over the per-pose noise)"
    if result.dof <= 0:
        return BandCheck(what, result.chisqr, float("nan"), float("nan"), "no degrees of freedom left", False)
    lo, hi = stats.chi2.ppf([(1 - BAND_LEVEL) / 2, (1 + BAND_LEVEL) / 2], result.dof)
    source = f"{BAND_LEVEL * 100:g} % band of the χ² distribution with {result.dof} degrees of freedom"
    if not result.sigma_known:
        return BandCheck(what, result.chisqr, float(lo), float(hi),
                         source + "; no per-pose noise given, so χ² is matched by construction", False)
    return BandCheck(what, result.chisqr, float(lo), float(hi), source)


def simulation_check(simulation: Any) -> BandCheck:
    """The rms statistic of a diagnosis's :class:`~optcal.applications.diagnosis.simulation.SimulationCheck` as a :class:`BandCheck`."""
    st = simulation.statistics["rms_g"]
    lo, hi = st.band
    return BandCheck(
        "rms of the norm residuals (g)", float(st.measured), float(lo), float(hi),
        f"{simulation.band * 100:g} % band of {simulation.simulations} simulations of the fitted model",
        bool(simulation.simulations) and simulation.noise_scale is not None,
    )


def _sphere_grid(n: int = 2000) -> NDArray[np.float64]:
    """Nearly uniform points on the unit sphere (Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z**2)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def distinct_orientations(directions: NDArray[np.float64]) -> int:
    """Number of unit directions more than ``SAME_ORIENTATION_DEG`` from every earlier kept one."""
    cos_same = np.cos(np.deg2rad(SAME_ORIENTATION_DEG))
    centres: list[NDArray[np.float64]] = []
    for v in directions:
        if all(float(v @ c) < cos_same for c in centres):
            centres.append(v)
    return len(centres)


def coverage(result: CalibrationResult, poses: PoseTable) -> Coverage:
    """Calibrated pose directions, distinct orientations and the largest empty cap."""
    d = result.correct(poses.acc)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    nearest = np.max(_sphere_grid() @ d.T, axis=1)
    gap = float(np.rad2deg(np.arccos(np.clip(nearest.min(), -1, 1))))
    return Coverage(d, distinct_orientations(d), gap)


def robust_outliers(result: CalibrationResult, poses: PoseTable) -> Outliers:
    """Poses whose residual under a Cauchy-loss refit (which one bad pose cannot drag towards
    itself), standardised by its noise and a robust scale (MAD), exceeds the Bonferroni bound
    ``Φ⁻¹(1 − α/(2n))``."""
    from scipy import stats

    from optcal.families.accel.calibration import calibrate
    from optcal.applications.diagnosis.outliers import robust_scale

    try:
        with warnings.catch_warnings():  # only its residuals are used
            warnings.simplefilter("ignore", ConvergenceWarning)
            robust = calibrate(poses, method="mle", loss="cauchy", allow_degenerate=True)
        residuals, how = robust.residuals, "Cauchy-loss refit"
    except InputError:
        residuals, how = result.residuals, "the fit itself"
    sigma_r = noise_floor(result, poses)
    e = residuals / sigma_r if sigma_r is not None else residuals.copy()
    scale = robust_scale(e)
    n = e.size
    bound = float(stats.norm.isf(OUTLIER_ALPHA / (2 * n)))
    if scale <= 1e-12 or n <= result.n_params:
        return Outliers([], [], [], bound, "not tested (too few poses for a robust scale)")
    z = e / scale
    flagged = np.flatnonzero(np.abs(z) > bound)
    return Outliers(
        [pose_name(poses, int(k)) for k in flagged], [float(z[k]) for k in flagged],
        [float(residuals[k]) for k in flagged], bound,
        f"standardised residual of the {how} beyond ±{bound:.2f}, the {OUTLIER_ALPHA:g} level over {n} poses",
    )


def suggest_poses(result: CalibrationResult, poses: PoseTable,
                  count: int = MAX_SUGGESTIONS) -> tuple[list[str], NDArray[np.float64]]:
    """The next poses the pose planner recommends after these (:func:`optcal.applications.plan.next_pose`, D criterion,
    planned for this calibration), one after another; their descriptions and gravity directions."""
    from optcal.applications.plan import Prior, next_pose

    prior = Prior(result.model, result.units, "this calibration")
    acc = poses.acc.copy()
    sigma = None if poses.sigma is None else poses.sigma.copy()
    descriptions: list[str] = []
    directions: list[NDArray[np.float64]] = []
    for _ in range(count):
        nxt = next_pose(PoseTable(acc=acc, sigma=sigma, units=poses.units), prior=prior)
        descriptions.append(nxt.description)
        directions.append(np.asarray(nxt.direction, dtype=float))
        acc = np.vstack([acc, result.model.measure(nxt.direction[None, :])])
        if sigma is not None:
            sigma = np.append(sigma, np.median(sigma))
    return descriptions, np.asarray(directions).reshape(-1, 3)


def determination(result: CalibrationResult, poses: PoseTable) -> Determination:
    """Rank, conditioning, undetermined and weak combinations, and the poses that would help."""
    idf = result.identifiability
    named = idf if isinstance(idf, IdentifiabilityReport) else None
    undetermined = [Combination(u["entry"], u["text"], float("inf")) for u in (named.unidentified if named else [])]
    weak = [Combination(u["entry"], u["text"], float(u.get("stderr", float("nan")))) for u in (named.weak if named else [])]
    suggestions, directions = suggest_poses(result, poses) if (undetermined or weak) else ([], np.zeros((0, 3)))
    return Determination(
        result.n_params if idf is None else idf.rank, result.n_params if idf is None else idf.n_params,
        float("nan") if idf is None else idf.condition_number, undetermined, weak, suggestions, directions,
    )


def outlier_names(poses: PoseTable, finding: Any) -> list[str]:
    """:func:`pose_name` of an outlier finding's poses, with each one's session when several were stacked.

    By their positions among the diagnosed poses (``pose_index``): file row numbers repeat
    across the sessions of ``optcal diagnose A B C``.
    """
    sessions = finding.row_sessions
    return [pose_name(poses, k) + ("" if sessions is None else f" of {sessions[i]}")
            for i, k in enumerate(finding.pose_index or [])]


def effect_sizes(findings: list[Any], poses: PoseTable) -> list[EffectSize]:
    """Size of each :class:`~optcal.applications.diagnosis.findings.Finding` over the recorded temperature or time range, mg."""
    from optcal.core.extended_model import format_value

    out: list[EffectSize] = []
    for f in findings:
        effect = f.effect
        if effect == "outliers":
            rows = list(f.rows or [])
            out.append(EffectSize(effect, "", f"{len(rows)} poses given zero weight", float("nan"),
                                  ", ".join(outlier_names(poses, f)), f.cause))
            continue
        for axis in f.axes:
            if effect == "session_bias":  # the sessions' biases: their range, the spread as the estimate
                out.append(EffectSize(effect, axis, format_value(effect, f.estimate[axis], f.stderr[axis]),
                                      1e3 * f.change_over_data[axis], "the sessions", f.cause))
                continue
            coefs = np.asarray(f.coefficients[axis], dtype=float)
            if effect.startswith("temperature") or effect == "bias_drift":
                column = poses.temp if effect.startswith("temperature") else poses.t
                if column is None:  # impossible: the diagnosis tests such an effect only when its column is usable
                    raise AssertionError(f"a {effect} finding on poses without that column")
                ref = f.reference.get("temp_ref_c" if effect.startswith("temperature") else "t_ref_s", 0.0)
                lo, hi = float(np.min(column)), float(np.max(column))
                x = np.linspace(lo - ref, hi - ref, 201)
                unit = "°C" if effect.startswith("temperature") else "s"
                over = f"{lo:.3g}-{hi:.3g} {unit}"
            else:  # scale_nonlinearity: f² at up to 1 g
                x = np.linspace(-1.0, 1.0, 201)
                over = "±1 g"
            change = sum(c * x ** (p + 1) for p, c in enumerate(coefs))
            size_g = float(np.max(change) - np.min(change)) if effect != "scale_nonlinearity" else float(np.max(np.abs(change)))
            out.append(EffectSize(effect, axis, format_value(effect, f.estimate[axis], f.stderr[axis]),
                                  1e3 * size_g, over, f.cause))
    return out


# ----------------------------------------------------------------------------- gathering
def gather(
    result: CalibrationResult,
    poses: PoseTable,
    method: str | None = None,
    settings: dict[str, Any] | None = None,
    diagnosis: Any | None = None,
) -> Evidence:
    """Collect the evidence on ``result``, a calibration of ``poses``.

    Parameters
    ----------
    result : CalibrationResult
    poses : PoseTable
        The poses it was fitted to (same order).
    method, settings : optional
        Estimator and settings to refit in the held-out folds (default: ``result.method``, none).
    diagnosis : optcal.applications.diagnosis.Diagnosis, optional
        When given, its held-out error, simulation check, outliers and findings are used
        instead of recomputing them.
    """
    if poses.n != result.n_poses:
        raise InputError(f"poses has {poses.n} poses but the result was fitted to {result.n_poses}; pass the same poses")
    sigma_r = noise_floor(result, poses)
    floor = rms(sigma_r) if sigma_r is not None else float("nan")
    simulated: list[BandCheck] = []
    simulation_note = ""  # a diagnosis brings its own simulation check
    if diagnosis is not None:
        folds = int(diagnosis.settings.folds)
        held = HeldOut(diagnosis.baseline_heldout_rms(), diagnosis.baseline_rms(), folds,
                       f"{folds}-fold over poses, the paper's model by maximum likelihood")
        check = simulation_check(diagnosis.simulation)
        found = diagnosis.finding("outliers")
        at = list(found.pose_index or []) if found is not None else []
        names = outlier_names(poses, found) if found is not None else []
        outliers = Outliers(names, [], [float(diagnosis.baseline.residuals[k]) for k in at], float("nan"),
                            "the diagnosis's robust fit and deleted-residual test")
        effects = effect_sizes(diagnosis.findings, poses)
    else:
        held = held_out_error(poses, method or result.method, dict(settings or {}), result.rms_norm_residual_g, result.method)
        check = chi_square_check(result)
        outliers = robust_outliers(result, poses)
        effects = []
        from optcal.applications.quality.simulation_band import simulation_band

        band = simulation_band(result, poses)
        simulated, simulation_note = band.checks, band.note
    return Evidence(
        result=result,
        n_poses=poses.n,
        noise_floor_g=floor,
        held_out=held,
        model_check=check,
        determination=determination(result, poses),
        coverage=coverage(result, poses),
        outliers=outliers,
        effects=effects,
        diagnosed=diagnosis is not None,
        solver_ok=bool(result.solver.success),
        solver_text=f"{result.solver.name}: {result.solver.status}",
        simulated=simulated,
        simulation_note=simulation_note,
    )
