"""The nine stretches of a Ferraris session: six static faces and three full turns.

A Ferraris session (Ferraris, Grimaldi & Parvis 1995; imucal's ``FerrarisCalibration``) holds the
sensor still with each axis up and down (``x_p`` … ``z_a``) and turns it once about each axis
(``x_rot`` … ``z_rot``).  The stretches are taken, in order of preference:

1. from imucal's **section list** (``--sections FILE``; :func:`optcal.data.sections.read_section_list`),
2. from a **label column** (``part``) naming the section of every row, when the file has one,
3. **found in the recording**: a face is a static interval of the segmentation
   (:mod:`optcal.data.static`) whose mean lies along an axis (the axis nearest to it; of several
   intervals on one face the longest, whose mean is the least noisy; the others are rests held out
   of the fit); a turn is the stretch between two rests on the same face over which the gyro,
   its rest bias removed, integrates to the largest angle about that face's axis (a turn about the
   vertical keeps gravity where it was, so the rests on either side agree), the axis taking at
   least :data:`TURN_AXIS_SHARE` of the integrated angle.

Every choice is kept with its reason (:attr:`Section.how`), for the report.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from optcal.data.recording import Recording
from optcal.data.sections import FACE_NAMES, SECTION_NAMES, TURN_NAMES, read_label_column, read_section_list
from optcal.data.static import Segmentation
from optcal.errors import InputError

__all__ = ["FerrarisRegions", "Section", "find_regions", "regions_from_labels", "regions_from_section_list"]

#: The share of the integrated rotation vector a turn's own axis must carry (cos 30°): a turn about
#: the vertical with the axis within 30° of it; a wobble between rests spreads over the axes.
TURN_AXIS_SHARE: float = float(np.cos(np.radians(30.0)))
#: Axis letter of each face and turn.
AXIS_OF: dict[str, int] = {name: "xyz".index(name[0]) for name in SECTION_NAMES}


@dataclass(frozen=True)
class Section:
    """One stretch of the recording.

    Attributes
    ----------
    name : str
        imucal's section name (``x_p``, ..., ``z_rot``).
    samples : ndarray of int
        Sample indices into the recording (usable samples only).
    how : str
        Where the stretch came from, in words (for the report).
    interval : int or None
        The static interval number, for a face found in the segmentation.
    """

    name: str
    samples: NDArray[np.int64]
    how: str
    interval: int | None = None

    def rows(self, rec: Recording) -> str:
        """The file's data rows of the stretch, as text."""
        r = rec.row[self.samples]
        return f"rows {int(r.min())}-{int(r.max())}"


@dataclass
class FerrarisRegions:
    """The nine sections, how they were taken, and the rests left out of the fit.

    Attributes
    ----------
    sections : dict of str to Section
    source : str
        ``section list``, ``label column`` or ``found``.
    held_out : list of int
        Static intervals (of the segmentation) not used as a face: the rests the fit is checked on.
    notes : list of str
    """

    sections: dict[str, Section]
    source: str
    held_out: list[int] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        missing = [n for n in SECTION_NAMES if n not in self.sections]
        if missing:
            raise InputError(f"the Ferraris sections {', '.join(missing)} are missing ({self.source})")

    def describe(self, rec: Recording) -> list[str]:
        """One line per section: what was taken for what."""
        out = []
        for name in SECTION_NAMES:
            s = self.sections[name]
            out.append(f"{name:<5s}: {s.rows(rec)} ({s.samples.size} samples), {s.how}")
        return out


def _usable(rec: Recording, idx: NDArray[np.int64], name: str, where: str) -> NDArray[np.int64]:
    use = idx[rec.gyro_usable[idx]]  # a section's means and turns read both sensors
    if use.size < 2:
        raise InputError(f"section {name} ({where}) has {use.size} usable sample(s)")
    return use


def regions_from_section_list(rec: Recording, path: str, seg: Segmentation | None = None) -> FerrarisRegions:
    """The sections of imucal's section list: data rows ``start`` (0-based) to ``end`` (exclusive)."""
    listed = read_section_list(path)
    data_row0 = rec.row.astype(np.int64) - 1  # 0-based data row of each sample (imucal's iloc)
    sections = {}
    for name, (start, end) in listed.items():
        lo, hi = np.searchsorted(data_row0, [start, end])
        if hi <= lo:
            raise InputError(f"{path}: section {name} (rows {start}-{end}) holds no sample of the recording ({rec.n} samples)")
        idx = _usable(rec, np.arange(lo, hi, dtype=np.int64), name, path)
        sections[name] = Section(name, idx, f"from the section list {path} (data rows {start} to {end}, end exclusive)")
    return FerrarisRegions(sections, "section list", _held_out(seg, sections))


def regions_from_labels(rec: Recording, column: str, seg: Segmentation | None = None) -> FerrarisRegions:
    """The sections named by a label column (imucal's annotated session: ``part``)."""
    labels = read_label_column(rec.path, column)
    if labels.size < int(rec.row.max()):
        raise InputError(f"{rec.path}: the column {column!r} has fewer rows than the recording")
    per_sample = labels[rec.row.astype(np.int64) - 1]
    found = sorted(set(per_sample.tolist()) & set(SECTION_NAMES))
    other = sorted(set(per_sample.tolist()) - set(SECTION_NAMES))
    sections = {}
    for name in found:
        idx = _usable(rec, np.flatnonzero(per_sample == name).astype(np.int64), name, f"column {column!r}")
        sections[name] = Section(name, idx, f"the rows labelled {name!r} in column {column!r}")
    regions = FerrarisRegions(sections, "label column", _held_out(seg, sections))
    if other:
        regions.notes.append(f"rows labelled {', '.join(repr(o) for o in other[:5])} in column {column!r} are not Ferraris sections")
    return regions


def _held_out(seg: Segmentation | None, sections: dict[str, Section]) -> list[int]:
    """Static intervals that share no sample with a face: the rests the calibration is checked on."""
    if seg is None:
        return []
    used = np.concatenate([sections[n].samples for n in FACE_NAMES if n in sections])
    out = []
    for iv in seg.intervals:
        if not np.any((used >= iv.start) & (used < iv.stop)):
            out.append(iv.number)
    return out


def _face_of(direction: NDArray[np.float64]) -> tuple[str, float]:
    """The face whose axis is nearest to a unit direction, and the angle to it (degrees)."""
    k = int(np.argmax(np.abs(direction)))
    name = f"{'xyz'[k]}_{'p' if direction[k] > 0 else 'a'}"
    return name, float(np.degrees(np.arccos(min(1.0, abs(direction[k])))))


def find_regions(seg: Segmentation) -> FerrarisRegions:
    """Find the six faces and the three turns in a segmented recording (module docstring).

    Raises
    ------
    InputError
        A face or a turn is not in the recording (naming what is missing and how to give it).
    """
    rec = seg.recording
    if rec.gyro is None:
        raise InputError("the Ferraris method needs the gyro columns (gx, gy, gz): its turns calibrate the gyroscope")
    if not seg.intervals:
        raise InputError(f"{rec.path}: no static interval; the Ferraris faces are rests")
    zero = rec.nominal.offset if rec.nominal is not None else np.zeros(3)
    faces: list[str] = []
    tilts: list[float] = []
    for iv in seg.intervals:
        d = iv.mean - zero
        name, tilt = _face_of(d / np.linalg.norm(d))
        faces.append(name)
        tilts.append(tilt)
    sections: dict[str, Section] = {}
    for name in FACE_NAMES:
        on_face = [k for k, f in enumerate(faces) if f == name]
        if not on_face:
            raise InputError(
                f"no rest with {'+' if name[2] == 'p' else '-'}{name[0]} up ({name}) in the recording "
                f"(faces found: {', '.join(sorted(set(faces)))}); Ferraris needs all six faces, or give the "
                "sections with --sections FILE (imucal's section list)"
            )
        k = max(on_face, key=lambda j: seg.intervals[j].n_samples)
        iv = seg.intervals[k]
        others = [seg.intervals[j].number for j in on_face if j != k]
        how = (f"static interval {iv.number}, its mean {tilts[k]:.1f}° from {'+' if name[2] == 'p' else '-'}{name[0]}; "
               f"the longest of {len(on_face)} rest(s) on this face")
        if others:
            how += f" (rests {', '.join(map(str, others))} held out)"
        sections[name] = Section(name, _usable(rec, np.arange(iv.start, iv.stop, dtype=np.int64), name, "interval"), how,
                                 iv.number)
    bias = np.mean([iv.gyro_mean for iv in seg.intervals if iv.gyro_mean is not None], axis=0)
    for name in TURN_NAMES:
        sections[name] = _find_turn(seg, faces, bias, AXIS_OF[name])
    return FerrarisRegions(sections, "found", _held_out(seg, sections))


def sample_dt(rec: Recording) -> NDArray[np.float64]:
    """Each sample's duration: the step to the next sample's time (the last one's, one sampling period)."""
    return np.diff(rec.t, append=rec.t[-1] + 1.0 / rec.rate_hz)


def _find_turn(seg: Segmentation, faces: list[str], bias: NDArray[np.float64], axis: int) -> Section:
    """The stretch between two rests on one face of ``axis`` with the largest integrated turn about it."""
    rec = seg.recording
    gyro = rec.gyro
    assert gyro is not None
    ivs = seg.intervals
    dt = sample_dt(rec)
    best: tuple[float, int, int, NDArray[np.float64]] | None = None
    for i in range(len(ivs) - 1):
        if faces[i][0] != "xyz"[axis]:
            continue
        for j in range(i + 1, len(ivs)):
            if faces[j] != faces[i]:
                break  # a turn about the vertical keeps the face
            lo, hi = ivs[i].stop, ivs[j].start
            use = np.arange(lo, hi)[rec.gyro_usable[lo:hi]]
            if use.size < 2:
                continue
            angle = ((gyro[use] - bias) * dt[use, None]).sum(axis=0)  # raw units × s
            share = abs(angle[axis]) / max(float(np.linalg.norm(angle)), 1e-300)
            if share >= TURN_AXIS_SHARE and (best is None or abs(angle[axis]) > best[0]):
                best = (abs(angle[axis]), i, j, angle)
    name = TURN_NAMES[axis]
    if best is None:
        raise InputError(
            f"no turn about the {'xyz'[axis]} axis found ({name}: a stretch between two rests with {'xyz'[axis]} up or "
            f"down over which the gyro turns about {'xyz'[axis]}); give the sections with --sections FILE (imucal's section list)"
        )
    _, i, j, angle = best
    lo, hi = ivs[i].stop, ivs[j].start
    idx = np.arange(lo, hi, dtype=np.int64)
    share = abs(angle[axis]) / float(np.linalg.norm(angle))
    how = (f"the move from static interval {ivs[i].number} to {ivs[j].number} (both {faces[i]}): the gyro, rest bias "
           f"removed, integrates to {angle[axis]:+.4g} ({rec.gyro_units or 'gyro units'})·s about {'xyz'[axis]} "
           f"({100 * share:.1f} % of the integrated rotation), the largest such turn")
    return Section(name, _usable(rec, idx, name, "move"), how)


def regions_for(seg: Segmentation, sections: str | None = None) -> FerrarisRegions:
    """The nine stretches of a segmented recording, from the first source that has them.

    imucal's section list (``sections``, a JSON or CSV file), else a label column of the file
    (``part``, imucal's annotated session), else found in the recording (:func:`find_regions`).
    """
    from optcal.data.sections import label_column_of

    rec = seg.recording
    label = label_column_of(list(rec.meta.get("ignored_columns", []))) if rec.file_type == "csv" else None
    if sections:
        return regions_from_section_list(rec, sections, seg)
    if label is not None:
        return regions_from_labels(rec, label, seg)
    return find_regions(seg)
