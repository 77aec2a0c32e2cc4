"""Exporters: a calibration written in the format another tool reads.

=============  =================================================================  ==========================
format         what is written                                                    module
=============  =================================================================  ==========================
``ardupilot``  ``INS_ACC*OFFS/SCAL``, ``INS_GYR*OFFS``, ids (+ ``INS_TCALn_*``)   :mod:`.ardupilot`
``px4``        ``CAL_ACCn_*``, ``CAL_GYROn_*OFF``, ids (+ ``TC_An_*``), QGC file  :mod:`.px4`
``px4-shell``  the same as ``param set`` lines                                    :mod:`.px4`
``kalibr``     ``imu.yaml`` noise model from an ``optcal allan --json`` result      :mod:`.kalibr`
``ros``        ``sensor_msgs/Imu`` linear-acceleration covariance                  :mod:`.ros`
``c``          a C99 header that applies the calibration (numbers baked in)        :mod:`.c_header`
=============  =================================================================  ==========================

Each format module has ``export(cal, options) -> ExportResult``; :data:`EXPORTERS` maps the
format name to it (imported on first use).  What every exporter shares
(:class:`~.base.ExportOptions`, :class:`~.base.ExportResult`, :class:`~.base.LossReport`) is in
:mod:`.base`, below the format modules, so that none of them imports this registry.  The
firmware formats keep only offsets and diagonal scales; :mod:`.firmware` builds that model
once, measures what it loses and writes the parameter file.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from optcal.core.jsonio import read_json
from optcal.families.caltypes.base import Calibration
from optcal.errors import InputError
from optcal.applications.export.base import ExportOptions, ExportResult

#: format → "module:function".  One line per format.
EXPORTERS: dict[str, str] = {
    "ardupilot": "optcal.applications.export.ardupilot:export",
    "px4": "optcal.applications.export.px4:export",
    "px4-shell": "optcal.applications.export.px4:export_shell",
    "kalibr": "optcal.applications.export.kalibr:export",
    "ros": "optcal.applications.export.ros:export",
    "c": "optcal.applications.export.c_header:export",
    "imucal": "optcal.applications.export.imucal:export",
    "kalibr-imu": "optcal.applications.export.kalibr_imu:export",
    "openvins": "optcal.applications.export.kalibr_imu:export_openvins",
    "basalt": "optcal.applications.export.basalt:export",
    "imutk": "optcal.applications.export.imutk:export",
    "vins": "optcal.applications.export.noise:export_vins",
    "orbslam3": "optcal.applications.export.noise:export_orbslam3",
    "okvis": "optcal.applications.export.noise:export_okvis",
}


def export(cal: Calibration, fmt: str, options: ExportOptions | None = None) -> ExportResult:
    """Export ``cal`` in format ``fmt`` (one of :data:`EXPORTERS`)."""
    target = EXPORTERS.get(fmt)
    if target is None:
        raise InputError(f"unknown export format {fmt!r}; choose one of {', '.join(EXPORTERS)}")
    if cal.cal_type == "magnetometer":  # its own module: the compass parameters, other formats refused
        from optcal.applications.export.mag_firmware import export as export_mag

        return export_mag(cal, fmt, options or ExportOptions())
    module, attr = target.split(":")
    return getattr(importlib.import_module(module), attr)(cal, options or ExportOptions())


def read_allan(path: str | Path) -> dict[str, Any]:
    """An ``optcal allan --json`` result, checked to have the per-axis noise parameters."""
    p = Path(path)
    d = read_json(p, "Allan result file", hint=f"save one with optcal allan LOG --json > {p.name}")
    parts = [d.get("accelerometer"), d.get("gyroscope")] if d.get("sensor") == "both" else [d]
    if not all(isinstance(part, dict) and "log" in part and all(isinstance(part.get(a), dict) for a in "xyz")
               for part in parts):
        raise InputError(f"{p}: not an optcal allan --json result (no per-axis x, y, z entries)")
    return d
