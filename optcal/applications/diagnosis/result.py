"""The result of a diagnosis: numbers, the extended model, and the JSON shape of ``optcal diagnose --json``.

The text report is :func:`optcal.report.diagnosis_text.diagnosis_report`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.findings import Finding
from optcal.applications.diagnosis.fitting import BASELINE_MODEL, Fit
from optcal.applications.diagnosis.limits import DetectionLimit, OutlierLimit
from optcal.applications.diagnosis.noise_model import NoiseModelCheck
from optcal.applications.diagnosis.pose_noise import PoseNoiseFloor
from optcal.applications.diagnosis.regressors import Regressors
from optcal.applications.diagnosis.backward import Dropped
from optcal.applications.diagnosis.acceptance import TemperatureTimeDecision
from optcal.applications.diagnosis.selection import Step
from optcal.applications.diagnosis.sessions import SessionStack
from optcal.applications.diagnosis.simulation import SimulationCheck
from optcal.core.extended_model import ExtendedModel
from optcal.core.model import AXES, LumpedModel
from optcal.core.poses import PoseTable
from optcal.core.stats import rms

if TYPE_CHECKING:
    from optcal.families.caltypes.base import Calibration
    from optcal.applications.diagnosis.diagnoser import DiagnosisSettings
    from optcal.applications.diagnosis.sessions import SessionOffsets


@dataclass
class Diagnosis:
    """Everything a diagnosis found (text with :meth:`report`, JSON with :meth:`to_dict`).

    Attributes
    ----------
    poses : PoseTable
    regressors : Regressors
    settings : DiagnosisSettings
    baseline_source : str
        Where the baseline calibration came from (a method name, or ``"given calibration"``).
    effects_tested : tuple of str
    skipped : dict of str to str
        Effects not tested, and why.
    notes : list of str
    baseline, final : Fit
        The paper's model and the final extended model (maximum likelihood, norm residuals).
    baseline_heldout, final_heldout : ndarray, shape (n,)
        k-fold held-out residuals (g).
    simulation, simulation_after : SimulationCheck, SimulationCheck or None
        The simulation check of the baseline, and of the final model when something was found.
    steps : list of Step
    findings : list of Finding
    decisions : list of TemperatureTimeDecision
    model : ExtendedModel
        The final model in physical units.
    fitted_directions : ndarray, shape (n, 3)
        Unit specific-force directions of the poses under the final model.
    given_rms_g : float or None
        rms norm residual of a given calibration as it was given (before the refit).
    detection_limits : list of DetectionLimit
        For every candidate not in the final model, the smallest effect the last step would have named.
    outlier_limit : OutlierLimit or None
        The smallest outlier pose the outlier test would name (``None`` when outliers were not tested).
    noise_model : NoiseModelCheck or None
        Whether the given per-pose σ describes the scatter, and the extended noise model when not.
    sessions : SessionStack or None
        The sessions when several sessions of one sensor were diagnosed together.
    baseline_model : LumpedModel or None
        The baseline fit (the paper's model refitted on these poses) as a lumped model.
    peer : PeerComparison or None
        A peer's calibration given as the baseline (imucal, imu_tk) next to optcal's baseline fit
        (:class:`optcal.applications.quality.peer.PeerComparison`, set by the caller).
    step : ndarray, shape (n,) or (n, m), or None
        1 for the poses after each bias step of a ``bias_step`` finding, 0 before (``None``: no step).
    dropped : list of Dropped
        Terms accepted by the forward selection and dropped once later terms made them unneeded
        (:meth:`~optcal.applications.diagnosis.selection.ForwardSelection.backward_check`).
    pose_noise : PoseNoiseFloor or None
        The pose-to-pose noise tested beside the per-pose σ (:mod:`optcal.applications.diagnosis.pose_noise`);
        when used, ``poses.sigma`` is the widened σ the diagnosis weighed the poses by.
    """

    poses: PoseTable
    regressors: Regressors
    settings: "DiagnosisSettings"
    baseline_source: str
    effects_tested: tuple[str, ...]
    skipped: dict[str, str]
    notes: list[str]
    baseline: Fit
    baseline_heldout: NDArray[np.float64]
    final: Fit
    final_heldout: NDArray[np.float64]
    simulation: SimulationCheck
    simulation_after: SimulationCheck | None
    steps: list[Step]
    findings: list[Finding]
    decisions: list[TemperatureTimeDecision]
    model: ExtendedModel
    fitted_directions: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    given_rms_g: float | None = None
    detection_limits: list[DetectionLimit] = field(default_factory=list)
    outlier_limit: OutlierLimit | None = None
    noise_model: NoiseModelCheck | None = None
    sessions: SessionStack | None = None
    baseline_model: LumpedModel | None = None
    peer: Any = None
    step: NDArray[np.float64] | None = None
    dropped: list[Dropped] = field(default_factory=list)
    pose_noise: PoseNoiseFloor | None = None

    @property
    def n(self) -> int:
        return self.poses.n

    @property
    def kept(self) -> NDArray[np.bool_]:
        """Poses that are not outliers of the final model."""
        return self.final.kept(self.n)

    def baseline_rms(self) -> float:
        return rms(self.baseline.residuals)

    def baseline_heldout_rms(self, mask: NDArray[np.bool_] | None = None) -> float:
        return rms(self.baseline_heldout, mask)

    def final_rms(self) -> float:
        return rms(self.final.residuals, self.kept)

    def final_heldout_rms(self) -> float:
        return rms(self.final_heldout, self.kept)

    def gain(self) -> float:
        """Baseline held-out rms over the final model's."""
        return self.baseline_heldout_rms() / self.final_heldout_rms()

    def finding(self, effect: str) -> Finding | None:
        """The finding of ``effect`` (``None`` when not found)."""
        return next((f for f in self.findings if f.effect == effect), None)

    def calibration(self) -> "Calibration":
        """The final model as a calibration: ``extended`` when terms were found, else ``lumped``.

        Fitted on the kept poses (outliers excluded); the validity range is their temperature,
        time and ``|ā|`` ranges.  Columns the data could not use (no or constant temperature)
        carry no term, so they are not needed to apply it.  Two named causes cannot be applied
        to a later recording and are carried as the bias's uncertainty instead (an ``extended``
        calibration then): the turn-on repeatability between sessions (``o`` is the sessions'
        mean) and a bias that wanders as a random walk (``K``).  After a bias step, ``o`` is the bias after it
        (the sensor's bias now).
        """
        from optcal.families.caltypes.base import FitPoses
        from optcal.families.caltypes.extended import BiasRandomWalk, BiasRepeatability, ExtendedCalibration
        from optcal.families.caltypes.lumped import LumpedCalibration

        kept = self.kept
        temp = self.poses.temp[kept] if self.poses.temp is not None and self.regressors.has_temp else None
        t = self.poses.t[kept] if self.poses.t is not None and self.regressors.has_time else None
        fitted_on = FitPoses(self.poses.acc[kept].copy(), temp, t)
        walk = None if self.noise_model is None else self.noise_model.random_walk
        walk_named = walk is not None and walk.named
        sessions = self.session_offsets()
        if sessions is None:
            model = self.model
            if self.step is not None:  # the bias after the last step is the sensor's now: o is that bias
                from optcal.applications.diagnosis.problem import step_shift

                columns = 1 if self.step.ndim == 1 else self.step.shape[1]
                shift = step_shift(self.final.x, model.base.C, np.ones((1, columns)))[0]  # the bias after every step
                model = replace(model, base=LumpedModel(model.base.C, model.base.o + shift))
                fitted_on = replace(fitted_on, acc=fitted_on.acc - (self.session_shift() - shift)[kept])
            if not any(e != "bias_step" for e, _ in self.final.terms) and not walk_named:
                return LumpedCalibration.from_model(model.base, self.poses.units, fitted_on)
            cal = ExtendedCalibration.from_model(model, units=self.poses.units, fitted_on=fitted_on)
        else:
            # per-session offsets do not apply to a future session: the mean bias, the spread as its uncertainty
            base = self.model.base
            shift = np.array([sessions.mean_from_first_g.get(a, 0.0) for a in AXES]) * np.linalg.norm(base.C, axis=1)
            model = replace(self.model, base=LumpedModel(base.C, base.o + shift))
            fitted_on = replace(fitted_on, acc=fitted_on.acc - (self.session_shift() - shift)[kept])
            cal = ExtendedCalibration.from_model(model, units=self.poses.units, fitted_on=fitted_on)
            cal.bias_repeatability = BiasRepeatability(tuple(sessions.repeatability_vector()),
                                                       self.regressors.n_sessions)
        if walk is not None and walk.named:
            cal.bias_random_walk = BiasRandomWalk(walk.K_g, walk.K_interval_g, walk.wander_rms_g)
        return cal

    def session_offsets(self) -> "SessionOffsets | None":
        """The sessions' bias offsets when ``session_bias`` was found (``None`` otherwise)."""
        found = self.finding("session_bias")
        return None if found is None else found.sessions

    def session_shift(self) -> NDArray[np.float64]:
        """Raw bias of each pose's session relative to the first session's, shape (n, 3) (zeros for one session),
        and of the poses after a bias step relative to those before it."""
        from optcal.applications.diagnosis.problem import session_shift, step_shift

        shift = session_shift(self.final.x, self.model.base.C, self.regressors.session, self.regressors.n_sessions)
        return shift + step_shift(self.final.x, self.model.base.C, self.step) if self.step is not None else shift

    def to_dict(self) -> dict[str, Any]:
        """The one JSON object of ``optcal diagnose --json``."""
        kept = self.kept
        baseline: dict[str, Any] = {
            "model": BASELINE_MODEL,
            "calibration": self.baseline_source,
            "rms_g": self.baseline_rms(),
            "heldout_rms_g": self.baseline_heldout_rms(),
        }
        if self.given_rms_g is not None:
            baseline["given_rms_g"] = self.given_rms_g
        return {
            "n_poses": self.n,
            "gain": self.gain(),  # held-out error of the paper's model over the final model's (also final.gain)
            "baseline": baseline,
            "simulation_check": {
                **self.simulation.to_dict(),
                "after": None if self.simulation_after is None else self.simulation_after.to_dict(),
            },
            "findings": [f.to_dict() for f in self.findings],
            "final": {
                "model": self.final.describe(),
                "rms_g": self.final_rms(),
                "heldout_rms_g": self.final_heldout_rms(),
                "gain": self.gain(),
                "heldout_poses": int(kept.sum()),
                "gain_on_kept_poses": self.baseline_heldout_rms(kept) / self.final_heldout_rms(),
            },
            "effects_tested": list(self.effects_tested),
            "effects_skipped": dict(self.skipped),
            "temperature_time_decisions": [d.to_dict() for d in self.decisions],
            "detection_limits": [lim.to_dict() for lim in self.detection_limits],
            "outlier_limit": None if self.outlier_limit is None else self.outlier_limit.to_dict(),
            "noise_model": None if self.noise_model is None else self.noise_model.to_dict(),
            "pose_noise": None if self.pose_noise is None else self.pose_noise.to_dict(),
            "sessions": None if self.sessions is None else {
                "names": list(self.sessions.names), "poses": self.sessions.counts(),
                "time_origins_s": list(self.sessions.time_origins),
            },
            "selection": [s.to_dict() for s in self.steps],
            "settings": self.settings.to_dict(),
            "notes": list(self.notes),
            **({"peer_comparison": self.peer.to_dict()} if self.peer is not None else {}),
            # terms accepted, then made unneeded by later ones (present only when the backward check dropped one)
            **({"dropped": [d.to_dict() for d in self.dropped]} if self.dropped else {}),
        }
