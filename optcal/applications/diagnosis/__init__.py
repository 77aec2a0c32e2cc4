"""Diagnosis: what the calibrated model gets wrong in measured data, the cause, the extended model, the gain.

One module per concept: :mod:`~optcal.applications.diagnosis.effects` (the vocabulary),
:mod:`~optcal.applications.diagnosis.regressors`, :mod:`~optcal.applications.diagnosis.problem` (the extended fit:
vectorised residuals and Jacobian, least squares), :mod:`~optcal.applications.diagnosis.fitting`,
:mod:`~optcal.applications.diagnosis.simulation` (the simulation check), :mod:`~optcal.applications.diagnosis.outliers`,
:mod:`~optcal.applications.diagnosis.selection` (forward selection; the acceptance of a step:
:mod:`~optcal.applications.diagnosis.acceptance`), :mod:`~optcal.applications.diagnosis.findings`,
:mod:`~optcal.applications.diagnosis.limits` (detection limits), :mod:`~optcal.applications.diagnosis.noise_model` (the
noise model as a named explanation), :mod:`~optcal.applications.diagnosis.result`,
:mod:`~optcal.report.diagnosis_text`, :mod:`~optcal.report.diagnosis_figures`,
:mod:`~optcal.applications.diagnosis.progress` and :mod:`~optcal.applications.diagnosis.diagnoser`
(``Diagnoser(settings).run(poses) -> Diagnosis``).

The names below are imported on first use, so ``import optcal.applications.diagnosis.effects`` (the CLI's
help) pulls in neither scipy nor matplotlib.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_EXPORTS = {
    "Diagnoser": "diagnoser", "DiagnosisSettings": "diagnoser", "diagnose": "diagnoser",
    "Diagnosis": "result", "Finding": "findings", "Evidence": "findings", "Step": "selection",
    "Candidate": "acceptance", "TemperatureTimeDecision": "acceptance", "SimulationCheck": "simulation",
    "StatisticBand": "simulation", "EFFECTS": "effects", "Progress": "progress", "NoiseModelCheck": "noise_model",
    "DetectionLimit": "limits",
    "OutlierLimit": "limits",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(f"optcal.applications.diagnosis.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'optcal.applications.diagnosis' has no attribute {name!r}")
