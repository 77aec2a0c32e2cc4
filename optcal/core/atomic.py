"""Files written whole or not at all: a temporary file in the target's folder, renamed when complete.

A reader of the target (a firmware flasher, the next command of a pipeline) sees either the
previous file or the complete new one, never a file cut by a full disk, an interrupted run
(Ctrl-C) or a second run writing the same path: :func:`atomic_path` hands out a temporary
path beside the target (the same file system, so the final :func:`os.replace` is one atomic
rename, POSIX ``rename(2)``), flushes it to the disk, renames it, and removes it on any
failure.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "write_text_atomic"]


def _fsync(path: Path) -> None:
    """Flush ``path``'s data to the disk (a full disk shows here at the latest, before the rename)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _umask() -> int:
    """The process' file-creation mask (read by setting it and setting it back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed to ``path`` when the block completes.

    The temporary file keeps the target's suffix (writers that choose the format by the
    suffix, such as Matplotlib's ``savefig`` or pandas' Parquet, write the same format).  On
    any exception, :class:`KeyboardInterrupt` included, the temporary file is removed and the
    target is left as it was.

    Parameters
    ----------
    path : str or Path
        The file to write (replaced when it exists); its folder must exist.

    Yields
    ------
    Path
        The temporary file (created empty, with the permissions a new file would get).

    Raises
    ------
    OSError
        The folder is not writable, or the disk is full (nothing is left behind); its
        ``filename`` is ``path``.
    """
    target = Path(path)
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".part{target.suffix}", dir=target.parent or ".")
    except OSError as exc:  # named by the target, not by the temporary name the user never gave
        raise OSError(exc.errno, exc.strerror, str(target)) from None
    os.close(fd)
    tmp = Path(name)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's 0600 would make the output private
        yield tmp
        _fsync(tmp)
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror, str(target)) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomic(path: str | Path, text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` whole or not at all (:func:`atomic_path`).

    Parameters
    ----------
    path : str or Path
    text : str
    encoding : str
    """
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)
