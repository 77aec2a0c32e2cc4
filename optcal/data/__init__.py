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
)
from optcal.data.evidence import Evidence, gather_evidence
from optcal.data.readers import Source
from optcal.data.recording import Recording
from optcal.data.options import READ_FIELDS, Reading, ReadOptions, read, read_recording, recording_meta
from optcal.data.static import Segmentation, StaticSettings, detect_static
from optcal.data.tables import read_csv_frame
from optcal.core.poses import PoseTable

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
    "Reading",
    "ReadOptions",
    "Recording",
    "Segmentation",
    "StaticSettings",
    "decide_kind",
    "load",
    "load_pose_table",
    "load_recording",
    "load_with_segmentation",
    "read",
    "read_csv_frame",
    "recording_meta",
    "segment",
]

#: The kind decision (``value`` is ``"pose table"`` or ``"raw recording"``).
KindDecision = Decision

#: What :func:`load_with_segmentation` returns (the :class:`Reading` of :func:`read`).
LoadedData = Reading


def decide_kind(src: Source, requested: str = "auto", units: str | None = None) -> Decision:
    """Tell a pose table from a raw recording (see :func:`optcal.data.decisions.decide`)."""
    return decide(src, gather_evidence(src), kind=requested, units=units).kind


def _overrides(overrides: dict[str, Any]) -> dict[str, Any]:
    """The keywords of :func:`read`, ``settings=`` (the former name of ``static=``) renamed."""
    if "settings" in overrides:
        overrides = dict(overrides)
        settings = overrides.pop("settings")
        if settings is not None:
            overrides["static"] = settings
    return overrides


def load_recording(path: str | Path, options: ReadOptions | None = None, *,
                   required_by: str = "reading a recording", **overrides: Any) -> Recording:
    """Read a raw recording (any supported file) as a :class:`Recording` (``decisions`` say how).

    ``required_by`` names what needs the raw recording (e.g. ``"the allan command"``); it is
    the reason the kind decision gives.  ``options`` and ``overrides`` as for :func:`read`.
    """
    return read_recording(path, options, required_by=required_by, **_overrides(overrides))


def segment(path: str | Path, options: ReadOptions | None = None, **overrides: Any) -> Segmentation:
    """Read a raw recording and find its static intervals (``options`` and ``overrides`` as for :func:`read`)."""
    overrides = _overrides(overrides)
    rec = read_recording(path, options, **{k: v for k, v in overrides.items() if k in READ_FIELDS and k != "static"})
    return detect_static(rec, ReadOptions.build(options, **overrides).static)


def load_with_segmentation(path: str | Path, options: ReadOptions | None = None, **overrides: Any) -> Reading:
    """Like :func:`load`, also returning the decisions and the static detection (the :class:`Reading`)."""
    return read(path, options, **_overrides(overrides))


def load_pose_table(path: str | Path, units: str | None = None, columns: str | dict[str, str] | None = None) -> PoseTable:
    """Read a pose table (CSV or Parquet), one row per static pose.

    Parameters
    ----------
    path : str or Path
        File with a header row and one row per static pose.
    units : {"g", "m/s^2", "counts"}, optional
        Units of the acceleration columns; from the column names or the mean norm when omitted.
    columns : str or dict, optional
        Mapping of canonical names to the file's columns (``"ax=acc1,ay=acc2,az=acc3"``).
    """
    return read(path, columns=columns, units=units, kind="poses").poses


def load(path: str | Path, options: ReadOptions | None = None, **overrides: Any) -> PoseTable:
    """Load DATA, a pose table or a raw recording, as a :class:`~optcal.core.poses.PoseTable`.

    The poses of :func:`read` (which also returns the decisions, the recording and its
    segmentation: ``optcal.load``).

    Parameters
    ----------
    path : str or Path
        CSV/text, Parquet, MAT/netCDF/HDF5, ROS 1 bag, ROS 2 bag (directory), or PX4 ULog file.
    options : ReadOptions, optional
        The reading options (:class:`ReadOptions`).
    **overrides
        Any field of :class:`ReadOptions` (``columns``, ``units``, ``topic``, ``rate``,
        ``kind``, ``time_unit``, ``timing``, ``gyro_file``, ``gyro_units``, ``static``) or
        static-detection setting (``window_s``, ``threshold``, ``min_dwell_s``, ...).

    Returns
    -------
    PoseTable
        ``source`` is ``"pose table"`` or ``"raw recording"``; ``decisions`` says why and
        how (also ``meta["decisions"]``); for a recording ``meta["segmentation"]`` lists the
        intervals.

    Raises
    ------
    InputError
        An unknown keyword, unreadable file, unknown columns, time running backwards, no
        static interval, ...
    """
    return read(path, options, **_overrides(overrides)).poses
