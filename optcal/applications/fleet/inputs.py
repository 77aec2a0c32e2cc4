"""The units of a fleet: INPUT arguments (folders, globs, manifest CSVs) expanded into units.

Every unit is one file (or a ROS 2 bag directory) that :func:`optcal.data.load` reads: a pose
table or a raw recording.  Inputs are resolved on the client into *paths or URLs only*; the
workers open them (:func:`optcal.applications.fleet.unit.read_unit`), so a path on shared storage or an
fsspec URL (``s3://bucket/unit.csv``) works on a remote cluster, and no user file is ever
pickled.

* a **folder**: every data file in it (suffixes :data:`DATA_SUFFIXES`, and ROS 2 bag
  directories), sorted by name, one unit each, named by the file's stem;
* a **glob** (``data/unit_*.csv``, also on an fsspec URL): the files it matches;
* a **manifest CSV**: a CSV whose header has the columns ``unit`` and ``path`` (paths relative
  to the manifest's folder, or URLs), any further columns kept as the unit's metadata;
* any other file or URL: one unit.
"""

from __future__ import annotations

import csv
import glob
from dataclasses import dataclass, field
from pathlib import Path

from optcal.errors import InputError

#: Suffixes of the files a folder contributes (what :mod:`optcal.data.readers` reads; loggers' text dumps
#: often end in .log or .dat, and imu_tk's in .mat).
DATA_SUFFIXES: tuple[str, ...] = (".csv", ".txt", ".tsv", ".log", ".dat", ".mat", ".parquet", ".pq", ".bag", ".ulg",
                                  ".db3", ".mcap")
#: Columns a CSV must have to be read as a manifest.
MANIFEST_COLUMNS: tuple[str, str] = ("unit", "path")


@dataclass(frozen=True)
class UnitInput:
    """One unit of the fleet: its name, where its data are, and the manifest's metadata.

    Attributes
    ----------
    unit : str
        Unit identifier (unique within the run).
    path : str
        Local path or fsspec URL of the unit's data, opened by the worker.
    metadata : dict of str to str
        Further manifest columns (empty for folders and globs).
    """

    unit: str
    path: str
    metadata: dict[str, str] = field(default_factory=dict)


def is_url(path: str) -> bool:
    """Whether ``path`` is an fsspec URL (``scheme://...``) rather than a local path."""
    return "://" in path and not path.startswith("file://")


def _manifest_header(path: Path) -> list[str] | None:
    try:
        with path.open(newline="", encoding="utf-8", errors="replace") as fh:
            first = fh.readline()
    except OSError:
        return None
    names = [c.strip().lower() for c in next(csv.reader([first]), [])]
    return names if all(c in names for c in MANIFEST_COLUMNS) else None


def read_manifest(path: str | Path) -> list[UnitInput]:
    """The units listed in a manifest CSV (columns ``unit``, ``path``, optional metadata).

    Raises
    ------
    InputError
        When the manifest lacks a column, has an empty cell in one, or repeats a unit.
    """
    p = Path(path)
    units: list[UnitInput] = []
    with p.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        fields = {name.strip().lower(): name for name in (reader.fieldnames or [])}
        missing = [c for c in MANIFEST_COLUMNS if c not in fields]
        if missing:
            raise InputError(f"{p}: a manifest needs the columns unit and path; missing {', '.join(missing)}")
        for line, row in enumerate(reader, start=2):
            unit = (row.get(fields["unit"]) or "").strip()
            where = (row.get(fields["path"]) or "").strip()
            if not unit or not where:
                raise InputError(f"{p}, line {line}: empty unit or path; every manifest row needs both")
            resolved = where if is_url(where) or Path(where).is_absolute() else str(p.parent / where)
            meta = {k: (v or "") for k, v in row.items() if k not in (fields["unit"], fields["path"]) and k is not None}
            units.append(UnitInput(unit, resolved, meta))
    return units


def _folder_units(folder: Path) -> list[UnitInput]:
    out = []
    for child in sorted(folder.iterdir()):
        if child.is_dir() and (child / "metadata.yaml").exists():
            out.append(UnitInput(child.name, str(child)))
        elif child.is_file() and child.suffix.lower() in DATA_SUFFIXES and _manifest_header(child) is None:
            out.append(UnitInput(child.stem, str(child)))
    return out


def _glob_units(pattern: str) -> list[UnitInput]:
    if is_url(pattern):
        import fsspec

        fs, _, paths = fsspec.get_fs_token_paths(pattern)
        protocol = fs.protocol if isinstance(fs.protocol, str) else fs.protocol[0]
        return [UnitInput(Path(q).stem, f"{protocol}://{q}") for q in sorted(paths)]
    return [UnitInput(Path(q).stem, q) for q in sorted(glob.glob(pattern, recursive=True))]


def expand_inputs(inputs: list[str]) -> list[UnitInput]:
    """Expand INPUT arguments into units (see the module docstring).

    Unit names must be unique; a name used twice (two folders with ``unit1.csv``) is made
    unique by prefixing the parent folder's name.

    Raises
    ------
    InputError
        When no INPUT is given, an INPUT matches nothing, or names stay ambiguous.
    """
    if not inputs:
        raise InputError("give at least one input: a folder, a glob, a manifest CSV or a data file")
    units: list[UnitInput] = []
    for item in inputs:
        p = Path(item)
        if not is_url(item) and p.is_dir() and not (p / "metadata.yaml").exists():
            found = _folder_units(p)
            if not found:
                raise InputError(f"{item}: the folder holds no data files ({', '.join(DATA_SUFFIXES)})")
        elif not is_url(item) and p.is_file():
            found = read_manifest(p) if _manifest_header(p) is not None else [UnitInput(p.stem, item)]
        elif any(ch in item for ch in "*?["):
            found = _glob_units(item)
            if not found:
                raise InputError(f"{item}: the pattern matches no file")
        elif is_url(item) or (p.is_dir()):
            found = [UnitInput(Path(item.rstrip("/")).stem, item)]
        else:
            raise InputError(f"{item}: no such file, folder or pattern")
        units.extend(found)
    return _unique(units)


def _unique(units: list[UnitInput]) -> list[UnitInput]:
    seen: dict[str, int] = {}
    for u in units:
        seen[u.unit] = seen.get(u.unit, 0) + 1
    out = []
    for u in units:
        if seen[u.unit] > 1:
            u = UnitInput(f"{Path(u.path).parent.name}/{u.unit}", u.path, u.metadata)
        out.append(u)
    names = [u.unit for u in out]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise InputError(f"unit names given more than once: {', '.join(dupes[:5])}; give each unit once (or name them in a manifest)")
    return out
