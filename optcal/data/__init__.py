"""Measured data in: pose tables and raw recordings, readers, evidence, decisions, static detection.

:func:`load` is the one entry point every command uses for DATA.  It runs the steps of
:mod:`optcal.data.decisions` in order, each module once: **read** any supported file
(:mod:`optcal.data.readers`), gather the **evidence** (one pass of statistics,
:mod:`optcal.data.evidence`), make the **decisions** (columns, pose table or raw recording,
units, time base, rate, exclusions; each with its reason), **convert** (a pose table, or a
:class:`Recording`), and for a recording **segment** it into static poses
(:mod:`optcal.data.static`).  The returned :class:`~optcal.core.poses.PoseTable` carries the
:class:`DataDecisions` (``decisions``), and every excluded sample is counted in
``exclusions``.  An error met once decisions were made is a
:class:`~optcal.data.decisions.DataInputError` that carries them (the command line prints
them before the error).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any


from optcal.data.decisions import (
    KINDS,
    POSE_TABLE,
    RAW_RECORDING,
    DataDecisions,
    DataInputError,
    Decision,
    decide,
    with_decisions,
)
from optcal.data.evidence import Evidence, gather_evidence
from optcal.data.readers import Source, read_source
from optcal.data.recording import Recording, recording_from_source
from optcal.data.static import Segmentation, StaticSettings, detect_static
from optcal.data.tables import load_pose_table, pose_table_from_source, read_csv_frame
from optcal.data.units import check_sensitivity
from optcal.errors import InputError
from optcal.core.poses import PoseTable
from optcal.core.stats import rms

__all__ = [
    "KINDS",
    "POSE_TABLE",
    "RAW_RECORDING",
    "decide",
    "gather_evidence",
    "DataDecisions",
    "DataInputError",
    "Decision",
    "Evidence",
    "KindDecision",
    "LoadedData",
    "Recording",
    "Segmentation",
    "StaticSettings",
    "decide_kind",
    "load",
    "load_pose_table",
    "load_recording",
    "load_with_segmentation",
    "read_csv_frame",
    "segment",
]

#: The kind decision (``value`` is ``"pose table"`` or ``"raw recording"``).
KindDecision = Decision


def decide_kind(src: Source, requested: str = "auto", units: str | None = None) -> Decision:
    """Tell a pose table from a raw recording (see :func:`optcal.data.decisions.decide`)."""
    return decide(src, gather_evidence(src), kind=requested, units=units).kind


def load_recording(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
    time_unit: str | None = None,
    timing: str = "auto",
    gyro_file: str | Path | None = None,
    required_by: str = "reading a recording",
) -> Recording:
    """Read a raw recording (any supported file) as a :class:`Recording` (``decisions`` say how).

    ``required_by`` names what needs the raw recording (e.g. ``"the allan command"``); it is
    the reason the kind decision gives.
    """
    src = read_source(path, columns=columns, topic=topic, gyro_file=gyro_file)  # read
    decisions = decide(  # evidence, then decisions
        src, gather_evidence(src), kind="raw", units=units, rate=rate, time_unit=time_unit, timing=timing,
        required_by=required_by,
    )
    return recording_from_source(src, decisions)  # conversion


def segment(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
    settings: StaticSettings | None = None,
    **read_options: Any,
) -> Segmentation:
    """Read a raw recording and find its static intervals."""
    rec = load_recording(path, columns=columns, units=units, topic=topic, rate=rate, **read_options)
    return detect_static(rec, settings)


@dataclass
class LoadedData:
    """What :func:`load_with_segmentation` read: the pose table, and how it was made.

    Attributes
    ----------
    poses : PoseTable
    decisions : DataDecisions
    segmentation : Segmentation or None
        The static detection (raw recordings only).
    """

    poses: PoseTable
    decisions: DataDecisions
    segmentation: Segmentation | None = None

    @property
    def kind(self) -> Decision:
        """The kind decision (pose table or raw recording) and its reason."""
        return self.decisions.kind


def load_with_segmentation(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
    kind: str = "auto",
    time_unit: str | None = None,
    timing: str = "auto",
    gyro_file: str | Path | None = None,
    settings: StaticSettings | None = None,
    **static_options: Any,
) -> LoadedData:
    """Like :func:`load`, also returning the decisions and the static detection."""
    if settings is None:
        settings = StaticSettings.from_options(**static_options)
    elif static_options:
        raise InputError("give static-detection settings either as settings= or as keywords, not both")
    src = read_source(path, columns=columns, topic=topic, gyro_file=gyro_file)  # read
    decisions = decide(  # evidence, then decisions
        src, gather_evidence(src), kind=kind, units=units, rate=rate, time_unit=time_unit, timing=timing
    )
    try:
        if decisions.kind.value == POSE_TABLE:
            poses = pose_table_from_source(src, decisions)  # conversion
            check_sensitivity(poses.acc, poses.units)  # the units and columns decisions, checked on the poses
            return LoadedData(poses, decisions)
        rec = recording_from_source(src, decisions)  # conversion
        del src  # the recording holds its own arrays: free the file's columns before segmenting
        seg = detect_static(rec, settings)  # segmentation
        decisions.warnings.extend(seg.override_warnings())  # an override says what it assumes, on the error path too
        table = seg.pose_table()
        # the units and columns decisions, checked on the poses and their noise
        check_sensitivity(table.acc, table.units, noise=[rms(iv.std) for iv in seg.intervals])
    except InputError as exc:
        raise with_decisions(exc, decisions) from exc
    table.meta.update(recording_meta(rec, decisions))
    table.decisions = decisions
    return LoadedData(table, decisions, seg)


def load(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
    kind: str = "auto",
    time_unit: str | None = None,
    timing: str = "auto",
    gyro_file: str | Path | None = None,
    settings: StaticSettings | None = None,
    **static_options: Any,
) -> PoseTable:
    """Load DATA, a pose table or a raw recording, as a :class:`~optcal.core.poses.PoseTable`.

    This is the one entry point every command uses for DATA.

    Parameters
    ----------
    path : str or Path
        CSV/text, Parquet, ROS 1 bag, ROS 2 bag (directory), or PX4 ULog file.
    columns : str or dict, optional
        ``"ax=NAME,ay=NAME,az=NAME,t=NAME,..."`` for columns with other names, or 1-based
        positions (``"t=1,ax=2,ay=3,az=4"``), e.g. for a file without a header.
    units : {"g", "m/s^2", "counts"}, optional
        Units of the accelerometer data; decided from the file when omitted.
    topic : str, optional
        ROS topic (``sensor_msgs/Imu``) or ULog topic (``sensor_accel[:N]``).
    rate : float, optional
        Sampling rate (Hz) of a recording without a time column.
    kind : {"auto", "poses", "raw"}
        Force the reading as a pose table or a raw recording (``auto`` decides and says why).
    time_unit : {"s", "ms", "us", "ns"}, optional
        Unit of a time column whose name does not say it (default: seconds, as documented).
    timing : {"auto", "stamps", "uniform"}
        Keep the time stamps, or spread the samples evenly over the stamped span (``auto``
        does so for bursty or coarse stamps, and says so).
    gyro_file : str or Path, optional
        A second text file ``t gx gy gz`` merged on time (imu_tk's pair of files).
    settings : StaticSettings, optional
        Static-detection settings for raw recordings; or give them as keywords
        (``window_s=``, ``threshold=``, ``min_dwell_s=``, ...).

    Returns
    -------
    PoseTable
        ``source`` is ``"pose table"`` or ``"raw recording"``; ``decisions`` says why and
        how (also ``meta["decisions"]``); for a recording ``meta["segmentation"]`` lists the
        intervals.

    Raises
    ------
    InputError
        Unreadable file, unknown columns, time running backwards, no static interval, ...
    """
    return load_with_segmentation(
        path, columns=columns, units=units, topic=topic, rate=rate, kind=kind, time_unit=time_unit,
        timing=timing, gyro_file=gyro_file, settings=settings, **static_options
    ).poses


def recording_meta(rec: Recording, decisions: DataDecisions) -> dict[str, Any]:
    """Provenance of a recording for ``PoseTable.meta``."""
    return {
        "path": rec.path,
        "file_type": rec.file_type,
        "kind_reason": decisions.kind.reason,
        "units_reason": rec.units_reason,
        "time": rec.time_reason,
        "rate_hz": rec.rate_hz,
        "duration_s": rec.duration_s,
        "n_usable": rec.n_usable,
        "decisions": decisions.to_dict(),
        **rec.meta,
    }
