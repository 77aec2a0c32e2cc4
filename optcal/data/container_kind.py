"""Which container a file is, from its first bytes (:func:`container_type`): MATLAB 5, MATLAB 7.3 or HDF5.

Every read of a file asks (a CSV is none of them), so this is apart from :mod:`optcal.data.containers`, whose readers
and their tables of names are imported only when a container is found.
"""

from __future__ import annotations

from pathlib import Path

from optcal.errors import InputError

MAT5_HEADER = b"MATLAB 5.0 MAT-file"
MAT73_HEADER = b"MATLAB 7.3 MAT-file"
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: An HDF5 file may begin with a user block of 512 bytes or any larger power of two (MATLAB 7.3
#: writes its header text there); the signature is looked for at 0, 512, 1024, 2048, ...
HDF5_SMALLEST_USER_BLOCK = 512
#: File name endings that promise an HDF5 file (netCDF-4, HDF5): without its signature the file is corrupt.
HDF5_SUFFIXES: tuple[str, ...] = (".nc", ".nc4", ".h5", ".hdf5", ".he5", ".hdf")

MAT5 = "MATLAB 5 MAT-file"
MAT73 = "MATLAB 7.3 MAT-file"
HDF5 = "HDF5"


def container_type(path: str | Path) -> str | None:
    """:data:`MAT5`, :data:`MAT73` or :data:`HDF5` from the first bytes of ``path``, else ``None``.

    Raises
    ------
    InputError
        A file named as HDF5 (``.nc``, ``.h5``, ...) without the HDF5 signature.
    """
    p = Path(path)
    if not p.is_file():
        return None
    size = p.stat().st_size
    with p.open("rb") as fh:
        head = fh.read(len(MAT5_HEADER))
        if head == MAT5_HEADER:
            return MAT5
        offset = 0
        while offset + len(HDF5_SIGNATURE) <= size:
            fh.seek(offset)
            if fh.read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE:
                return MAT73 if head == MAT73_HEADER else HDF5
            offset = HDF5_SMALLEST_USER_BLOCK if offset == 0 else 2 * offset
    if p.suffix.lower() in HDF5_SUFFIXES:
        raise InputError(f"{p}: the file is truncated or corrupt (no HDF5 signature, which a {p.suffix} file has)")
    return None
