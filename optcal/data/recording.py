"""A raw recording: a time series of accelerometer (and gyro, temperature) samples.

:func:`recording_from_source` turns what a reader found into a :class:`Recording`: time in
seconds (from a time column, or from the sample index and the sampling rate), units
decided, and every unusable sample flagged and counted (non-finite cells, duplicated
samples and repeated timestamps, saturated samples).  Time running backwards is an
error, because it means the file is two logs glued together or its clock is broken, and
sorting it would silently interleave them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import ACC, GYRO
from optcal.data.decisions import DataDecisions, Decision, decide, with_decisions
from optcal.data.evidence import NON_FINITE, Evidence, gather_evidence
from optcal.data.held_samples import held_rows
from optcal.data.quantiles import median
from optcal.data.rails import GyroRail, gyro_rail, rail_samples
from optcal.data.readers import Source
from optcal.data.units import NominalConversion, nominal_conversion
from optcal.errors import InputError

#: Exclusion counters of :class:`Recording` (also used as keys of ``PoseTable.exclusions``);
#: :data:`NON_FINITE` and the other reading exclusions are in :mod:`optcal.data.decisions`.
DUPLICATED = "duplicated samples (same time and values as the previous one)"
REPEATED_TIME = "samples with a repeated timestamp (the first one kept)"
SATURATED = "saturated samples"
GYRO_SATURATED = "samples with the gyro at its rail (in no rest, their moves out of the gyro fit; --keep-gyro-rail keeps them)"
#: A rail lies at least this far (in g, by the nominal conversion) from the axis's zero.
SATURATION_MIN_G: float = 1.5
HELD = "accelerometer rows repeating its last update (a slower sensor in a faster log; --keep-held keeps them)"
HELD_TORN = "accelerometer rows holding axes of two updates (a logger's torn copy between them)"


@dataclass
class Recording:
    """A raw time series in the units of the file.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Time of each sample, seconds.
    acc : ndarray, shape (n, 3)
        Accelerometer samples, raw units.
    gyro : ndarray, shape (n, 3) or None
        Gyro samples in the file's units.
    temp : ndarray, shape (n,) or None
        Temperature, °C.
    row : ndarray of int, shape (n,)
        Data row (1-based) or message number of each sample in the file (int32 when every
        number fits).
    usable : ndarray of bool, shape (n,)
        Samples that may enter a static interval (finite, not duplicated, not saturated).
    units : str
    units_reason : str
    gyro_units : str or None
    rate_hz : float
        Median sampling rate.
    time_reason : str
    path, file_type : str
    exclusions : dict of str to int
        The samples flagged as unusable, by reason.
    meta : dict
    decisions : DataDecisions or None
        Every decision about the file, with its reason.
    nominal : NominalConversion or None
        The nominal conversion of the usable samples (:func:`optcal.data.units.nominal_conversion`
        of ``acc[usable]``), made once while converting for the saturation check and the static
        detection; ``None`` to have it made from the samples when needed.
    gyro_rail : GyroRail or None
        The gyro samples at a saturation rail (None: none found, or no gyro); unless ``gyro_rail_kept``, they enter
        no static interval and the moves holding them are left out of the gyro's fit (they stay ``usable``: the
        accelerometer's reading is sound).
    gyro_rail_kept : bool
        ``--keep-gyro-rail``: the gyro's rails were found and kept.
    gyro_unhealthy : ndarray of bool or None
        Usable samples whose gyro reading the file marks unusable (a DataFlash ``GH`` = 0, counted while reading):
        their accelerometer sample is used, their gyro sample is not (:attr:`gyro_usable`).
    """

    t: NDArray[np.float64]
    acc: NDArray[np.float64]
    gyro: NDArray[np.float64] | None
    temp: NDArray[np.float64] | None
    row: NDArray[np.int32] | NDArray[np.int64]
    usable: NDArray[np.bool_]
    units: str
    units_reason: str
    gyro_units: str | None
    rate_hz: float
    time_reason: str
    path: str
    file_type: str
    exclusions: dict[str, int] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    decisions: DataDecisions | None = None
    nominal: NominalConversion | None = None
    gyro_rail: GyroRail | None = None
    gyro_rail_kept: bool = False
    gyro_unhealthy: NDArray[np.bool_] | None = None

    @property
    def n(self) -> int:
        return int(self.t.size)

    @property
    def gyro_usable(self) -> NDArray[np.bool_]:
        """The usable samples whose gyro reading may be used too: ``usable`` less :attr:`gyro_unhealthy`.

        Whatever reads the gyro (the rests, which it gates and whose bias it gives; the moves it integrates; its
        noise; the Ferraris turns) reads these rows; a row marked unhealthy is a hole in the gyro's record, its
        accelerometer sample still read where the accelerometer is used alone.
        """
        return self.usable if self.gyro_unhealthy is None else self.usable & ~self.gyro_unhealthy

    @property
    def n_usable(self) -> int:
        """Samples not excluded (the rows counted in ``exclusions`` are not)."""
        return int(np.count_nonzero(self.usable))

    @property
    def duration_s(self) -> float:
        """Time from the first to the last usable sample (excluded rows may have no time)."""
        idx = np.flatnonzero(self.usable)
        return float(self.t[idx[-1]] - self.t[idx[0]]) if idx.size > 1 else 0.0


def recording_from_source(
    src: Source,
    decisions: DataDecisions | None = None,
    *,
    evidence: Evidence | None = None,
    units: str | None = None,
    rate: float | None = None,
    time_unit: str | None = None,
    timing: str = "auto",
    required_by: str = "reading a recording",
    keep_gyro_rail: bool = False,
    gyro_range_dps: float | None = None,
    keep_held: bool = False,
) -> Recording:
    """Build a :class:`Recording` from a reader's :class:`Source` (the conversion step).

    Parameters
    ----------
    src : Source
    decisions : DataDecisions, optional
        Made by :func:`optcal.data.decisions.decide`; made here (as a raw recording, with the
        keyword options) when omitted.
    evidence : Evidence, optional
        The evidence the decisions were made from, when ``decisions`` do not hold it (gathered
        here when neither has it).
    units, rate, time_unit, timing
        Options of :func:`optcal.data.decisions.decide` when ``decisions`` is omitted.
    required_by : str
        What requires a raw recording (the reason of the kind decision when ``decisions`` is
        omitted), e.g. ``"the allan command"``.
    keep_gyro_rail : bool
        Let the gyro's samples at a saturation rail into the rests and the gyro fit (``--keep-gyro-rail``); by default they are
        counted (:data:`GYRO_SATURATED`), kept out of the rests and their moves out of the gyro's fit.
    gyro_range_dps : float, optional
        The gyro's full scale, ±°/s, as stated (``--gyro-range``): tightens the bound a rail of a gyro of unknown
        scale lies beyond (:func:`optcal.data.rails.gyro_rail`).
    keep_held : bool
        Keep every row where the accelerometer's value is held over several rows of a faster log (``--keep-held``;
        by default the first row of each update is kept and the repeats counted: :mod:`optcal.data.held_samples`).

    Raises
    ------
    DataInputError
        No time and no rate, time running backwards, or no usable sample (with the decisions made).
    """
    if decisions is None:
        ev = evidence if evidence is not None else gather_evidence(src)
        decisions = decide(
            src, ev, kind="raw", units=units, rate=rate, time_unit=time_unit, timing=timing, required_by=required_by
        )
    try:
        return _convert(src, decisions, evidence, keep_gyro_rail, gyro_range_dps, keep_held)
    except InputError as exc:
        raise with_decisions(exc, decisions) from exc


def _convert(src: Source, decisions: DataDecisions, evidence: Evidence | None, keep_gyro_rail: bool = False,
             gyro_range_dps: float | None = None, keep_held: bool = False) -> Recording:
    """The decisions applied to ``src`` (see :func:`recording_from_source`)."""
    if decisions.evidence is not None:  # the evidence of the columns as decided
        ev = decisions.evidence
    else:
        ev = evidence if evidence is not None else gather_evidence(src)
    n = src.n_rows
    acc = src.block(ACC)
    gyro = src.block(GYRO) if src.has(*GYRO) else None
    temp = src.column("temp") if src.has("temp") else None
    row: NDArray[np.int32] | NDArray[np.int64]  # int32 when it fits: half the memory
    row = np.arange(1, n + 1, dtype=np.int32) if n < 2**31 - 1 else np.arange(1, n + 1, dtype=np.int64)
    if decisions.time_base.value == "rate":
        if src.has("index"):
            base = src.column("index")
            t = (base - base[0]) / float(decisions.rate.value)
        else:  # in place: no temporaries of the row numbers
            t = np.arange(n, dtype=float)
            t /= float(decisions.rate.value)
    else:
        t = src.column("t")
    exclusions: dict[str, int] = dict(src.exclusions)
    for k, v in decisions.exclusions.items():
        _count(exclusions, k, v)
    usable = ev.usable.copy()
    if decisions.time_base.value == "rate":
        usable &= np.isfinite(t)
    held = None if keep_held else held_rows(acc, usable)  # a slower accelerometer in a faster log (held_samples)
    if held is not None:  # one row per update: the repeats weigh no value several times, and are counted
        keep, runs = held
        t, acc, row, usable = t[keep], acc[keep], row[keep], usable[keep]
        gyro, temp = (None if gyro is None else gyro[keep]), (None if temp is None else temp[keep])
        _count(exclusions, HELD, runs.n_repeats)
        _count(exclusions, HELD_TORN, int(runs.torn.size))
    if keep_held and (found := held_rows(acc, usable)) is not None:
        decisions.warnings.append(found[1].describe("accelerometer", "--keep-held", kept=True))
    elif held is not None:
        decisions.warnings.append(held[1].describe("accelerometer", "--keep-held"))
    # row numbers over a rate, and samples spread evenly, never repeat a time: no search for duplicates
    retimed = decisions.time_base.value == "uniform" or (decisions.time_base.value == "rate" and not src.has("index"))
    same = np.empty(0, dtype=np.intp)
    if not retimed:
        # every row usable (the common case): the steps of the column itself, no gathered copy of it
        same = np.flatnonzero(np.diff(t if usable.all() else t[np.flatnonzero(usable)]) == 0)
    if same.size:
        idx = np.flatnonzero(usable)
        later = idx[same + 1]
        earlier = idx[same]
        identical = np.all(acc[later] == acc[earlier], axis=1)
        if gyro is not None:
            identical &= np.all(gyro[later] == gyro[earlier], axis=1)
        usable[later] = False
        _count(exclusions, DUPLICATED, int(np.sum(identical)))
        _count(exclusions, REPEATED_TIME, int(np.sum(~identical)))
    units = str(decisions.units.value)
    # the evidence's statistics are the ones over these rows when no duplicate was set aside
    if int(np.count_nonzero(usable)) == int(np.count_nonzero(ev.usable)):
        nominal = decisions.nominal if decisions.nominal is not None else nominal_conversion(
            units, None, median_norm=ev.median_norm, extremes=ev.extremes, medians=ev.medians,
            midscale_norm=ev.midscale_norm)
    else:
        nominal = nominal_conversion(units, acc if usable.all() else acc[usable])
    def rows(flags: NDArray[np.bool_] | None) -> NDArray[np.bool_] | None:  # a reader's per-row flags, on the rows kept
        return flags if flags is None or held is None else flags[held[0]]

    sat = saturated_samples(acc, usable, units, rows(src.saturated), nominal=nominal)
    unhealthy = rows(src.gyro_unhealthy) if gyro is not None and src.gyro_unhealthy is not None else None
    rail = None if gyro is None else gyro_rail(gyro, usable if unhealthy is None else usable & ~unhealthy,
                                             src.gyro_units, rows(src.gyro_saturated), units, gyro_range_dps)
    n_saturated = int(np.count_nonzero(sat & usable))
    _count(exclusions, SATURATED, n_saturated)
    usable &= ~sat
    # a gyro at its rail: its samples stay usable (the accelerometer's reading is sound, and the rests' blocks stay
    # where they were) but enter no rest (data/static.py) and their moves no gyro fit (families/gyro/moves.py)
    if rail is not None and not keep_gyro_rail:
        _count(exclusions, GYRO_SATURATED, int(np.count_nonzero(rail.samples & usable)))
    if rail is not None and rail.samples.any():  # said, kept or not
        decisions.warnings.append(rail.describe(src.gyro_units, keep_gyro_rail))
    elif gyro_range_dps is not None:  # the stated full scale's use said even where it found no rail
        decisions.warnings.append("--gyro-range: no gyro read" if rail is None else
                                  f"no gyro rail found beyond {rail.limit:.4g} from its zero ({rail.unit})")
    if n_saturated:  # the conversion of the samples left
        nominal = nominal_conversion(units, acc[usable])
    if not usable.any():
        raise InputError(f"{src.path}: no usable sample (all are non-finite, duplicated or saturated)")
    same_rows = int(np.count_nonzero(usable)) == int(np.count_nonzero(ev.usable))
    if (decisions.time_base.value == "stamps" and not same_rows) or held is not None:  # the median step of the samples left
        steps = np.diff(t[usable])
        step = median(steps) if steps.size else 0.0
        rate_hz = float(1.0 / step) if step > 0 else float("nan")
        decisions.rate = Decision(rate_hz, decisions.rate.reason, decisions.rate.flag)
    else:  # the evidence's, as the decisions took it
        rate_hz = float(decisions.rate.value)
    decisions.exclusions = dict(exclusions)
    meta = {
        "columns": src.describe_columns(),
        "ignored_columns": list(src.ignored_columns),
        "header": dict(src.header),
        "notes": list(src.notes),
    }
    return Recording(
        t=t,
        acc=acc,
        gyro=gyro,
        temp=temp,
        row=row,
        usable=usable,
        units=str(decisions.units.value),
        units_reason=decisions.units.reason,
        gyro_units=src.gyro_units,
        rate_hz=rate_hz,
        time_reason=decisions.time_base.reason,
        path=src.path,
        file_type=src.file_type,
        exclusions=exclusions,
        meta=meta,
        decisions=decisions,
        nominal=nominal,
        gyro_rail=rail if rail is not None and rail.samples.any() else None,
        gyro_rail_kept=keep_gyro_rail,
        gyro_unhealthy=unhealthy if unhealthy is not None and unhealthy.any() else None,
    )


def _count(d: dict[str, int], key: str, value: int) -> None:
    if value:
        d[key] = d.get(key, 0) + int(value)


def saturated_samples(
    acc: NDArray[np.float64],
    usable: NDArray[np.bool_],
    units: str,
    flagged: NDArray[np.bool_] | None = None,
    nominal: NominalConversion | None = None,
) -> NDArray[np.bool_]:
    """Samples with an axis at a saturation rail.

    A rail is an extreme value (minimum or maximum of an axis over the usable samples)
    whose magnitude at least :data:`~optcal.data.rails.SATURATION_MIN_COUNT` samples reach exactly on any
    axis (a clipped signal keeps hitting the same full scale, the same on every axis and
    in both directions; an unclipped one does not) and which lies at least
    :data:`SATURATION_MIN_G` g from the axis's zero, beyond anything gravity alone produces
    (so that the extreme of a coarsely quantised static pose is never taken for a rail);
    or a full-scale value of a 16-bit converter (:data:`~optcal.data.rails.INTEGER_RAILS`) reached by
    integer-valued data.  ``flagged`` adds the file's own saturation flags (ULog clip
    counters).  ``nominal`` is the nominal conversion of ``acc[usable]`` when already made.
    """
    if nominal is None and usable.any():
        nominal = nominal_conversion(units, acc if usable.all() else acc[usable])
    if nominal is None:
        return np.zeros(acc.shape[0], dtype=bool) if flagged is None else np.asarray(flagged, bool).copy()
    # magnitudes matched about zero: a converter's full scale is symmetric about its zero count, not about the offset
    return rail_samples(acc, usable, nominal.offset, SATURATION_MIN_G * nominal.sensitivity, flagged)
