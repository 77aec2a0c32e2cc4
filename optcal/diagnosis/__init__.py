"""Diagnosis: what the calibrated model gets wrong in measured data, the cause, the extended model, the gain.

One module per concept: :mod:`~optcal.diagnosis.effects` (the vocabulary),
:mod:`~optcal.diagnosis.regressors`, :mod:`~optcal.diagnosis.problem` (the extended fit:
vectorised residuals and Jacobian, least squares), :mod:`~optcal.diagnosis.fitting`,
:mod:`~optcal.diagnosis.simulation` (the simulation check), :mod:`~optcal.diagnosis.outliers`,
:mod:`~optcal.diagnosis.selection`, :mod:`~optcal.diagnosis.findings`,
:mod:`~optcal.diagnosis.limits` (detection limits), :mod:`~optcal.diagnosis.noise_model` (the
noise model as a named explanation), :mod:`~optcal.diagnosis.result`,
:mod:`~optcal.diagnosis.report`, :mod:`~optcal.diagnosis.figures`,
:mod:`~optcal.diagnosis.progress` and :mod:`~optcal.diagnosis.diagnoser`
(``Diagnoser(settings).run(poses) -> Diagnosis``).

The names below are imported on first use, so ``import optcal.diagnosis.effects`` (the CLI's
help) pulls in neither scipy nor matplotlib.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_EXPORTS = {
    "Diagnoser": "diagnoser", "DiagnosisSettings": "diagnoser", "diagnose": "diagnoser",
    "Diagnosis": "result", "Finding": "findings", "Evidence": "findings", "Step": "selection",
    "Candidate": "selection", "TemperatureTimeDecision": "selection", "SimulationCheck": "simulation",
    "StatisticBand": "simulation", "save_figures": "figures", "residual_figure": "figures",
    "simulation_figure": "figures", "EFFECTS": "effects", "Progress": "progress", "NoiseModelCheck": "noise_model",
    "DetectionLimit": "limits",
    "OutlierLimit": "limits",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(f"optcal.diagnosis.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'optcal.diagnosis' has no attribute {name!r}")
