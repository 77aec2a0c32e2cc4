"""Exporters: a calibration written in the format another tool reads.

=============  =================================================================  ==========================
format         what is written                                                    module
=============  =================================================================  ==========================
``ardupilot``  ``INS_ACCOFFS_*``, ``INS_ACCSCAL_*`` (+ ``INS_TCAL1_*``) param file  :mod:`.ardupilot`
``px4``        ``CAL_ACC0_*OFF/*SCALE`` (+ ``TC_A0_*``) as ``param set`` lines      :mod:`.px4`
``kalibr``     ``imu.yaml`` noise model from an ``optcal allan --json`` result      :mod:`.kalibr`
``ros``        ``sensor_msgs/Imu`` linear-acceleration covariance                  :mod:`.ros`
``c``          a C99 header that applies the calibration (numbers baked in)        :mod:`.c_header`
=============  =================================================================  ==========================

Each format module has ``export(cal, options) -> ExportResult``; :data:`EXPORTERS` maps the
format name to it (imported on first use).  The firmware formats keep only offsets and
diagonal scales; :mod:`.firmware` builds that model once and measures what it loses.
"""

from __future__ import annotations

import importlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from optcal.families.caltypes.base import Calibration, FitPoses
from optcal.errors import InputError

#: format → "module:function".  One line per format.
EXPORTERS: dict[str, str] = {
    "ardupilot": "optcal.applications.export.ardupilot:export",
    "px4": "optcal.applications.export.px4:export",
    "kalibr": "optcal.applications.export.kalibr:export",
    "ros": "optcal.applications.export.ros:export",
    "c": "optcal.applications.export.c_header:export",
}
#: Default largest acceptable loss of a diagonal firmware model, g (5 mg).
DEFAULT_MAX_LOSS_G: float = 5e-3


@dataclass(frozen=True)
class ExportOptions:
    """Settings shared by the exporters.

    Attributes
    ----------
    counts_per_g : float, optional
        The driver's sensitivity (counts per g) for a calibration in counts: firmware
        parameters are in m/s² of the driver's output.
    counts_zero : float, optional
        The raw reading the driver subtracts before scaling (e.g. 32768, the mid-scale of an
        unsigned 16-bit converter; 0 for signed counts).  Default: 32768 when the poses are
        unsigned 16-bit counts around mid-scale (the test of ``optcal check``), else 0.
    max_loss_g : float
        Refuse a diagonal firmware model whose rms ``|a|`` error exceeds the full model's by more.
    poses : FitPoses, optional
        Poses to measure the loss on, when the calibration file has none (``fitted_on``).
    allan : dict, optional
        An ``optcal allan --json`` result (``kalibr``, ``ros``).
    random_walk_bound : bool
        ``kalibr``: write the Allan result's upper bound of the rate random walk on axes where
        the log shows none (labelled as a bound), instead of refusing.
    gyro_allan : dict, optional
        An ``optcal allan --sensor gyro --json`` result (``kalibr``: the gyroscope keys).
    rate_hz : float, optional
        Sample rate of the IMU topic (``kalibr``; default: the Allan log's rate).
    rostopic : str
        Topic of the IMU messages (``kalibr``).
    source : str
        Where the calibration came from (named in the file's comments).
    """

    counts_per_g: float | None = None
    counts_zero: float | None = None
    max_loss_g: float = DEFAULT_MAX_LOSS_G
    poses: FitPoses | None = None
    allan: dict[str, Any] | None = None
    random_walk_bound: bool = False
    gyro_allan: dict[str, Any] | None = None
    rate_hz: float | None = None
    rostopic: str = "/imu0"
    source: str = "a calibration"


@dataclass(frozen=True)
class LossReport:
    """rms ``|a| − 1`` of the full calibration and of the exported model on the same poses, g."""

    n_poses: int
    rms_full_g: float
    rms_exported_g: float

    @property
    def loss_g(self) -> float:
        return self.rms_exported_g - self.rms_full_g

    def describe(self) -> str:
        return (
            f"rms |a|-1 on the calibration's {self.n_poses} poses: full model {self.rms_full_g * 1e3:.4f} mg, "
            f"exported {self.rms_exported_g * 1e3:.4f} mg (loss {self.loss_g * 1e3:.4f} mg)"
        )


@dataclass
class ExportResult:
    """An exported calibration.

    Attributes
    ----------
    format : str
    text : str
        The file's content.
    loss : LossReport, optional
        For formats that simplify the model.
    mapped : list of str
        optcal terms written into the format.
    dropped : list of str
        optcal terms the format cannot hold (with the reason).
    notes : list of str
        What the user must know (units, frames, parameters optcal cannot fill in).
    """

    format: str
    text: str
    loss: LossReport | None = None
    mapped: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def export(cal: Calibration, fmt: str, options: ExportOptions | None = None) -> ExportResult:
    """Export ``cal`` in format ``fmt`` (one of :data:`EXPORTERS`)."""
    target = EXPORTERS.get(fmt)
    if target is None:
        raise InputError(f"unknown export format {fmt!r}; choose one of {', '.join(EXPORTERS)}")
    module, attr = target.split(":")
    return getattr(importlib.import_module(module), attr)(cal, options or ExportOptions())


def read_allan(path: str | Path) -> dict[str, Any]:
    """An ``optcal allan --json`` result, checked to have the per-axis noise parameters."""
    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except FileNotFoundError as exc:
        raise InputError(f"{p}: no such Allan result file") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: not a JSON file; save one with optcal allan LOG --json > {p.name}") from exc
    if not isinstance(d, dict) or not all(isinstance(d.get(a), dict) for a in "xyz") or "log" not in d:
        raise InputError(f"{p}: not an optcal allan --json result (no per-axis x, y, z entries)")
    return d
