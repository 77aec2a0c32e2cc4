"""Applying a calibration to a whole file: every row corrected, every other column passed through.

:func:`apply_to_file` reads DATA (a raw recording or a pose table, any supported format),
corrects every row with :meth:`Calibration.correct <optcal.families.caltypes.base.Calibration.correct>`
(temperature and time from DATA's own columns when the calibration needs them) and returns
the file's table with the three acceleration columns replaced by the calibrated ones
(``ax_g, ay_g, az_g`` or ``ax_m_s2, ...``: the unit word in the name, which optcal's readers
recognise) and a status column :data:`STATUS_COLUMN`.  Nothing is dropped: the row count is
unchanged, and rows that are not finite, were excluded by the recording checks (duplicated
samples, repeated timestamps, saturation) or lie outside the calibration's validity range are
marked in the status column and counted.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.families.caltypes.base import Calibration, ValidityRangeWarning
from optcal.errors import InputError
from optcal.core.model import STANDARD_GRAVITY

if TYPE_CHECKING:
    from optcal.data.options import ReadOptions

#: Name of the column that marks each row.
STATUS_COLUMN: str = "optcal_status"
#: Status words, in the order they are reported.
STATUS_WORDS: tuple[str, ...] = ("ok", "out_of_range", "excluded", "non_finite")
#: Output units → (factor from g, unit word appended to the column names).
OUTPUT_UNITS: dict[str, tuple[float, str]] = {"g": (1.0, "g"), "m/s^2": (STANDARD_GRAVITY, "m_s2")}
#: Output file extensions → format.
OUTPUT_FORMATS: dict[str, str] = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet"}
_G_FACTOR: dict[str, float] = {"g": 1.0, "m/s^2": STANDARD_GRAVITY}


@runtime_checkable
class CorrectsGyro(Protocol):
    """A calibration that corrects the gyro columns as well (cal_type imu, :mod:`optcal.families.gyro.result`; a peer's with a gyro)."""

    gyro_units: str | None

    def correct_gyro(self, gyro: ArrayLike, acc: ArrayLike | None = None) -> NDArray[np.float64]:
        """Body rate in rad/s for raw gyro samples (and raw ``acc``)."""
        ...


@dataclass
class AppliedFile:
    """A file corrected by a calibration.

    Attributes
    ----------
    frame : pandas.DataFrame
        The output table (same rows as the file).
    kind : str
        ``"raw recording"`` or ``"pose table"``, and :attr:`kind_reason` why.
    units_in : str
        Units of DATA (decided as every command does), :attr:`units_reason` why.
    units_out : str
    status_counts : dict of str to int
        Rows per status word.
    exclusions : dict of str to int
        Why rows were excluded and marked in the status column (recordings: duplicated, repeated timestamp,
        saturated, non-finite).
    read_exclusions : dict of str to int
        What the file's own reader counted while reading a log container (a DataFlash log's unhealthy rows, a
        ULog's truncated message): rows it left out are not in the output (a ``GH`` = 0 row is, its gyro columns
        empty).
    range_notes : list of str
        What lies outside the validity range, and by how much.
    header : dict of str to str
        Metadata lines above the CSV header, written back above it.
    time_reason : str
        How the time column was read (unit and scale), when there is one.
    gravity_m_s2 : float
        m/s² per g of the m/s² output: the standard gravity, or a peer calibration's own g (its
        m/s² are then the peer's own output).
    """

    frame: Any
    kind: str
    kind_reason: str
    units_in: str
    units_reason: str
    units_out: str
    status_counts: dict[str, int]
    exclusions: dict[str, int] = field(default_factory=dict)
    range_notes: list[str] = field(default_factory=list)
    header: dict[str, str] = field(default_factory=dict)
    time_reason: str = ""
    gravity_m_s2: float = STANDARD_GRAVITY
    read_exclusions: dict[str, int] = field(default_factory=dict)

    @property
    def n_rows(self) -> int:
        return int(len(self.frame))


def convert_samples(acc: NDArray[np.float64], units: str, to_units: str) -> NDArray[np.float64]:
    """Samples in ``to_units`` (g ↔ m/s²; counts only to counts)."""
    if units == to_units:
        return acc
    if units in _G_FACTOR and to_units in _G_FACTOR:
        return acc * (_G_FACTOR[to_units] / _G_FACTOR[units])
    raise InputError(
        f"the calibration takes {to_units} but DATA is in {units}; give DATA in {to_units} "
        f"(or pass units=\"{to_units}\" if that is what it is)"
    )


def apply_to_file(
    cal: Calibration,
    path: str | Path,
    options: ReadOptions | None = None,
    *,
    units_out: str = "g",
    **overrides: Any,
) -> AppliedFile:
    """Correct every row of DATA with ``cal``.

    Parameters
    ----------
    cal : Calibration
    path : str or Path
        DATA: CSV, Parquet, ROS bag or ULog; a raw recording or a pose table.
    options : ReadOptions, optional
        How DATA is read (:class:`optcal.data.ReadOptions`; the static-detection settings are
        not used: every row is corrected).
    units_out : {"g", "m/s^2"}
        Units of the calibrated accelerations.
    **overrides
        Any field of :class:`optcal.data.ReadOptions` (``columns``, ``units``, ``topic``,
        ``rate``, ``kind``, ...) over ``options``.

    Raises
    ------
    InputError
        Unreadable DATA, units that cannot be converted, or a temperature or time column the
        calibration needs and DATA lacks.
    """
    from optcal.data import POSE_TABLE
    from optcal.data.options import ReadOptions, read_decided
    from optcal.data.readers import ACC, GYRO, read_parquet
    from optcal.data.recording import recording_from_source
    from optcal.data.text import read_frame

    if units_out not in OUTPUT_UNITS:
        raise InputError(f"unknown output units {units_out!r}; use g or m/s^2")
    src, decisions = read_decided(path, ReadOptions.build(options, **overrides))  # the one reading path
    decision = decisions.kind
    acc = np.column_stack([src.column(c) for c in ACC])
    temp = src.column("temp") if src.has("temp") else None
    exclusions: dict[str, int] = {}
    time_reason = src.time_reason
    if decision.value == POSE_TABLE:
        t = src.column("t") if src.has("t") else None
        # the rows the reader excluded (all-zero, absurd) are marked excluded, as a recording's samples are
        evidence_usable = decisions.evidence.usable if decisions.evidence is not None else None
        usable = np.ones(len(acc), dtype=bool) if evidence_usable is None else np.asarray(evidence_usable, dtype=bool)
        exclusions = dict(decisions.exclusions) if not usable.all() else {}
        units_in, units_reason = str(decisions.units.value), decisions.units.reason
    else:
        # every row is corrected, a held value's repeats too (they are rows of the output)
        rec = recording_from_source(src, decisions, keep_gyro_rail=True, keep_held=True)
        t, usable, units_in, units_reason = rec.t, rec.usable, rec.units, rec.units_reason
        time_reason = rec.time_reason
        exclusions = dict(rec.exclusions)
    needed: list[NDArray[np.float64]] = []
    for column in cal.needs:
        values = temp if column == "temp" else t
        if values is None:
            what = "temperature column (temp, °C)" if column == "temp" else "time column (t, s) or rate"
            raise InputError(
                f"{path}: has no {what}, and the {cal.cal_type} calibration needs it (its terms depend on "
                f"{'temperature' if column == 'temp' else 'time'}); add the column or map it with columns=\"{column}=NAME\""
            )
        needed.append(values)
    raw = convert_samples(acc, units_in, cal.units)
    finite = np.all(np.isfinite(raw), axis=1)
    for values in needed:
        finite &= np.isfinite(values)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ValidityRangeWarning)
        corrected = np.full(raw.shape, np.nan)
        pick = (lambda v: None if v is None else v[finite])  # noqa: E731
        corrected[finite] = cal.correct(raw[finite], pick(temp), pick(t))
    range_notes = [str(w.message) for w in caught if issubclass(w.category, ValidityRangeWarning)]
    outside = np.zeros(len(raw), dtype=bool)
    outside[finite] = cal.out_of_range(corrected[finite], pick(temp), pick(t))

    # a correction that overflows (a scale far outside a sensor's) is no corrected value: marked, never "ok"
    finite &= np.all(np.isfinite(corrected), axis=1)
    status = np.full(len(raw), "ok", dtype=object)
    status[outside] = "out_of_range"
    status[~usable] = "excluded"
    status[~finite] = "non_finite"
    factor, word = OUTPUT_UNITS[units_out]
    # a peer's calibration (imucal, imu_tk) outputs m/s² at its own g: written as the peer writes them
    gravity = float(getattr(cal, "gravity_m_s2", STANDARD_GRAVITY))
    if units_out == "m/s^2":
        factor = gravity

    if src.file_type in ("csv", "parquet"):
        frame, header = read_frame(path) if src.file_type == "csv" else (read_parquet(path), {})
    else:
        import pandas as pd

        frame, header = pd.DataFrame(src.data), {}
        for name, values in src.extra.items():
            frame[name] = values
    if len(frame) != len(raw):
        raise InputError(f"{path}: read {len(frame)} rows but {len(raw)} samples; cannot pass the columns through")
    def frame_column(role: str) -> Any:
        """The frame's column holding ``role`` (a headerless file's columns are named by position: '#2' is '2'; a
        container's frame, built from the source's samples, by the role itself: a DataFlash log's ``IMU.AccX``
        is its ``ax``)."""
        name = src.column_map.get(role, role)
        if name not in frame.columns and name.startswith("#") and name[1:] in frame.columns:
            return name[1:]
        if name not in frame.columns and role in frame.columns:
            return role
        return name

    names = [frame_column(c) for c in ACC]
    position = min(list(frame.columns).index(n) for n in names)
    frame = frame.drop(columns=names)
    for k, axis in enumerate("xyz"):
        frame.insert(position + k, f"a{axis}_{word}", corrected[:, k] * factor)
    if isinstance(cal, CorrectsGyro) and getattr(cal, "has_gyro", True) and src.has(*GYRO):  # imu, peer: gyro to rad/s
        from optcal.core.units import normalise_units

        if src.gyro_units is not None and normalise_units(src.gyro_units, "gyro") != cal.gyro_units:
            raise InputError(f"{path}: its gyro columns are in {src.gyro_units}, the calibration's in {cal.gyro_units}")
        gyro = np.full(raw.shape, np.nan)  # NaN where the log marks the gyro sample unhealthy (Source.gyro_unhealthy)
        g_ok = finite if src.gyro_unhealthy is None else finite & ~src.gyro_unhealthy
        gyro[g_ok] = cal.correct_gyro(np.column_stack([src.column(c) for c in GYRO])[g_ok], raw[g_ok])
        gnames = [frame_column(c) for c in GYRO]
        if all(n in frame.columns for n in gnames):  # replaced in place
            gpos = min(list(frame.columns).index(n) for n in gnames)
            frame = frame.drop(columns=gnames)
        else:  # from a gyro file (gyro_file), interpolated onto DATA's times: added after DATA's columns
            gpos = len(frame.columns)
        for k, axis in enumerate("xyz"):
            frame.insert(gpos + k, f"g{axis}_rad_s", gyro[:, k])
    frame[STATUS_COLUMN] = status
    counts = {w: int(np.sum(status == w)) for w in STATUS_WORDS if np.any(status == w)}
    read_exclusions = {k: v for k, v in src.exclusions.items() if k in exclusions}  # counted by a container's reader
    marked = {k: v for k, v in exclusions.items() if k not in read_exclusions}
    return AppliedFile(
        frame, decision.value, decision.reason, units_in, units_reason, units_out, counts, marked, range_notes, header,
        time_reason if t is not None else "", gravity, read_exclusions,
    )


def write_table(applied: AppliedFile, path: str | Path) -> str:
    """Write the output as CSV or Parquet by the extension of ``path``; returns the format."""
    p = Path(path)
    fmt = OUTPUT_FORMATS.get(p.suffix.lower())
    if fmt is None:
        raise InputError(f"{p}: give an output file ending in .csv or .parquet (the format follows the extension)")
    from optcal.core.atomic import atomic_path

    with atomic_path(p) as tmp:  # whole or not at all (a full disk or Ctrl-C leaves the target as it was)
        if fmt == "parquet":
            try:
                applied.frame.to_parquet(tmp, index=False)
            except ImportError as exc:
                raise InputError("writing Parquet files needs pyarrow: pip install 'optcal[parquet]'") from exc
            return fmt
        with tmp.open("w", newline="") as fh:
            for key, value in applied.header.items():
                fh.write(f"{key},{value}\n" if value else f"# {key}\n")
            applied.frame.to_csv(fh, index=False)
    return fmt
