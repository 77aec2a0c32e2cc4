"""The diagnosis: where the calibrated model's simulation disagrees with the measurements, why, and the gain.

``Diagnoser(settings).run(poses) -> Diagnosis`` runs four steps:

1. **Baseline** — the paper's model ``a = C ā + o + n`` (Lu 2017, eq. 5), started from the
   calibration of the chosen method (default ``mle``, eq. 13-14) or from a given calibration,
   refitted by maximum likelihood on the norm residuals (the tests compare nested models at
   their optimum), with its held-out error (k-fold over poses).
2. **Simulation check** (:mod:`optcal.applications.diagnosis.simulation`) — what the simulation of the
   fitted model gets wrong.
3. **Selection** (:mod:`optcal.applications.diagnosis.selection`) — forward selection over the effects of
   :mod:`optcal.applications.diagnosis.effects`, per axis, each fitted jointly with ``T`` and ``o``.
4. **Findings** (:mod:`optcal.applications.diagnosis.findings`) — every effect of the final model with
   estimates, standard errors, evidence and the held-out gain.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.acceptance import HELDOUT_SE
from optcal.applications.diagnosis.effects import BIAS_STEP, FITTED, SESSION_BIAS, VOCABULARY, parse_effects
from optcal.applications.diagnosis.findings import build_findings
from optcal.applications.diagnosis.fitting import MIN_DOF, MIN_DOF_MEASURED, Fit, Fitter, measured_scale2
from optcal.applications.diagnosis.noise_model import check_noise_model, pose_correlation
from optcal.applications.diagnosis.pose_noise import (
    POSE_NOISE_CHOICES, effects_under_pose_noise, misweighs, pose_noise_floor, with_floor,
)
from optcal.applications.diagnosis.selection import SelectionResult
from optcal.applications.diagnosis.random_walk import RandomWalkCheck, check_random_walk
from optcal.applications.diagnosis.progress import Progress
from optcal.applications.diagnosis.regressors import Regressors
from optcal.applications.diagnosis.result import Diagnosis
from optcal.applications.diagnosis.limits import step_limits, detection_limits, outlier_limit
from optcal.applications.diagnosis.selection import ForwardSelection
from optcal.applications.diagnosis.sessions import SessionStack, stack_sessions
from optcal.applications.diagnosis.still_noise import MeasuredPoseNoise, pose_noise_from_still_parts, stack_measured
from optcal.applications.diagnosis.simulation import simulation_check
from optcal.errors import InputError
from optcal.core.model import AXES, canonicalise
from optcal.core.poses import PoseTable
from optcal.core.stats import rms

if TYPE_CHECKING:
    from optcal.data.static import Segmentation

#: How the pose noise correlated in time is used (:class:`DiagnosisSettings`).
POSE_CORRELATION_CHOICES: tuple[str, ...] = ("auto", "off", "on")
#: Parametric-bootstrap replications of the noise-model check (at most; fewer when fewer simulations are asked for).
NOISE_SIMULATIONS: int = 100


class LumpedCalibration(Protocol):
    """Anything with a scale-and-skew matrix ``T`` and a bias ``o`` (a calibration result or file)."""

    T: NDArray[np.float64]
    o: NDArray[np.float64]


@dataclass(frozen=True)
class DiagnosisSettings:
    """Settings of a diagnosis.

    Attributes
    ----------
    effects : str, tuple of str or None
        Candidate effects (names from :data:`~optcal.applications.diagnosis.effects.VOCABULARY`, or
        ``"none"``); ``None``: every effect the data's columns support.  Asking for an effect
        the data cannot support raises :class:`~optcal.errors.InputError`.
    folds : int
        k of the k-fold held-out error.
    simulations : int
        Parametric-bootstrap replications of the simulation check.
    alpha : float
        Family-wise false-finding level of a selection step.
    band : float
        Coverage of the simulated bands.
    seed : int
        Seed of the simulations.
    method : str
        Calibration method of the baseline (any of :func:`optcal.calibrate`'s).
    pose_correlation : {"auto", "off", "on"}
        The pose noise correlated in time (:mod:`optcal.applications.diagnosis.correlation`): ``auto`` uses it
        on evidence (its own test, or the still parts' noise at the pose time scale), ``off`` treats
        the poses as independent, ``on`` uses the estimate whatever the evidence.
    calibration : dict
        Further settings of the baseline's estimator (``solver``, ``solver_options``, ``fix``,
        ``bounds``, ``conic_solver``: :func:`optcal.calibrate`'s keywords).
    drop_unneeded : bool
        After each accepted term, drop an earlier one the later terms made unneeded
        (:meth:`~optcal.applications.diagnosis.selection.ForwardSelection.backward_check`); ``False`` (``optcal
        diagnose --keep-terms``): plain forward selection, every accepted term kept.
    term_pairs : bool
        When no one-term candidate of a step passes, search the best pair of first-order terms (or one effect on
        every axis) together, with a share of the step's level (:mod:`~optcal.applications.diagnosis.term_pair`);
        ``False`` (``optcal diagnose --no-term-pairs``): one term at a time, each at the whole terms' share.
    heldout_se : float, optional
        Standard errors of its paired held-out gain a term must show to enter the model
        (:func:`~optcal.applications.diagnosis.acceptance.accept`); ``None``:
        :data:`~optcal.applications.diagnosis.acceptance.HELDOUT_SE`; 0: any fall of the held-out rms
        (``optcal diagnose --heldout-se K``).
    """

    effects: str | tuple[str, ...] | None = None
    folds: int = 10
    simulations: int = 200
    alpha: float = 0.02
    band: float = 0.99
    seed: int = 0
    method: str = "mle"
    pose_correlation: str = "auto"
    calibration: dict[str, Any] = field(default_factory=dict, hash=False)
    drop_unneeded: bool = True
    term_pairs: bool = True
    pose_noise: str = "given"
    heldout_se: float | None = None

    def __post_init__(self) -> None:
        if self.heldout_se is not None and not 0.0 <= self.heldout_se < math.inf:
            raise InputError(f"the held-out standard errors must be finite and at least 0, got {self.heldout_se} "
                             "(--heldout-se)")
        if self.pose_correlation not in POSE_CORRELATION_CHOICES:
            raise InputError(f"pose_correlation must be one of {', '.join(POSE_CORRELATION_CHOICES)}, "
                             f"got {self.pose_correlation!r}")
        if self.pose_noise not in POSE_NOISE_CHOICES:
            raise InputError(f"pose_noise must be one of {', '.join(POSE_NOISE_CHOICES)}, got {self.pose_noise!r}")
        if not 0 < self.alpha < 1:
            raise InputError(f"alpha must be between 0 and 1, got {self.alpha}")
        if not 0 < self.band < 1:
            raise InputError(f"band must be between 0 and 1, got {self.band}")
        if self.folds < 2:
            raise InputError(f"folds must be at least 2, got {self.folds}")
        if self.simulations < 0:
            raise InputError(f"simulations must be non-negative, got {self.simulations}")
        if self.effects is not None and not isinstance(self.effects, str):
            object.__setattr__(self, "effects", tuple(self.effects))

    def to_dict(self) -> dict[str, Any]:
        return {"folds": self.folds, "simulations": self.simulations, "alpha": self.alpha, "band": self.band,
                "seed": self.seed, "min_dof": MIN_DOF, "min_dof_measured": MIN_DOF_MEASURED, "method": self.method, "pose_correlation": self.pose_correlation,
                "calibration": dict(self.calibration),
                "effects": None if self.effects is None else (
                    self.effects if isinstance(self.effects, str) else ",".join(self.effects)),
                # said only when the backward check is off (--keep-terms): the default's record is unchanged
                **({} if self.drop_unneeded else {"drop_unneeded": False}),
                **({} if self.term_pairs else {"term_pairs": False}),
                **({} if self.pose_noise == "given" else {"pose_noise": self.pose_noise}),
                "heldout_se": HELDOUT_SE if self.heldout_se is None else self.heldout_se}


#: Why a bias step is not searched when several sessions are diagnosed together.
STEP_SESSIONS: str = ("several sessions are diagnosed together (their biases differ by session_bias; a step inside "
                      "one session is searched when that session is diagnosed alone)")


def choose_effects(asked_text: str | Iterable[str] | None, reg: Regressors) -> tuple[tuple[str, ...], dict[str, str]]:
    """The effects to test and the ones skipped with the reason."""
    asked = parse_effects(asked_text)
    skipped: dict[str, str] = {}
    if asked is None:
        chosen = []
        for e in VOCABULARY:
            if e == BIAS_STEP and reg.n_sessions > 1:
                skipped[e] = STEP_SESSIONS
            elif reg.supports(e):
                chosen.append(e)
            elif e != SESSION_BIAS:  # one recording: sessions are not a question
                skipped[e] = reg.reason_unsupported(e)
        return tuple(chosen), skipped
    if not asked:
        return (), {e: "not asked for (effects 'none')" for e in VOCABULARY if e != SESSION_BIAS or reg.n_sessions > 1}
    bad = [f"{e}: {reg.reason_unsupported(e)}" for e in asked if not reg.supports(e)]
    if BIAS_STEP in asked and reg.n_sessions > 1:
        raise InputError(f"cannot test {BIAS_STEP}: {STEP_SESSIONS}; diagnose each session alone for a step "
                         f"inside it, or leave {BIAS_STEP} out of the candidate effects")
    if bad:
        fix = ("give several sessions of the sensor (a list of pose tables)" if SESSION_BIAS in " ".join(bad)
               else "give data with a varying temp column (°C) and a time column")
        raise InputError("cannot test " + "; ".join(bad) + f". {fix.capitalize()}, "
                         "or leave those effects out of the candidate effects")
    return asked, skipped


def entry_levels(selection: SelectionResult) -> dict[tuple[str, int], float]:
    """The level each term of the selection entered at (two entered together: each at the pair's)."""
    levels: dict[tuple[str, int], float] = {}
    for step in selection.steps:
        c = step.accepted
        if c is None:
            continue
        keys = c.together or (((c.effect, AXES.index(c.axis)),) if c.axis in AXES else ())
        for key in keys:
            levels.setdefault(key, c.threshold)
    return levels


def check_size(n: int) -> None:
    """Refuse a pose table below the baseline's own minimum (candidates are tested one at a time)."""
    if n < 9 + 3:
        more = 12 - n
        raise InputError(
            f"{n} poses are too few for a diagnosis: at least 12 are needed (9 calibration parameters and 3 residual "
            "degrees of freedom: a candidate effect, and the residuals that check the noise measured in the rests); "
            f"record {more} more rest{'s' if more > 1 else ''} in new orientations, or fit the "
            "paper's model alone with `optcal calibrate` (from 9 poses)"
        )


class Diagnoser:
    """Runs diagnoses with fixed settings (module docstring).

    Parameters
    ----------
    settings : DiagnosisSettings, optional
    progress : Progress or callable, optional
        How to report progress (:class:`~optcal.applications.diagnosis.progress.Progress`), or a callable
        receiving a short message at each stage.  Silent by default.
    """

    def __init__(self, settings: DiagnosisSettings | None = None,
                 progress: Progress | Callable[[str], None] | None = None) -> None:
        self.settings = settings or DiagnosisSettings()
        self.reporter = progress if isinstance(progress, Progress) else Progress(message=progress)

    def progress(self, text: str) -> None:
        """Report a stage."""
        self.reporter.say(text)

    def start(self, poses: PoseTable, baseline: LumpedCalibration | None) -> tuple[Any, Any, str]:
        """``T``, ``o`` of the baseline calibration and where it came from."""
        if baseline is not None:
            T, o = getattr(baseline, "T", None), getattr(baseline, "o", None)
            if T is None or o is None:
                raise InputError("baseline must be a calibration with a T matrix and a bias o (e.g. optcal.calibrate's result)")
            units = getattr(baseline, "units", None)
            if units is not None and units != poses.units:
                raise InputError(
                    f"the baseline calibration is for data in {units} but the poses are in {poses.units}; "
                    f"give a baseline fitted on {poses.units} data, or the data in {units}"
                )
            label = getattr(baseline, "label", None)  # a peer's calibration (imucal, imu_tk) is named by its tool
            return canonicalise(T), np.asarray(o, float), f"the given {label} calibration" if label else "the given calibration"
        from optcal.families.accel.calibration import calibrate

        with self.reporter.stage(f"fitting the paper's model ({self.settings.method})"):
            result = calibrate(poses, self.settings.method, **self.settings.calibration)
        return canonicalise(result.T), np.asarray(result.o, float), f"the {self.settings.method} calibration"

    def prepare(self, poses: PoseTable, baseline: LumpedCalibration | None = None,
                regressors: Regressors | None = None) -> tuple[Fitter, str]:
        """The :class:`Fitter` of ``poses`` started from the baseline calibration, and where that came from."""
        T, o, source = self.start(poses, baseline)
        return Fitter(poses, regressors or Regressors.of(poses), T, o, self.settings.folds, self.reporter.loop), source

    def run_sessions(self, sessions: Sequence[PoseTable], baseline: LumpedCalibration | None = None,
                     names: Sequence[str] | None = None,
                     still_parts: Sequence["Segmentation | None"] | None = None) -> Diagnosis:
        """Diagnose several sessions of one sensor together (:mod:`optcal.applications.diagnosis.sessions`).

        One calibration ``T``, ``o`` is fitted to every session's poses; "the bias changed
        between sessions" (``session_bias``) is a candidate effect; time terms count from each
        session's own start, temperature terms are pooled.  ``still_parts`` (optional): each
        session's static detection (``None`` for a pose table), for the measured noise route.
        """
        if isinstance(sessions, PoseTable) or not all(isinstance(p, PoseTable) for p in sessions):
            raise InputError("Diagnoser.run_sessions() takes a list of PoseTables, one per session; "
                             "load each with optcal.data.load")
        for p in sessions:
            p.validate()
        parts = [None] * len(sessions) if still_parts is None else list(still_parts)
        if len(parts) != len(sessions):
            raise InputError(f"still_parts has {len(parts)} entries for {len(sessions)} sessions; give one per session")
        measured = stack_measured([pose_noise_from_still_parts(p, seg) for p, seg in zip(sessions, parts)])
        return self.run_stack(stack_sessions(sessions, names), baseline, measured=measured)

    def run(self, poses: PoseTable, baseline: LumpedCalibration | None = None,
            still_parts: "Segmentation | None" = None) -> Diagnosis:
        """Diagnose ``poses``; ``baseline`` (optional) replaces the settings' method as the baseline calibration.

        ``still_parts`` (optional) is the static detection ``poses`` came from
        (:func:`optcal.data.load_with_segmentation`): the noise of each pose mean is then also
        measured on the recording's still parts (:mod:`optcal.applications.diagnosis.still_noise`).
        """
        if not isinstance(poses, PoseTable):
            raise InputError("Diagnoser.run() takes a PoseTable; load data with optcal.data.load")
        return self.run_stack(None, baseline, poses, pose_noise_from_still_parts(poses, still_parts))

    def run_stack(self, stack: SessionStack | None, baseline: LumpedCalibration | None = None,
                  poses: PoseTable | None = None, measured: MeasuredPoseNoise | None = None) -> Diagnosis:
        """Diagnose the sessions of ``stack``, or the one recording ``poses`` when ``stack`` is ``None``."""
        poses = stack.poses if stack is not None else poses
        assert poses is not None
        poses.validate()
        s = self.settings
        reg = Regressors.of(poses, None if stack is None else stack.session)
        notes: list[str] = []

        def note(text: str) -> None:
            if text not in notes:
                notes.append(text)

        if stack is not None:
            counts = ", ".join(f"{name}: {count}" for name, count in zip(stack.names, stack.counts()))
            note(f"{stack.n_sessions} sessions of one sensor diagnosed together ({counts} poses); one calibration "
                 "fitted to all; time counts from each session's own start (so does a saved drift term's t), "
                 "temperature is pooled")

        effects, skipped = choose_effects(s.effects, reg)
        candidates = [(e, a) for e in effects if e in FITTED for a in range(3)]
        check_size(poses.n)
        T, o, source = self.start(poses, baseline)
        loop = self.reporter.loop
        fitter = Fitter(poses, reg, T, o, s.folds, loop)
        base = fitter.fit({}, frozenset(), fitter.x_start)
        # whether the σ's ratios describe the poses' scatter; when a pose-to-pose noise does, every pose's σ is widened
        floor = pose_noise_floor(fitter, base, s.alpha, s.pose_noise)
        if floor.used:
            poses = with_floor(poses, floor)
            fitter = Fitter(poses, reg, T, o, s.folds, loop)
            base = fitter.fit({}, frozenset(), base.x)
        # the noise of the pose means measured in the rests: a small session is tested from 1 residual degree of freedom
        fitter.measured_scale2 = measured_scale2(poses, fitter.w_mean, None if measured is None else measured.sigma)
        given = fitter.evaluate(fitter.x_start)
        correlation = pose_correlation(fitter, base, s.alpha, measured, s.pose_correlation)
        if correlation.used:  # the tests, standard errors and limits under the correlated pose noise
            fitter.correlation = correlation.operator
            base = fitter.fit({}, frozenset(), base.x)
        self.progress("k-fold held-out error of the baseline")
        base_heldout = fitter.heldout(base)
        self.progress(f"simulating the fitted model {s.simulations} times")
        # a bias step has no column before its position is chosen: it is not among the simulated statistics
        open_terms = [(e, a) for e, a in candidates if e != BIAS_STEP]
        sim = simulation_check(fitter, base, open_terms, s.simulations, s.band, s.seed, loop)
        self.progress("forward selection over the candidate effects")
        selector = ForwardSelection(fitter, candidates, "outliers" in effects, s.alpha, note, loop, s.drop_unneeded,
                                    s.term_pairs)
        selector.correlation = correlation if correlation.used else None
        if s.heldout_se is not None:
            selector.heldout_se = s.heldout_se
        selection = selector.run(base)
        final = selection.final
        self.progress("measuring the findings (held-out error without each effect)")
        findings = build_findings(fitter, final, selection.steps, () if stack is None else stack.names)
        self.progress("detection limits of the candidates not found")
        limits = detection_limits(fitter, final, open_terms, selection.last_level, loop) if open_terms else []
        # a bias step not named: its own limit per axis searched, at the level its test had (alpha_step shared by the
        # axes and the pair searched together, the positions paid for as adjusted_p pays for them)
        step_axes = selector.step_axes(final)
        if step_axes:
            limits += step_limits(fitter, final, step_axes, selector.single_step_level(final, step_axes))
        pose_limit = outlier_limit(fitter, final, selector.alpha_outliers) if "outliers" in effects else None

        def widened_fitter(widened: PoseTable, measured: bool = False) -> Fitter:
            other = Fitter(widened, reg, T, o, s.folds, loop, fitter.correlation,
                           fitter.measured_scale2 if measured else None)
            other.set_steps(fitter.steps_at)
            return other

        def refit(widened: PoseTable) -> tuple[Fitter, Fit]:
            other = widened_fitter(widened)
            return other, other.fit(final.terms, final.outliers, final.x)

        if not floor.used and misweighs(floor, s.alpha) and (final.terms or final.outliers):
            # the σ's ratios misweigh the poses but are kept: each finding tested again with σ widened
            self.progress("testing the findings again under the pose-to-pose noise")
            floor = replace(floor, effects=effects_under_pose_noise(
                fitter, final, entry_levels(selection), selector.alpha_outliers, s.alpha,
                lambda p: widened_fitter(p, measured=True)))
        self.progress("checking the noise model")
        noise = check_noise_model(fitter, final, s.alpha, min(s.simulations, NOISE_SIMULATIONS), s.seed, refit, loop,
                                  measured)
        noise.correlation = selection.correlation or correlation  # the one the selection ended under
        sim_after = None
        if findings:
            self.progress("simulating the extended model")
            sim_after = simulation_check(fitter, final, open_terms, s.simulations, s.band, s.seed, loop)
        model = fitter.model(final)
        d = fitter.fitted_directions(final)
        diagnosis = Diagnosis(
            poses=poses, regressors=reg, settings=s, baseline_source=source, effects_tested=effects,
            skipped=skipped, notes=notes, baseline=base, baseline_heldout=base_heldout, final=final,
            final_heldout=fitter.heldout(final), simulation=sim, simulation_after=sim_after, steps=selection.steps,
            findings=findings, decisions=selection.decisions, model=model, fitted_directions=d,
            given_rms_g=rms(given.residuals), detection_limits=limits, outlier_limit=pose_limit, noise_model=noise,
            sessions=stack, baseline_model=fitter.model(base).base, step=fitter.data.step,
            dropped=selection.dropped, pose_noise=floor,
        )
        self.progress("testing a bias that wanders in time (a random walk)")
        noise.random_walk = self.random_walk(diagnosis, s.alpha, noise.measured_understated_by, measured)
        return diagnosis

    @staticmethod
    def random_walk(diagnosis: Diagnosis, alpha: float, measured_ratio: float | None,
                    still: MeasuredPoseNoise | None = None) -> RandomWalkCheck:
        """The random-walk bias tested about the final model: the named effects' share of each pose is
        taken out first (so the walk cannot re-explain a drift, a temperature term or a session's
        bias), and the outlier poses are left out."""
        poses, model, kept = diagnosis.poses, diagnosis.model, diagnosis.kept
        directions = diagnosis.fitted_directions
        share = model.measure(directions, poses.temp, poses.t) - model.base.measure(directions)
        share = share + diagnosis.session_shift()
        subset = poses.with_acc(poses.acc - share).subset(np.flatnonzero(kept))
        session = None if diagnosis.sessions is None else diagnosis.sessions.session[kept]
        return check_random_walk(subset, model.base.T_canonical, model.base.o, session, alpha, measured_ratio, still)


def diagnose(poses: PoseTable, baseline: LumpedCalibration | None = None,
             progress: Progress | Callable[[str], None] | None = None, **settings: Any) -> Diagnosis:
    """``Diagnoser(DiagnosisSettings(**settings), progress).run(poses, baseline)`` in one call."""
    return Diagnoser(DiagnosisSettings(**settings), progress).run(poses, baseline)
