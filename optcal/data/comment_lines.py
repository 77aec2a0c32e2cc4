"""Comment lines among a text file's data rows: found in one scan in C, counted, and left out of the parse.

Loggers write notes between or after their samples (NXP's IMU data logger a ``%`` footer of means and
extremes, others ``#``, ``//`` or ``;``).  A line whose first character after optional blanks is one of
:data:`COMMENT_LINE_MARKS` is a comment wherever it stands: no number starts so.  The readers' fast paths
(numpy, pyarrow) fail on such a line; only then is the file scanned (:func:`find_comment_lines`, a regular
expression over the memory-mapped file, no loop over its lines in Python), and the parsers read the file through
:class:`UncommentedStream`, which hands them the bytes of every other line.  A file without comment lines is
never scanned.
"""

from __future__ import annotations

import io
import mmap
import re
from dataclasses import dataclass
from pathlib import Path

#: Lines above the data starting with one of these are comments (``#`` of most loggers and numpy, ``%`` of MATLAB and
#: NXP's IMU data logger, ``//`` of C-style firmware prints, ``;`` of INI-style notes); the one just above the data
#: may name the columns (:mod:`optcal.data.text`).  None can start a number.  Widening them from ``#``/``%`` left every
#: shared recording's sniffed layout as it was (header, first data line, names, metadata: stranger14's run).
COMMENT_MARKS: tuple[str, ...] = ("#", "%", "//", ";")
#: A line among the data rows starting with one of these (after blanks) is a comment: the same marks.  A mark equal to
#: the file's delimiter is not one (``;`` in a semicolon-separated file starts a row whose first field is empty,
#: which the parser counts as a missing cell).
COMMENT_LINE_MARKS: tuple[str, ...] = COMMENT_MARKS
#: Bytes of the file counted for newlines at a time when numbering the comment lines (the count holds no more).
_COUNT_BYTES: int = 2**24


@dataclass(frozen=True)
class CommentLines:
    """The comment lines among a file's data rows.

    Attributes
    ----------
    spans : tuple of (int, int)
        Byte ranges ``[start, end)`` of each comment line (its newline included), in the file's order.
    lines : tuple of int
        Their 1-based line numbers in the file.
    marks : tuple of str
        The marks they start with, each once, in order of first appearance.
    data_start : int
        Byte offset of the first line after the header (where the scan starts).
    """

    spans: tuple[tuple[int, int], ...]
    lines: tuple[int, ...]
    marks: tuple[str, ...]
    data_start: int

    @property
    def count(self) -> int:
        """How many comment lines there are among the data."""
        return len(self.lines)

    def describe(self) -> str:
        """``2 comment lines among the data skipped (lines 330-335, starting '%')``, or ``""`` when none."""
        if not self.lines:
            return ""
        where = f"line {self.lines[0]}" if len(self.lines) == 1 else f"lines {self.lines[0]}-{self.lines[-1]}"
        return (f"{len(self.lines)} comment line(s) among the data skipped ({where}, starting "
                f"{', '.join(repr(m) for m in self.marks)})")


def find_comment_lines(path: str | Path, first_data_line: int, delimiter: str) -> CommentLines:
    """The comment lines of ``path`` from line ``first_data_line`` (0-based) on.

    One regular expression over the memory-mapped file (a search in C for each newline followed by blanks and a
    mark); the lines are numbered by counting newlines between the hits, in blocks of :data:`_COUNT_BYTES`.
    """
    marks = [m for m in COMMENT_LINE_MARKS if m != delimiter]
    alternatives = b"|".join(re.escape(m.encode()) for m in marks)
    after_newline = re.compile(rb"\n[ \t]*(" + alternatives + rb")")
    at_start = re.compile(rb"[ \t]*(" + alternatives + rb")")
    p = Path(path)
    with p.open("rb") as fh:
        for _ in range(first_data_line):
            fh.readline()
        start = fh.tell()
        size = p.stat().st_size
        if size <= start:
            return CommentLines((), (), (), start)
        with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            hits: list[tuple[int, bytes]] = []
            if (first := at_start.match(mm, start)) is not None:
                hits.append((start, first.group(1)))
            hits.extend((m.start() + 1, m.group(1)) for m in after_newline.finditer(mm, start))
            spans, lines, seen = [], [], []
            line, counted = first_data_line + 1, start
            for offset, mark in hits:
                while counted < offset:  # newlines between the previous hit and this one
                    stop = min(offset, counted + _COUNT_BYTES)
                    line += mm[counted:stop].count(b"\n")
                    counted = stop
                end = mm.find(b"\n", offset)
                spans.append((offset, size if end < 0 else end + 1))
                lines.append(line)
                if (word := mark.decode()) not in seen:
                    seen.append(word)
    return CommentLines(tuple(spans), tuple(lines), tuple(seen), start)


class UncommentedStream(io.RawIOBase):
    """A file's bytes from its data's first line on, without its comment lines (a stream for pandas and pyarrow).

    Parameters
    ----------
    path : str or Path
    comments : CommentLines
        The lines to leave out and where the data starts.
    """

    def __init__(self, path: str | Path, comments: CommentLines) -> None:
        super().__init__()
        self._fh = Path(path).open("rb")
        self._pos = comments.data_start
        self._spans = comments.spans
        self._k = 0  # the next span at or after the position

    def readable(self) -> bool:  # noqa: D102 - io's protocol
        return True

    def readinto(self, buffer: bytearray | memoryview) -> int:  # type: ignore[override]  # noqa: D102
        while self._k < len(self._spans) and self._pos >= self._spans[self._k][0]:
            self._pos = max(self._pos, self._spans[self._k][1])  # over a comment line
            self._k += 1
        view = memoryview(buffer).cast("B")
        limit = len(view)
        if self._k < len(self._spans):
            limit = min(limit, self._spans[self._k][0] - self._pos)
        self._fh.seek(self._pos)
        got = self._fh.readinto(view[:limit]) or 0
        self._pos += got
        return got

    def close(self) -> None:  # noqa: D102
        self._fh.close()
        super().close()
