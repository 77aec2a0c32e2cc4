"""Measured data in: pose tables and raw recordings, readers, units and static detection.

:func:`load` is the one entry point every command uses for DATA.  It reads any supported
file (:mod:`optcal.data.readers`), decides whether it is a **pose table** (one row per
static pose) or a **raw recording** (a time series), and returns a
:class:`~optcal.poses.PoseTable` whose ``source`` says which it saw and whose ``meta``
records how: for a recording, the static intervals found (:mod:`optcal.data.static`),
thresholds and per-interval statistics; every excluded sample is counted in
``exclusions``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from optcal.data.readers import ACC, Source, read_source
from optcal.data.recording import Recording, recording_from_source
from optcal.data.static import Segmentation, StaticSettings, detect_static
from optcal.data.tables import load_pose_table, pose_table_from_source, read_csv_frame
from optcal.data.units import decide_units, nominal_conversion
from optcal.errors import InputError
from optcal.poses import PoseTable

__all__ = [
    "KINDS",
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

#: ``--format`` choices: decide automatically, or force a pose table or a raw recording.
KINDS: tuple[str, ...] = ("auto", "poses", "raw")
POSE_TABLE = "pose table"
RAW_RECORDING = "raw recording"
#: Consecutive rows of a raw recording differ by less than this fraction of 1 g (median).
RAW_STEP_RATIO: float = 0.02


@dataclass(frozen=True)
class KindDecision:
    """Pose table or raw recording, and why."""

    kind: str
    reason: str


def decide_kind(src: Source, requested: str = "auto") -> KindDecision:
    """Tell a pose table from a raw recording.

    A raw recording is a time series: consecutive rows are samples of the same (or nearly
    the same) orientation and differ by the noise, a small fraction of ‖a‖.  A pose
    table's consecutive rows are different orientations.  ``sigma`` or a per-pose
    ``n_samples`` column mark a pose table; bags, ULog files and files with a sampling
    rate in their header are recordings.
    """
    if requested not in KINDS:
        raise InputError(f"unknown --format {requested!r}; use one of {', '.join(KINDS)}")
    if requested == "poses":
        if src.always_raw:
            raise InputError(f"{src.path}: a {src.file_type} holds a raw recording; it cannot be read with --format poses")
        return KindDecision(POSE_TABLE, "given with --format poses")
    if requested == "raw":
        return KindDecision(RAW_RECORDING, "given with --format raw")
    if src.always_raw:
        return KindDecision(RAW_RECORDING, f"a {src.file_type} is a time series")
    if src.has("sigma") or src.has("n_samples"):
        return KindDecision(POSE_TABLE, "it has per-pose columns (sigma / n_samples)")
    if src.rate_hint is not None:
        return KindDecision(RAW_RECORDING, f"its header gives a sampling rate ({src.rate_reason})")
    acc = np.column_stack([src.column(c) for c in ACC])
    acc = acc[np.all(np.isfinite(acc), axis=1)]
    if acc.shape[0] < 3:
        return KindDecision(POSE_TABLE, "too few rows for a recording")
    step = float(np.median(np.linalg.norm(np.diff(acc, axis=0), axis=1)))
    try:
        one_g = nominal_conversion(decide_units(acc, None, src.units_hint, src.units_reason).units, acc).sensitivity
    except InputError:
        one_g = float(np.median(np.linalg.norm(acc, axis=1)))
    ratio = step / one_g if one_g > 0 else 0.0
    if ratio < RAW_STEP_RATIO:
        return KindDecision(
            RAW_RECORDING,
            f"consecutive rows differ by {100 * ratio:.2g} % of 1 g (median), as samples of a time series do",
        )
    return KindDecision(
        POSE_TABLE,
        f"consecutive rows differ by {100 * ratio:.2g} % of 1 g (median), as different poses do",
    )


def load_recording(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
) -> Recording:
    """Read a raw recording (any supported file) as a :class:`Recording`."""
    return recording_from_source(read_source(path, columns=columns, topic=topic), units=units, rate=rate)


def segment(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
    settings: StaticSettings | None = None,
) -> Segmentation:
    """Read a raw recording and find its static intervals."""
    return detect_static(load_recording(path, columns=columns, units=units, topic=topic, rate=rate), settings)


@dataclass
class LoadedData:
    """What :func:`load_with_segmentation` read: the pose table, and how it was made.

    Attributes
    ----------
    poses : PoseTable
    kind : KindDecision
    segmentation : Segmentation or None
        The static detection (raw recordings only).
    """

    poses: PoseTable
    kind: KindDecision
    segmentation: Segmentation | None = None


def load_with_segmentation(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
    kind: str = "auto",
    settings: StaticSettings | None = None,
    **static_options: Any,
) -> LoadedData:
    """Like :func:`load`, also returning the kind decision and the static detection."""
    if settings is None:
        settings = StaticSettings.from_options(**static_options)
    elif static_options:
        raise InputError("give static-detection settings either as settings= or as keywords, not both")
    src = read_source(path, columns=columns, topic=topic)
    decision = decide_kind(src, kind)
    if decision.kind == POSE_TABLE:
        if rate is not None:
            raise InputError(f"--rate applies to raw recordings; {path} was read as a pose table ({decision.reason})")
        table = pose_table_from_source(src, units)
        table.meta["kind_reason"] = decision.reason
        return LoadedData(table, decision)
    rec = recording_from_source(src, units=units, rate=rate)
    seg = detect_static(rec, settings)
    table = seg.pose_table()
    table.meta.update(recording_meta(rec, decision.reason))
    return LoadedData(table, decision, seg)


def load(
    path: str | Path,
    *,
    columns: str | dict[str, str] | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
    kind: str = "auto",
    settings: StaticSettings | None = None,
    **static_options: Any,
) -> PoseTable:
    """Load DATA, a pose table or a raw recording, as a :class:`~optcal.poses.PoseTable`.

    This is the one entry point every command uses for DATA.

    Parameters
    ----------
    path : str or Path
        CSV/text, Parquet, ROS 1 bag, ROS 2 bag (directory), or PX4 ULog file.
    columns : str or dict, optional
        ``"ax=NAME,ay=NAME,az=NAME,t=NAME,..."`` for columns with other names.
    units : {"g", "m/s^2", "counts"}, optional
        Units of the accelerometer data; decided from the file when omitted.
    topic : str, optional
        ROS topic (``sensor_msgs/Imu``) or ULog topic (``sensor_accel[:N]``).
    rate : float, optional
        Sampling rate (Hz) of a recording without a time column.
    kind : {"auto", "poses", "raw"}
        Force the reading as a pose table or a raw recording (``auto`` decides and says why).
    settings : StaticSettings, optional
        Static-detection settings for raw recordings; or give them as keywords
        (``window_s=``, ``threshold=``, ``min_dwell_s=``, ...).

    Returns
    -------
    PoseTable
        ``source`` is ``"pose table"`` or ``"raw recording"``; ``meta["kind_reason"]`` says
        why; for a recording ``meta["segmentation"]`` lists the intervals.

    Raises
    ------
    InputError
        Unreadable file, unknown columns, time running backwards, no static interval, ...
    """
    return load_with_segmentation(
        path, columns=columns, units=units, topic=topic, rate=rate, kind=kind, settings=settings, **static_options
    ).poses


def recording_meta(rec: Recording, kind_reason: str) -> dict[str, Any]:
    """Provenance of a recording for ``PoseTable.meta``."""
    return {
        "path": rec.path,
        "file_type": rec.file_type,
        "kind_reason": kind_reason,
        "units_reason": rec.units_reason,
        "time": rec.time_reason,
        "rate_hz": rec.rate_hz,
        "duration_s": rec.duration_s,
        **rec.meta,
    }
