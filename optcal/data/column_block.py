"""The reader's column block and pyarrow's numbers in it (:mod:`optcal.data.text`'s large-file readers).

:class:`ColumnBlock` holds a file's float columns once, column-major, in base pages (:func:`base_pages`);
:func:`arrow_numbers` reads a pyarrow array's numbers without a copy; :func:`release_unused` hands the memory a
pyarrow pool freed back to the system.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["ColumnBlock", "arrow_numbers", "base_pages", "release_unused"]


def base_pages(shape: tuple[int, int]) -> NDArray[np.float64]:
    """An uninitialised float array of ``shape`` in Fortran order, in an anonymous mapping of the system's base pages.

    numpy's allocator asks the kernel for transparent huge pages for any array above 4 MiB; the reader's block is
    written once, front to back, as the file is read, and there the huge pages' first touch cost more than the base
    pages' faults: on the 12-hour still log (242 MB of numbers) `optcal allan` spent 1.03-1.15 s of system time with
    them and 0.70-0.79 s without (three runs each, alternating, on the two-core machine), on the reading's serial
    path.  Pages never written take no memory, as with ``np.empty``; the mapping is released with the array.

    The mapping is private where the system has one (:data:`PRIVATE_MAPPING`): a private page's first touch is a
    plain anonymous fault, a shared mapping's goes through the kernel's shared-memory file (0.12 against 0.18 s of
    CPU to write 266 MB in the reader's batch-sized pieces, three runs each).
    """
    import mmap

    size = max(1, shape[0] * shape[1]) * np.dtype(np.float64).itemsize
    flags = PRIVATE_MAPPING
    buffer = mmap.mmap(-1, size) if flags is None else mmap.mmap(-1, size, flags=flags)
    return np.ndarray(shape, dtype=np.float64, buffer=buffer, order="F")


def _private_mapping() -> int | None:
    """``MAP_PRIVATE | MAP_ANONYMOUS``, or ``None`` where :mod:`mmap` has no such flags (Windows)."""
    import mmap

    private, anonymous = getattr(mmap, "MAP_PRIVATE", None), getattr(mmap, "MAP_ANONYMOUS", None)
    return None if private is None or anonymous is None else private | anonymous


#: The flags of :func:`base_pages`' mapping (``None``: :mod:`mmap`'s default, a shared one).
PRIVATE_MAPPING: int | None = _private_mapping()


class ColumnBlock:
    """Float columns filled chunk by chunk into one column-major (Fortran-order) array.

    The array is allocated for an estimate of the row count (pages never written take no
    memory) and grown by half when a chunk does not fit; :meth:`columns` returns contiguous
    views of its filled rows, so the numbers are held once, not once per chunk and once joined.
    """

    def __init__(self, width: int, rows: int) -> None:
        self.block = base_pages((max(1, rows), width))
        self.n = 0

    def append(self, cols: list[NDArray[np.float64]]) -> None:
        """Copy one chunk's columns below the rows already filled."""
        k = int(cols[0].size) if cols else 0
        if self.n + k > self.block.shape[0]:
            grown = base_pages((max(self.n + k, self.block.shape[0] * 3 // 2), self.block.shape[1]))
            grown[: self.n] = self.block[: self.n]
            self.block = grown
        for j, col in enumerate(cols):
            self.block[self.n:self.n + k, j] = col
        self.n += k

    def release_rows(self, start: int, stop: int) -> None:
        """Hand the whole pages of rows ``start`` to ``stop`` of every column back to the system (they read as 0).

        The block is a private anonymous mapping (:func:`base_pages`), whose pages ``MADV_DONTNEED`` frees; a shared
        one (where the system has no private one) only by ``MADV_REMOVE`` (``MADV_DONTNEED`` would unmap them and
        keep their memory); where the system has no such call, nothing.
        """
        import mmap

        buffer = self.block.base
        remove = getattr(mmap, "MADV_REMOVE" if PRIVATE_MAPPING is None else "MADV_DONTNEED", None)
        if not isinstance(buffer, mmap.mmap) or stop <= start or remove is None:
            return
        page = mmap.PAGESIZE
        for j in range(self.block.shape[1]):
            a = (j * self.block.shape[0] + start) * 8
            b = (j * self.block.shape[0] + stop) * 8
            a = -(-a // page) * page
            b = b // page * page
            if b > a:
                buffer.madvise(remove, a, b - a)

    def columns(self) -> list[NDArray[np.float64]]:
        """The filled rows of every column (contiguous views into the block)."""
        return [self.block[: self.n, j] for j in range(self.block.shape[1])]


#: pyarrow's primitive number types by name, read straight from their buffer (:func:`arrow_numbers`).
_ARROW_DTYPES: dict[str, str] = {"double": "<f8", "float": "<f4", "int64": "<i8", "int32": "<i4", "int16": "<i2",
                                 "int8": "i1", "uint64": "<u8", "uint32": "<u4", "uint16": "<u2", "uint8": "u1"}


def arrow_numbers(chunk: Any) -> NDArray[Any]:
    """A pyarrow array of numbers as a NumPy array: a primitive type without nulls read from its data buffer (no
    copy; pyarrow's own ``to_numpy`` imports pandas, half a second a process need not spend), else by ``to_numpy``."""
    dtype = _ARROW_DTYPES.get(str(chunk.type))
    if dtype is None or chunk.null_count or np.dtype(dtype).byteorder not in ("<", "|", "="):
        return np.asarray(chunk.to_numpy(zero_copy_only=False))
    data = chunk.buffers()[1]
    if data is None:
        return np.asarray(chunk.to_numpy(zero_copy_only=False))
    size = np.dtype(dtype).itemsize
    return np.frombuffer(data, dtype=dtype, count=len(chunk), offset=chunk.offset * size)


def release_unused(pool: Any) -> None:
    """Hand the memory ``pool`` holds freed back to the system: the system allocator's by glibc's ``malloc_trim``
    (every thread's arena; pyarrow's ``release_unused`` of the system pool kept it: 104 against 48-62 MiB after reading
    the 2-hour still log), any other pool by its own ``release_unused``."""
    if pool.backend_name == "system":
        trim = _malloc_trim()
        if trim is not None:
            trim(0)
    else:
        pool.release_unused()


@cache
def _malloc_trim() -> Any:
    """glibc's ``malloc_trim``, or ``None`` (another C library)."""
    import ctypes

    try:
        return ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):
        return None
