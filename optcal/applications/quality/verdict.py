"""The verdict on a calibration: ``good``, ``usable with care`` or ``not usable``, with reasons.

The verdict is the worst level among the reasons, each judged from the measured
:class:`~optcal.applications.quality.evidence.Evidence` alone (no rendering here):

==========================  ==========================================================================
not usable                  a parameter combination is not determined by the poses (Fisher rank
                            deficit); the solver did not converge; the held-out error exceeds
                            ``NOT_USABLE_FACTOR`` × the tolerance
usable with care            a combination is only weakly determined; the held-out error exceeds the
                            tolerance, or it cannot be measured; the residuals exceed what the model
                            predicts by more than the tolerance (against the χ² distribution, or
                            χ² and the held-out rms against the band of simulations of the fitted
                            model); an effect found by
                            the diagnosis that changes the output by more than the tolerance over the
                            recorded range; an outlier pose off by more than the tolerance
good                        none of the above
==========================  ==========================================================================

The tolerance (default ``DEFAULT_TOLERANCE_MG`` = 1 mg of error in the norm of the calibrated
output) is the accuracy the user asks of the calibration; it is printed with the verdict and
can be set.  The noise floor is always stated next to the held-out error: an error several
times the noise floor but inside the tolerance is reported as model error that does not matter
at that tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from optcal.applications.quality.evidence import Evidence

if TYPE_CHECKING:
    from optcal.applications.fleet.results import FleetResult
    from optcal.applications.plan import NextPose, PosePlan

Level = Literal["good", "usable with care", "not usable"]
#: Levels from best to worst.
LEVELS: tuple[Level, ...] = ("good", "usable with care", "not usable")
#: Default tolerance on the norm of the calibrated output, mg.
DEFAULT_TOLERANCE_MG: float = 1.0
#: A held-out error this many tolerances makes the calibration unusable.
NOT_USABLE_FACTOR: float = 10.0
#: Held-out error up to this many noise floors counts as "at the noise floor".
NOISE_FLOOR_FACTOR: float = 3.0


@dataclass(frozen=True)
class Reason:
    """One reason behind a verdict.

    Attributes
    ----------
    level : str
        The verdict this reason alone would give.
    topic : str
        Short heading (``"held-out error"``).
    text : str
        Plain words with numbers.
    """

    level: Level
    topic: str
    text: str


@dataclass(frozen=True)
class Verdict:
    """The verdict and every reason behind it (worst first).

    Attributes
    ----------
    level : str
        ``good``, ``usable with care`` or ``not usable``.
    reasons : list of Reason
    tolerance_mg : float or None
        The tolerance the calibration was judged against (``None`` when no tolerance applies).
    """

    level: Level
    reasons: list[Reason] = field(default_factory=list)
    tolerance_mg: float | None = DEFAULT_TOLERANCE_MG

    @property
    def css_class(self) -> str:
        """``good``, ``care`` or ``bad`` (for styling)."""
        return {"good": "good", "usable with care": "care", "not usable": "bad"}[self.level]

    def summary(self) -> str:
        """One line: the verdict and its worst reasons."""
        worst = [r.text for r in self.reasons if r.level == self.level]
        return self.level + (": " + " ".join(worst) if self.level != "good" else "")


def _mg(x: float) -> str:
    """A value in g as mg with the digits it needs."""
    return f"{x * 1e3:.3g} mg"


def _unexplained_rms(total_g: float, explained_g: float) -> float:
    """The part of an rms error that ``explained_g`` does not account for, in quadrature: ``√max(total² − explained², 0)``."""
    return float(np.sqrt(max(total_g**2 - explained_g**2, 0.0)))


def _unexplained_level(excess_g: float, tol_g: float) -> tuple[Level, str]:
    """The level an error the model does not explain earns against the tolerance, and the word for it.

    ``("usable with care", "above")`` when ``excess_g`` exceeds the tolerance, else ``("good", "within")``.
    """
    return ("usable with care", "above") if excess_g > tol_g else ("good", "within")


def _beyond_tolerance(head: str, error_g: float, tol_g: float, topic: str) -> Reason | None:
    """An error on poses the fit did not see, when it exceeds the tolerance: ``not usable`` above
    ``NOT_USABLE_FACTOR`` tolerances, ``usable with care`` above one; ``None`` within it."""
    if error_g > NOT_USABLE_FACTOR * tol_g:
        return Reason("not usable", topic, f"{head}: more than {NOT_USABLE_FACTOR:g}× the tolerance of {_mg(tol_g)}.")
    if error_g > tol_g:
        return Reason("usable with care", topic, f"{head}: above the tolerance of {_mg(tol_g)}.")
    return None


def _determination(ev: Evidence) -> list[Reason]:
    det = ev.determination
    out: list[Reason] = []
    fix = (" The pose planner's next poses: " + "; ".join(f"{k}) {d}" for k, d in enumerate(det.suggestions, 1)) + "."
           if det.suggestions else "")
    if det.undetermined:
        names = ", ".join(c.entry for c in det.undetermined)
        combos = "; ".join(c.text for c in det.undetermined)
        out.append(Reason("not usable", "parameters not determined",
                          f"The poses do not determine {names}: any value of it fits the data equally well "
                          f"(Fisher information rank {det.rank} of {det.n_params}; the combination: {combos}).{fix}"))
    if det.weak:
        combos = "; ".join(f"{c.text}, standard error {c.stderr * 100:.2g} % of full scale" for c in det.weak)
        out.append(Reason("usable with care", "parameters weakly determined",
                          f"The poses determine {len(det.weak)} parameter combination(s) only weakly: {combos}.{fix}"))
    if not out:
        out.append(Reason("good", "parameters determined",
                          f"The poses determine all {det.n_params} parameters (Fisher condition number "
                          f"{det.condition_number:.3g})."))
    return out


def _held_out(ev: Evidence, tol_g: float) -> Reason:
    ho = ev.held_out
    if not ho.available:
        head = f"The error on poses not used in the fit could not be measured ({ho.failure}); the in-sample rms is {_mg(ho.rms_in_sample_g)}"
        # an in-sample error is optimistic for new data: above the tolerance on the fit's own poses, it fails it
        beyond = _beyond_tolerance(head + ", on the poses of the fit itself", ho.rms_in_sample_g, tol_g, "held-out error")
        if beyond is not None:
            return beyond
        return Reason("usable with care", "held-out error",
                      f"{head}, within the tolerance of {_mg(tol_g)} but on the fit's own poses, which says little "
                      "about new data.")
    floor = ev.noise_floor_g
    vs_floor = (f", {ho.rms_g / floor:.3g}× the noise floor of {_mg(floor)}" if np.isfinite(floor) and floor > 0
                else " (no per-pose noise known, so no noise floor to compare with)")
    head = f"On poses not used in the fit ({ho.source}) the rms error of |a| is {_mg(ho.rms_g)}{vs_floor}"
    beyond = _beyond_tolerance(head, ho.rms_g, tol_g, "held-out error")
    if beyond is not None:
        return beyond
    if np.isfinite(floor) and ho.rms_g > NOISE_FLOOR_FACTOR * floor:
        excess = _unexplained_rms(ho.rms_g, floor)
        return Reason("good", "held-out error",
                      f"{head}: about {_mg(excess)} is not noise (model error or slow drift), within the "
                      f"tolerance of {_mg(tol_g)}.")
    return Reason("good", "held-out error", f"{head}: within the tolerance of {_mg(tol_g)}.")


def _model_check(ev: Evidence, tol_g: float) -> Reason:
    mc = ev.model_check
    pos = mc.position
    if pos == "untested":
        return Reason("good", "model check", f"{mc.statistic}: {mc.measured:.4g}; not a test here ({mc.source}).")
    text = f"{mc.statistic}: {mc.measured:.4g} against {mc.low:.4g} .. {mc.high:.4g} ({mc.source})"
    if pos == "inside":
        return Reason("good", "model check", f"{text}: the model explains the scatter of the poses.")
    if pos == "below":
        return Reason("good", "model check",
                      f"{text}: the residuals are smaller than the per-pose noise predicts (the noise is overstated).")
    rms = ev.result.rms_norm_residual_g
    floor = ev.noise_floor_g if np.isfinite(ev.noise_floor_g) else 0.0
    excess = _unexplained_rms(rms, floor)
    level, judgement = _unexplained_level(excess, tol_g)
    return Reason(level, "model check",
                  f"{text}: the poses scatter more than their noise explains; the part not explained is about "
                  f"{_mg(excess)} rms, {judgement} the tolerance of {_mg(tol_g)}.")


def _simulation_band(ev: Evidence, tol_g: float) -> list[Reason]:
    """χ² and the held-out rms among refits of simulations of the fitted model.

    Above the band, the part of the error the simulations do not produce is
    ``√(measured² − median²)`` of the rms (χ² as its rms ``σ_floor·√(χ²/n)``); it is judged against the tolerance.
    """
    from optcal.applications.quality.simulation_band import band_text

    if not ev.simulated:
        return [Reason("good", "simulation band", f"Not computed: {ev.simulation_note}.")] if ev.simulation_note else []
    out: list[Reason] = []
    for check in ev.simulated:
        text = band_text(check)
        if check.position != "above":
            out.append(Reason("good", "simulation band", f"{text}: as the calibration model predicts."))
            continue
        if check.unit == "g":
            excess = _unexplained_rms(check.measured, check.median)
        else:
            floor = ev.noise_floor_g if np.isfinite(ev.noise_floor_g) else 0.0
            excess = floor * float(np.sqrt(max(check.measured - check.median, 0.0) / max(ev.n_poses, 1)))
        level, judgement = _unexplained_level(excess, tol_g)
        out.append(Reason(level, "simulation band",
                          f"{text}: above what the model produces; the part not explained is about {_mg(excess)} rms, "
                          f"{judgement} the tolerance of {_mg(tol_g)}."))
    return out


def _outliers(ev: Evidence, tol_g: float) -> Reason:
    o = ev.outliers
    if not o.poses:
        return Reason("good", "outliers", f"No outlier poses ({o.source}).")
    sizes = ", ".join(f"{name} ({r * 1e3:+.3g} mg)" for name, r in zip(o.poses, o.residuals_g))
    if max(abs(r) for r in o.residuals_g) > tol_g:
        return Reason("usable with care", "outliers",
                      f"{len(o.poses)} pose(s) do not fit the others: {sizes} ({o.source}), more than the tolerance "
                      f"of {_mg(tol_g)}. Check whether the sensor moved; repeat or drop them.")
    return Reason("good", "outliers",
                  f"{len(o.poses)} pose(s) stand out from their noise: {sizes} ({o.source}), but by less than the "
                  f"tolerance of {_mg(tol_g)}.")


def _coverage(ev: Evidence) -> Reason:
    c = ev.coverage
    return Reason("good", "orientation coverage",
                  f"{ev.n_poses} poses in {c.distinct} distinct orientations; the largest region of the sphere "
                  f"without a pose has a radius of {c.largest_gap_deg:.0f}°.")


def _effects(ev: Evidence, tol_g: float) -> list[Reason]:
    if not ev.diagnosed:
        return []
    if not ev.effects:
        return [Reason("good", "diagnosis", "The diagnosis found no effect beyond the paper's model.")]
    out: list[Reason] = []
    for e in ev.effects:
        if e.effect == "outliers":
            continue  # counted under outliers
        level, judgement = _unexplained_level(e.size_mg * 1e-3, tol_g)
        out.append(Reason(level, "diagnosis",
                          f"{e.effect} on axis {e.axis}: {e.coefficient}, which changes the output by {e.size_mg:.3g} mg "
                          f"over {e.over} ({judgement} the tolerance of {_mg(tol_g)}): "
                          f"{e.cause}. The constant calibration cannot follow it; the extended model of the diagnosis does."))
    return out


def judge(evidence: Evidence, tolerance_mg: float = DEFAULT_TOLERANCE_MG) -> Verdict:
    """The verdict on the calibration behind ``evidence`` (see the module docstring for the rules).

    Parameters
    ----------
    evidence : Evidence
        From :func:`optcal.applications.quality.evidence.gather`.
    tolerance_mg : float
        Accuracy asked of the calibrated norm, mg.

    Returns
    -------
    Verdict
    """
    from optcal.errors import InputError

    if not tolerance_mg > 0:
        raise InputError(f"tolerance_mg must be positive, got {tolerance_mg}")
    tol_g = tolerance_mg * 1e-3
    reasons = _determination(evidence)
    if not evidence.solver_ok:
        reasons.append(Reason("not usable", "solver",
                              f"The solver did not converge ({evidence.solver_text}): the numbers below are not an optimum."))
    reasons += [_held_out(evidence, tol_g), _model_check(evidence, tol_g), *_simulation_band(evidence, tol_g),
                _outliers(evidence, tol_g), _coverage(evidence)]
    reasons += _effects(evidence, tol_g)
    reasons.sort(key=lambda r: -LEVELS.index(r.level))
    level = max((r.level for r in reasons), key=LEVELS.index)
    return Verdict(level, reasons, tolerance_mg)


def judge_check(rms_after_g: float, rms_noise_g: float, n_poses: int,
                tolerance_mg: float = DEFAULT_TOLERANCE_MG) -> Verdict:
    """Verdict on a saved calibration applied to other data (``optcal check``).

    The rms of |a| − 1 g after calibration on poses the calibration never saw is a held-out
    error: judged like the held-out error of :func:`judge` (tolerance, ``NOT_USABLE_FACTOR``).
    """
    tol_g = tolerance_mg * 1e-3
    floor = (f", {rms_after_g / rms_noise_g:.3g}× the noise floor of {_mg(rms_noise_g)}"
             if np.isfinite(rms_noise_g) and rms_noise_g > 0 else "")
    head = f"On these {n_poses} poses the rms error of |a| after calibration is {_mg(rms_after_g)}{floor}"
    reason = (_beyond_tolerance(head, rms_after_g, tol_g, "error on new data")
              or Reason("good", "error on new data", f"{head}: within the tolerance of {_mg(tol_g)}."))
    return Verdict(reason.level, [reason], tolerance_mg)


def judge_segmentation(n_poses: int, distinct: int) -> Verdict:
    """Verdict on the static poses found in a recording (``optcal segment``): can they make a calibration?

    Nine parameters need at least nine poses (:data:`optcal.core.poses.MIN_POSES`) in at least nine
    distinct orientations; fewer distinct orientations may leave combinations undetermined
    (``optcal calibrate`` tells which).
    """
    from optcal.core.model import N_PARAMS
    from optcal.core.poses import MIN_POSES

    text = f"{n_poses} static poses in {distinct} distinct orientations (more than 15° apart)"
    if n_poses < MIN_POSES:
        reason = Reason("not usable", "static poses", f"{text}: a calibration needs at least {MIN_POSES} poses.")
    elif distinct < N_PARAMS:
        reason = Reason("usable with care", "static poses",
                        f"{text}: fewer orientations than the {N_PARAMS} parameters, so some may not be determined "
                        "(optcal calibrate names them).")
    else:
        reason = Reason("good", "static poses", f"{text}: enough for the {N_PARAMS} parameters.")
    return Verdict(reason.level, [reason], None)


#: Units named in one reason of a fleet verdict (the rest are counted).
NAMED_UNITS: int = 12


def _some(names: list[str]) -> str:
    """``a, b, c`` or ``a, b, ... and N more``."""
    shown = ", ".join(names[:NAMED_UNITS])
    return shown + (f" and {len(names) - NAMED_UNITS} more" if len(names) > NAMED_UNITS else "")


def judge_fleet(result: "FleetResult", tolerance_mg: float = DEFAULT_TOLERANCE_MG,
                flag_words: dict[str, str] | None = None) -> Verdict:
    """Verdict on a fleet as a whole (``optcal fleet``): can its calibrations be used, and which units need a look?

    ==========================  ==================================================================
    not usable                  no unit calibrated, or fewer than half of the units
    usable with care            a unit failed or was refused; a unit lies outside the population's
                                bands (flagged); a unit was calibrated with the population prior
                                (its undetermined parameters come from the fleet, not from its
                                data); a unit's held-out rms exceeds the tolerance; fewer than
                                five units calibrated by their own data (no population check)
    good                        none of the above
    ==========================  ==================================================================

    Parameters
    ----------
    result : optcal.applications.fleet.results.FleetResult
    tolerance_mg : float
        Accuracy asked of each unit's calibrated norm (its held-out rms), mg.
    flag_words : dict of str to str, optional
        The reason of each flagged unit in plain words (default: the fleet's own flag reason).
    """
    from optcal.errors import InputError

    if not tolerance_mg > 0:
        raise InputError(f"tolerance_mg must be positive, got {tolerance_mg}")
    tol_g = tolerance_mg * 1e-3
    n = len(result.outcomes)
    calibrated = [o for o in result.outcomes if o.calibrated]
    reasons: list[Reason] = []
    own, with_prior = result.count("calibrated"), result.count("calibrated_with_prior")
    counts = (f"{n} units: {own} calibrated by their own data, {with_prior} with the population prior, "
              f"{result.count('refused')} refused, {result.count('failed')} failed")
    if not calibrated or len(calibrated) < n / 2:
        reasons.append(Reason("not usable", "units calibrated",
                              f"{counts}: fewer than half of the units have a calibration. Check the files and the "
                              "data options (--columns, --units, the static detection) on one unit with optcal calibrate."))
    else:
        reasons.append(Reason("good", "units calibrated", f"{counts}."))
    bad = result.not_calibrated
    if bad:
        reasons.append(Reason("usable with care", "units without a calibration",
                              f"{len(bad)} unit(s) have no calibration: "
                              + _some([f"{o.unit} ({o.status}: {o.reason})" for o in bad]) + "."))
    if result.stats is None:
        reasons.append(Reason("usable with care", "population check",
                              "Fewer than five units were calibrated by their own data in the same units, so no unit "
                              "could be compared with the population."))
    flagged = result.flagged
    words = flag_words or {}
    if flagged:
        reasons.append(Reason("usable with care", "units unlike the others",
                              f"{len(flagged)} unit(s) lie outside the population's robust band"
                              + (f" (median ± {result.stats.threshold_n:.3g} robust SD)" if result.stats else "") + ": "
                              + _some([f"{o.unit}: {words.get(o.unit, o.flag)}" for o in flagged])
                              + ". Check them before use: a damaged part, a different part number or a bad session."))
    elif result.stats is not None:
        reasons.append(Reason("good", "units unlike the others",
                              f"No unit lies outside the population's robust band (median ± "
                              f"{result.stats.threshold_n:.3g} robust SD of every parameter and of the residual)."))
    if with_prior:
        names = [o.unit for o in result.outcomes if o.status == "calibrated_with_prior"]
        reasons.append(Reason("usable with care", "calibrated with the population prior",
                              f"{with_prior} unit(s) do not determine every parameter by their own poses; the missing "
                              f"part comes from the population prior: {_some(names)}. Their calibration is as good as "
                              "the population is alike; record more orientations to calibrate them alone."))
    high = [o for o in calibrated if np.isfinite(o.heldout_rms_g) and o.heldout_rms_g > tol_g]
    held = np.array([o.heldout_rms_g for o in calibrated if np.isfinite(o.heldout_rms_g)])
    if high:
        reasons.append(Reason("usable with care", "held-out error",
                              f"{len(high)} of {len(calibrated)} calibrated units have a held-out rms error of |a| "
                              f"(leave-one-out) above the tolerance of {_mg(tol_g)}: "
                              + _some([f"{o.unit} ({_mg(o.heldout_rms_g)})" for o in high]) + "."))
    elif held.size:
        reasons.append(Reason("good", "held-out error",
                              f"Every calibrated unit's held-out rms error of |a| (leave-one-out) is within the tolerance "
                              f"of {_mg(tol_g)}: median {_mg(float(np.median(held)))}, largest {_mg(float(held.max()))}."))
    reasons.sort(key=lambda r: -LEVELS.index(r.level))
    level = max((r.level for r in reasons), key=LEVELS.index)
    return Verdict(level, reasons, tolerance_mg)


#: A plan whose efficiency against the certified bound is below this is "usable with care".
PLAN_EFFICIENCY_GOOD: float = 0.9


def judge_plan(plan: "PosePlan") -> Verdict:
    """Verdict on a pose plan (``optcal plan --poses K``): how close it comes to the best any K poses can do.

    ``good`` when its efficiency against the relaxation's certified bound is at least
    ``PLAN_EFFICIENCY_GOOD``; ``usable with care`` below (the feasible set or the grid limits the
    plan).  The planner refuses plans that leave a combination undetermined, so none is judged here.
    """
    name = {"D": "D-efficiency", "A": "A-efficiency", "E": "E-efficiency"}[plan.criterion.value]
    text = (f"The {plan.n_poses} poses reach {100 * plan.efficiency:.1f} % of the best any {plan.n_poses} poses in the "
            f"feasible set ({plan.feasible_set}) can reach ({name} against the relaxation's certified bound)")
    if plan.efficiency >= PLAN_EFFICIENCY_GOOD:
        reason = Reason("good", "design", f"{text}.")
    else:
        reason = Reason("usable with care", "design",
                        f"{text}: the constraint limits the plan; more poses or a wider feasible set determine the "
                        "calibration better.")
    return Verdict(reason.level, [reason], None)


def judge_next_pose(step: "NextPose") -> Verdict:
    """Verdict on the poses taken so far (``optcal plan --next DATA``): can they make a calibration, or take the next?

    ``not usable`` while they do not determine every parameter; ``usable with care`` while a
    standard error is above the target, or, without a target, above the fraction of full scale
    at which a calibration calls a parameter weakly determined
    (:data:`optcal.core.identifiability.WEAK_STDERR`); ``good`` once every one is below it.
    """
    from optcal.core.identifiability import WEAK_STDERR
    from optcal.core.model import N_PARAMS

    have = f"The {step.n_poses} poses taken"
    worst = max(step.stderr_normalised, key=lambda k: step.stderr_normalised[k])
    if step.rank_before < N_PARAMS:
        reason = Reason("not usable", "poses so far",
                        f"{have} do not determine the calibration (Fisher information rank {step.rank_before} of "
                        f"{N_PARAMS}); the next pose ({step.description}) raises the rank to {step.rank_after}.")
    elif step.stop:
        reason = Reason("good", "poses so far", f"{have} determine every parameter; {step.stop_message}.")
    elif step.target_stderr is not None or step.stderr_normalised[worst] > WEAK_STDERR:
        bar = (f"the target {step.target_stderr:g}" if step.target_stderr is not None else
               f"{WEAK_STDERR:g}, where a calibration calls it weakly determined")
        reason = Reason("usable with care", "poses so far",
                        f"{have} determine every parameter, but {worst} has a standard error of "
                        f"{step.stderr_normalised[worst]:.3g} (normalised), above {bar}: "
                        f"take the next pose ({step.description}).")
    else:
        reason = Reason("good", "poses so far",
                        f"{have} determine every parameter; the next pose ({step.description}) adds "
                        f"{step.gain_logdet:.3g} to the log determinant of the information.")
    return Verdict(reason.level, [reason], None)


__all__ = ["DEFAULT_TOLERANCE_MG", "LEVELS", "Level", "PLAN_EFFICIENCY_GOOD", "Reason", "Verdict", "judge", "judge_check",
           "judge_fleet", "judge_next_pose", "judge_plan", "judge_segmentation"]
