"""Delimited text: find the layout of a file from its first lines, then parse its numbers.

The layout (:class:`TextLayout`) is sniffed from the first :data:`SNIFF_LINES` lines: the
delimiter (comma, semicolon, tab, ``|`` or whitespace), a decimal comma, the header row
(or none; a comment line just above the data with one name per column, ``# time ax ay az``
or ``% t ax ay az``, is offered as the header: :attr:`TextLayout.comment_names`), and the
metadata lines above it (``Fs,100``, ``# comments``).  The numbers are
then parsed in one place, :func:`parse_numbers`: numpy's C reader for small files (it
needs no pandas import, which costs more than reading a file of 10⁵ rows), pyarrow for
large files of plain numbers (multithreaded up to 1 GiB, streamed above), pandas' C
parser in chunks for the others, for decimal commas and for files with non-numeric
cells (which are counted, not fatal).  :func:`iter_number_chunks` streams a file of any
size chunk by chunk.
"""

from __future__ import annotations

import io
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.data.comment_lines import COMMENT_MARKS, CommentLines, UncommentedStream, find_comment_lines
from optcal.data.column_block import (  # re-exported: the reader's block and pyarrow's numbers
    ColumnBlock,
    arrow_numbers,
    base_pages,
    release_unused,
)

#: Lines read to find the layout.
SNIFF_LINES: int = 64
#: Files up to this size are parsed by numpy (no pandas import); larger ones by pandas.
SMALL_FILE_BYTES: int = 16 * 2**20
#: Rows per chunk when streaming with pandas (its tokenizer holds a chunk's text, fields and frame at once).
CHUNK_ROWS: int = 2**18
#: Delimiters tried, in order of preference when several fit.
DELIMITERS: tuple[str, ...] = ("\t", ";", "|", ",", " ")
_NAMES = {"\t": "tab", ";": "semicolon", "|": "'|'", ",": "comma", " ": "whitespace"}
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^[+-]?(nan|inf|infinity)$", re.IGNORECASE)
_COMMA_NUMBER = re.compile(r"^[+-]?\d+,\d+([eE][+-]?\d+)?$")


@dataclass(frozen=True)
class TextLayout:
    """How a delimited text file is laid out.

    Attributes
    ----------
    delimiter : str
        ``","``, ``";"``, ``"\\t"``, ``"|"``, or ``" "`` for any run of whitespace.
    decimal_comma : bool
        Numbers are written with a decimal comma (``9,81``).
    header_line : int or None
        0-based line of the header row; ``None`` when the file has no header.
    first_data_line : int
        0-based line of the first data row.
    names : list of str
        The header's column names, or ``"1"``, ``"2"``, ... (1-based positions) without one.
    metadata : dict of str to str
        ``key,value`` lines and comments above the header.
    comment_names : list of str or None
        The words of the comment line just above the data rows (``# time tx ty tz ...``) when the
        file has no header row and that line has one word per column, none of them a number: the
        columns' names if the reader takes them so (:meth:`with_comment_header`).
    comment_line : int or None
        0-based line of that comment.
    ignored_header : int or None
        0-based line of a row of names whose count differs from the data rows', read as a note
        because the caller names the columns by position (:func:`sniff_layout`'s ``by_position``).
    """

    delimiter: str
    decimal_comma: bool
    header_line: int | None
    first_data_line: int
    names: list[str]
    metadata: dict[str, str] = field(default_factory=dict)
    comment_names: list[str] | None = None
    comment_line: int | None = None
    ignored_header: int | None = None

    @property
    def has_header(self) -> bool:
        return self.header_line is not None

    @property
    def header_in_comment(self) -> bool:
        """The header is a comment line (:meth:`with_comment_header`)."""
        return self.header_line is not None and self.header_line == self.comment_line

    def with_comment_header(self) -> TextLayout:
        """This layout with :attr:`comment_names` as the header (and that comment no longer a metadata line)."""
        if self.comment_names is None or self.comment_line is None:
            raise ValueError("no comment line names the columns")
        key = next(iter(_metadata([" ".join(self.comment_names)])), None)
        metadata = {k: v for k, v in self.metadata.items() if k != key}
        return replace(self, header_line=self.comment_line, names=list(self.comment_names), metadata=metadata)

    def describe(self) -> str:
        """``comma-separated, header on line 5`` / ``whitespace-separated, no header``."""
        what = f"{_NAMES[self.delimiter]}-separated"
        if self.decimal_comma:
            what += " with decimal commas"
        if self.header_in_comment and self.header_line is not None:
            head = f"header in the comment on line {self.header_line + 1}"
        else:
            head = f"header on line {self.header_line + 1}" if self.header_line is not None else "no header"
        if self.ignored_header is not None:
            head += f" (line {self.ignored_header + 1}'s names do not match the fields: read as a note)"
        return f"{what}, {head}, {len(self.names)} columns"


def _is_number(s: str, decimal_comma: bool) -> bool:
    s = s.strip()
    if _NUMBER.match(s):
        return True
    return decimal_comma and bool(_COMMA_NUMBER.match(s))


def _numbers(row: list[str], decimal_comma: bool) -> int:
    return sum(1 for f in row if f and _is_number(f, decimal_comma))


def _split(line: str, delimiter: str) -> list[str]:
    return line.split() if delimiter == " " else [f.strip() for f in line.split(delimiter)]


def read_head(path: Path) -> list[str]:
    """The first :data:`SNIFF_LINES` lines of a text file (refusing binary files)."""
    try:
        with path.open("rb") as fh:
            raw = [fh.readline() for _ in range(SNIFF_LINES)]
    except IsADirectoryError as exc:  # pragma: no cover - detect_file_type catches directories
        raise InputError(f"{path}: is a directory; give a data file") from exc
    blob = b"".join(raw)
    if b"\x00" in blob:
        raise InputError(f"{path}: not a text file (and not a recognised binary format: ULog, ROS bag, Parquet)")
    try:
        text = blob.decode("utf-8-sig")
    except UnicodeDecodeError:
        try:
            text = blob.decode("latin-1")
        except UnicodeDecodeError as exc:  # pragma: no cover - latin-1 decodes every byte
            raise InputError(f"{path}: not a text file") from exc
        if sum(not (c.isprintable() or c.isspace()) for c in text) > 0.05 * max(1, len(text)):
            raise InputError(f"{path}: not a text file (and not a recognised binary format: ULog, ROS bag, Parquet)")
    return [ln.rstrip("\r\n") for ln in text.splitlines()]


def sniff_layout(path: str | Path, by_position: bool = False) -> TextLayout:
    """Find the delimiter, decimal mark, header row and metadata of a delimited text file.

    The data rows are the longest run of lines at the end of the sniffed head whose fields
    are all numbers (empty cells allowed) with one field count; the line just above them is
    the header when all its fields are names and it has as many fields.

    Parameters
    ----------
    path : str or Path
    by_position : bool
        The caller names the columns by position (``--columns t=1,ax=2,...``): a line of names
        whose count differs from the data rows' is then kept as a metadata line
        (:attr:`TextLayout.ignored_header`) and the file read without a header, instead of refused.

    Raises
    ------
    InputError
        Empty file, binary file, a header whose field count differs from the data rows' (unless
        ``by_position``), or no delimiter giving at least one column.
    """
    p = Path(path)
    lines = read_head(p)
    content = [(i, ln.strip()) for i, ln in enumerate(lines) if ln.strip() and not ln.strip().startswith(COMMENT_MARKS)]
    if not content:
        raise InputError(f"{p}: the file is empty; expected data rows (with or without a header row)")
    best: tuple[int, int, TextLayout] | None = None
    mismatch: str | None = None
    for rank, delim in enumerate(DELIMITERS):
        layout, why = _layout_for(p, lines, content, delim, by_position)
        if layout is None:
            if why and mismatch is None:
                mismatch = why
            continue
        n_data = sum(1 for i, _ in content if i >= layout.first_data_line)
        score = (n_data * (len(layout.names) >= 2), -rank)
        if best is None or score > best[:2]:
            best = (score[0], score[1], layout)
    if best is None or best[0] == 0:
        if mismatch:
            raise InputError(f"{p}: {mismatch}")
        if best is not None:
            return best[2]
        if (wrapped := _bracketed_rows(p, lines, content)) is not None:
            raise InputError(f"{p}: no data rows found: {wrapped}")
        raise InputError(
            f"{p}: no data rows found (expected rows of numbers, comma-, semicolon-, tab-, '|'- or "
            "whitespace-separated, optionally below a header row such as t,ax,ay,az)"
        )
    return best[2]


#: The brackets a program's printed tuples and lists wrap numbers in (MicroPython's ``print((acc, mag))`` writes
#: ``((ax, ay, az), (mx, my, mz))``).  The parsers read delimited numbers straight from the file (numpy's, pyarrow's
#: and pandas' C readers), so such rows are not rewritten on the way: they are named, with the conversion.
_BRACKETS = "()[]{}"


def _bracketed_rows(p: Path, lines: list[str], content: list[tuple[int, str]]) -> str | None:
    """What the rows look like and how to convert them, when they are delimited numbers once their brackets are
    removed (a program's printed tuples or lists), else ``None``."""
    table = str.maketrans("", "", _BRACKETS)
    wrapped = [(i, s) for i, s in content if any(c in s for c in _BRACKETS)]
    if not wrapped or 2 * len(wrapped) < len(content):  # most rows wrapped: else brackets are not the layout
        return None
    bare = [(i, s.translate(table).strip()) for i, s in content]
    bare_lines = [ln.translate(table) for ln in lines]
    for delim in DELIMITERS:
        layout, _ = _layout_for(p, bare_lines, bare, delim)
        if layout is not None and len(layout.names) >= 2:
            line, text = wrapped[0]
            return (f"the rows are numbers wrapped in brackets (line {line + 1}: {text[:80]}: a program's printed "
                    f"tuples or lists, as MicroPython's print((acc, mag)) writes them), and optcal reads delimited "
                    f"numbers; remove the brackets first (e.g. tr -d '{_BRACKETS}' < {p.name} > plain.csv), which "
                    f"leaves {len(layout.names)} {_NAMES[delim]}-separated columns to name with --columns")
    return None


def _layout_for(
    p: Path, lines: list[str], content: list[tuple[int, str]], delim: str, by_position: bool = False
) -> tuple[TextLayout | None, str | None]:
    fields = [_split(s, delim) for _, s in content]
    decimal_comma = delim != "," and any(_COMMA_NUMBER.match(f) for row in fields for f in row)
    # a data row: more numbers than other fields (a text label column may sit among them)
    numeric = [_numbers(row, decimal_comma) > sum(1 for f in row if f) - _numbers(row, decimal_comma) for row in fields]
    # the data block: the run of numeric rows ending at the last sniffed row (a truncated
    # last row, shorter than the others, still counts)
    end = len(content)
    k = end
    while k > 0 and numeric[k - 1]:
        k -= 1
    if k == end:
        return None, None
    counts = [len(fields[j]) for j in range(k, end)]
    width = max(set(counts), key=counts.count)
    # extend upwards only through rows of the data width
    while k < end and len(fields[k]) != width:
        k += 1
    if width < 1 or k == end:
        return None, None
    first_data = content[k][0]
    header_line = None
    ignored_header = None
    names = [str(j + 1) for j in range(width)]
    if k > 0:
        above = _without_empty_tail(fields[k - 1])
        # a delimiter written after the header's last name (``t,ax,ay,az,``, as after every data row's last
        # value) names no column: the names are those before it, and the data rows' fields beyond them must be
        # empty in every sniffed row (a column of no numbers), else the header does not match the rows
        empty_beyond = len(above) < width and all(
            not f for row in fields[k:end] for f in row[len(above):] if len(row) == width)
        if len(above) >= 2 and all(f and not _is_number(f, decimal_comma) for f in above):
            if len(above) == width or empty_beyond:
                header_line = content[k - 1][0]
                names = [f.strip().strip('"').strip("'") for f in above]
                names += [str(j + 1) for j in range(len(names), width)]
            elif len(above) >= 3 and by_position:
                # a header that lost a delimiter (``time (s)x (g),y (g),z (g)`` over 4 fields): the
                # caller names the columns by position, so the line is only read as a note
                ignored_header = content[k - 1][0]
            elif len(above) >= 3:
                example = ",".join(f"{c}={j + 1}" for j, c in enumerate(("t", "ax", "ay", "az")[:width]))
                return None, (
                    f"line {content[k - 1][0] + 1} looks like the header ({len(above)} columns: {', '.join(above)}) "
                    f"but line {first_data + 1} has {width} fields; every data row needs one value per column, "
                    f"or name the fields by 1-based position with --columns (e.g. --columns {example}: the line "
                    "is then read as a note)"
                )
    meta_end = header_line if header_line is not None else first_data
    comment_names, comment_line = None, None
    if header_line is None:
        comment_names, comment_line = _comment_names(lines, first_data, delim, decimal_comma, width)
    return TextLayout(
        delim, decimal_comma, header_line, first_data, names, _metadata(lines[:meta_end]), comment_names, comment_line,
        ignored_header,
    ), None


def _without_empty_tail(row: list[str]) -> list[str]:
    """``row`` without its empty last fields (a delimiter after the last value or name); at least one field kept."""
    n = len(row)
    while n > 1 and not row[n - 1]:
        n -= 1
    return row[:n]


def _comment_names(
    lines: list[str], first_data: int, delim: str, decimal_comma: bool, width: int
) -> tuple[list[str] | None, int | None]:
    """The words of the comment line just above the data (blank lines between allowed) when they
    are one name per column (at least two, none a number), and that line."""
    i = first_data - 1
    while i >= 0 and not lines[i].strip():
        i -= 1
    if i < 0 or not lines[i].strip().startswith(COMMENT_MARKS):
        return None, None
    text = lines[i].strip().lstrip("".join(COMMENT_MARKS)).strip()
    words = [w.strip().strip('"').strip("'") for w in _split(text, delim)]
    if width >= 2 and len(words) == width and all(w and not _is_number(w, decimal_comma) for w in words):
        return words, i
    return None, None


def _metadata(lines: list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for line in lines:
        s = line.strip().lstrip("".join(COMMENT_MARKS)).strip()
        if not s:
            continue
        m = re.match(r"^([^,;:=\t|]+)[,;:=\t|]\s*(.*)$", s)
        if m:
            out[m.group(1).strip()] = m.group(2).strip().rstrip(",;")
        else:
            out[s] = ""
    return out


def read_numbers(path: str | Path, by_position: bool = False) -> tuple[TextLayout, ParsedNumbers]:
    """The layout of a delimited text file and its numbers (:func:`sniff_layout`, then :func:`parse_numbers`).

    ``by_position``: the caller names the columns by position (see :func:`sniff_layout`).

    Raises
    ------
    InputError
        No layout found, or no data rows.
    """
    layout = sniff_layout(path, by_position)
    parsed = parse_numbers(path, layout)
    if parsed.n_rows == 0:
        raise InputError(f"{path}: no data rows after the header")
    return layout, parsed


@dataclass
class ParsedNumbers:
    """The numbers of a delimited file, one float column per field.

    Attributes
    ----------
    columns : list of ndarray
        One float array per field (NaN where a cell is empty, missing or not a number).
    non_numeric : dict of int to tuple
        Field index → (number of non-numeric cells, first data row (1-based), first value).
    engine : str
        ``"numpy"``, ``"pyarrow"`` or ``"pandas"``: which parser read the file.
    comments : CommentLines or None
        The comment lines among the data rows, skipped (``None``: the file was not scanned, its fast parse found
        none).
    """

    columns: list[NDArray[np.float64]]
    non_numeric: dict[int, tuple[int, int, str]]
    engine: str
    comments: CommentLines | None = None

    @property
    def comments_note(self) -> str:
        """``"; N comment line(s) among the data skipped (...)"`` for the layout's description, or ``""``."""
        return f"; {self.comments.describe()}" if self.comments is not None and self.comments.count else ""

    @property
    def n_rows(self) -> int:
        return int(self.columns[0].size) if self.columns else 0


def parse_numbers(path: str | Path, layout: TextLayout, chunk_rows: int = CHUNK_ROWS) -> ParsedNumbers:
    """Parse every data row of a file laid out as ``layout``.

    Small files with plain numbers are read by numpy.  Larger files are read into one
    column-major float block (:class:`ColumnBlock`; the columns returned are its contiguous
    columns, so the file's numbers are held once): by pyarrow when it is installed and the file
    is plain numbers with a one-character delimiter (byte ranges parsed at once, :func:`arrow_ranged_block`, up to
    :data:`THREADED_READ_BYTES`, its streaming reader above), otherwise, and for decimal commas and any file with a non-numeric or missing cell, by
    pandas (in chunks of ``chunk_rows``), which turns such cells into NaN and counts them per
    column.  Comment lines among the data (:mod:`optcal.data.comment_lines`) make the fast parsers fail; the file
    is then scanned for them once, and pyarrow (large files) or pandas reads it without them, counted in
    :attr:`ParsedNumbers.comments`.
    """
    p = Path(path)
    size = p.stat().st_size
    if size <= SMALL_FILE_BYTES and not layout.decimal_comma:
        try:
            data = _numpy_read(p, layout)
            return ParsedNumbers([np.ascontiguousarray(data[:, j]) for j in range(data.shape[1])], {}, "numpy")
        except ValueError:
            pass  # a ragged, empty or non-numeric cell, or a comment line: pandas reads it cell by cell
    if size > SMALL_FILE_BYTES:
        block = _arrow_block(p, layout)
        if block is not None:
            return ParsedNumbers(block.columns(), {}, "pyarrow")
    # only a file the fast parsers refused is scanned (a file of plain numbers is read in one pass)
    comments = find_comment_lines(p, layout.first_data_line, layout.delimiter)
    if comments.count and size > SMALL_FILE_BYTES:
        block = arrow_streamed_block(p, layout, comments)
        if block is not None:
            return ParsedNumbers(block.columns(), {}, "pyarrow", comments)
    rows = estimated_rows(p, layout)
    block = ColumnBlock(len(layout.names), rows)
    non_numeric: dict[int, tuple[int, int, str]] = {}
    from optcal.core.progress import progress

    # a bar (rows read) when the command line asked for one and the read outlasts a second: large files
    for cols, bad in progress(_pandas_chunks(p, layout, chunk_rows, comments), total=rows, desc=f"reading {p.name}", unit="rows",
                              scale=True, size=lambda item: item[0][0].size if item[0] else 0):
        for j, (count, row, value) in bad.items():
            old = non_numeric.get(j)
            non_numeric[j] = (count + (old[0] if old else 0), old[1] if old else row + block.n, old[2] if old else value)
        block.append(cols)
    if block.n == 0:
        raise InputError(f"{p}: no data rows after the header")
    return ParsedNumbers(block.columns(), non_numeric, "pandas", comments)


def estimated_rows(p: Path, layout: TextLayout) -> int:
    """Rows of a file from its size and the mean length of the data lines in its head (plus 10 %)."""
    lines = [ln for ln in read_head(p)[layout.first_data_line:] if ln.strip()]
    per_row = max(1.0, sum(len(ln) + 1 for ln in lines) / max(1, len(lines)))
    return int(p.stat().st_size / per_row * 1.1) + 1024


#: Bytes of text per block of pyarrow's streaming reader (each range of :func:`arrow_ranged_block`, and files over
#: :data:`THREADED_READ_BYTES`): it keeps blocks of text and their parsed batches in flight beside the numbers
#: already copied out, 78 MB at 1 MiB blocks and 22 MB at 256 KiB on the 12-hour, 300 MB still log (a third and a
#: tenth of a copy of its numbers), at the same speed.
ARROW_STREAM_BLOCK_BYTES: int = 2**18
#: Text files up to this size are parsed on every core at once (≈ 1.7× faster on two cores than one
#: streaming reader: 0.37 s against 0.63 s of wall time for the 85 MB, 10⁶-row CSV; 1.3 s against 2.4 s for
#: the 300 MB 12-hour still log), by byte ranges (:func:`arrow_ranged_block`; pyarrow's multithreaded
#: ``read_csv`` gives the same numbers but holds the whole parsed table, ≈ 1.25 copies, and copies it out after
#: the parse); larger ones by one streaming reader, one block at a time, whose
#: bar counts the rows.  Above this size a parse takes over about 5 s of two cores, where a bar with the rows
#: read and the time left is worth the streaming reader's slower parse (the ranges show their elapsed time only).
THREADED_READ_BYTES: int = 2**30


def _arrow_options(p: Path, layout: TextLayout, skip_rows: int | None = None) -> dict[str, Any] | None:
    """pyarrow's CSV options for a file of plain numbers laid out as ``layout``, or ``None`` when pyarrow cannot read it.

    ``None`` when pyarrow is not installed or numbers have decimal commas (whitespace runs and
    other cells pyarrow cannot read are found while reading).  ``skip_rows``: the lines before the numbers (the
    layout's header and the lines above it by default; 0 for a byte range that starts on a line of data).
    """
    if layout.decimal_comma:
        return None
    try:
        import pyarrow as pa
        import pyarrow.csv as pacsv
    except ImportError:
        return None
    names = [f"c{j}" for j in range(len(layout.names))]
    return {
        "read_options": pacsv.ReadOptions(
            column_names=names, skip_rows=layout.first_data_line if skip_rows is None else skip_rows,
            block_size=ARROW_STREAM_BLOCK_BYTES,
            encoding="utf8", use_threads=False,
        ),
        "parse_options": pacsv.ParseOptions(delimiter=layout.delimiter, quote_char=False),
        "convert_options": pacsv.ConvertOptions(column_types={n: pa.float64() for n in names}),
        # the system allocator: each batch's memory returns to the heap numpy allocates from,
        # instead of staying cached in pyarrow's own pool
        "memory_pool": pa.system_memory_pool(),
    }


def _arrow_block(p: Path, layout: TextLayout) -> ColumnBlock | None:
    """The file's numbers read by pyarrow into a :class:`ColumnBlock`, or ``None`` to leave it to pandas.

    Files up to :data:`THREADED_READ_BYTES` are read by byte ranges at once (:func:`arrow_ranged_block`), larger ones
    streamed (:func:`arrow_streamed_block`); both parse the same text into the same numbers.
    ``None`` when pyarrow is not installed, numbers have decimal commas, or any cell is not a
    plain number (a comment, text, a ragged row; with whitespace, an empty field from a run
    of blanks): pandas then reads the file and counts such cells.
    """
    if p.stat().st_size <= THREADED_READ_BYTES:
        return arrow_ranged_block(p, layout)
    return arrow_streamed_block(p, layout)


def text_ranges(p: Path, layout: TextLayout, parts: int) -> list[tuple[int, int]]:
    """Byte ranges ``(start, end)`` of ``p`` for ``parts`` readers: each but the first starts a line of data.

    The ranges share the file's bytes evenly (the first holds the lines before the data, the header), each
    boundary moved forward to the next newline.
    A file with no newline past a boundary (lone carriage returns) keeps fewer ranges, down to one.
    """
    size = p.stat().st_size
    with p.open("rb") as fh:
        for _ in range(layout.first_data_line):
            fh.readline()
        data_start = fh.tell()
        edges, start = [], 0
        for k in range(1, parts):
            fh.seek(max(data_start, start, size * k // parts))
            fh.readline()  # to the end of the line the nominal boundary falls in
            edge = fh.tell()
            if edge >= size:
                break
            if edge > start:
                edges.append((start, edge))
                start = edge
    return [*edges, (start, size)]


def arrow_ranged_block(p: Path, layout: TextLayout, parts: int | None = None) -> ColumnBlock | None:
    """The file's numbers by pyarrow's streaming reader on byte ranges of the file at once, or ``None`` (see
    :func:`_arrow_block`).

    The file is cut at line starts into one range per core (:func:`text_ranges`; ``parts``: how many ranges at
    most, pyarrow's CPU count by default).  Each range is streamed by its own thread (pyarrow parses outside the
    interpreter's lock, the calling thread takes the first range), which copies its batches into its own region
    of one :class:`ColumnBlock` as they come: a region starts at the range's estimated first row (its bytes over
    the head's bytes per row, the block's own estimate, 10 % above the rows of a file like its head).  Once all
    are read, each range's rows are moved down to follow the previous range's (a move within the block, each
    column's pages left behind handed back), so the numbers are held once, in the file's order.  A range with
    more rows than its region (lines much shorter than the head's) keeps the rest aside; the ranges are then
    joined in a new block.  The same numbers as pyarrow's multithreaded ``read_csv``, without its whole parsed
    table held (up to 1.25 copies of the numbers) and copied out once complete (0.24 CPU s and 0.2-0.4 s of wall
    on the 12-hour still log's serial path).
    """
    options = _arrow_options(p, layout)
    later = _arrow_options(p, layout, skip_rows=0)  # a later range starts on a line of data
    if options is None or later is None:
        return None
    import threading

    import pyarrow as pa
    import pyarrow.csv as pacsv

    width = len(layout.names)
    ranges = text_ranges(p, layout, max(1, parts if parts is not None else pa.cpu_count()))
    size = p.stat().st_size
    total = estimated_rows(p, layout)
    # each range's region: rows from its estimated first row to the next range's
    starts = [total * a // max(1, size) for a, _ in ranges] + [total]
    block = ColumnBlock(width, total)
    filled = [0] * len(ranges)  # rows written in each region
    aside: list[list[list[NDArray[np.float64]]]] = [[] for _ in ranges]  # batches beyond a region
    failed: list[BaseException | None] = [None] * len(ranges)
    stop = threading.Event()
    pool = options["memory_pool"]
    default = pa.default_memory_pool()

    def read(k: int) -> None:
        a, b = ranges[k]
        opts = later if k else options
        try:
            with pa.OSFile(str(p)) as fh, pacsv.open_csv(fh.get_stream(a, b - a), **opts) as reader:
                for batch in reader:
                    if stop.is_set():
                        return
                    if layout.delimiter == " " and any(batch.column(j).null_count for j in range(width)):
                        raise pa.ArrowInvalid("a run of blanks")  # fields are not single-blank separated
                    cols = [arrow_numbers(batch.column(j)) for j in range(width)]
                    n, row = len(batch), starts[k] + filled[k]
                    if aside[k] or row + n > starts[k + 1]:
                        aside[k].append([c.copy() for c in cols])
                        continue
                    for j, col in enumerate(cols):
                        block.block[row:row + n, j] = col
                    filled[k] += n
        except BaseException as exc:  # the calling thread decides
            failed[k] = exc
            stop.set()

    threads = [threading.Thread(target=read, args=(k,), name=f"optcal-read{k}", daemon=True)
               for k in range(1, len(ranges))]
    # the readers' batches and their own buffers (blocks of text) in the system allocator, whose freed pages
    # release_unused hands back at once: pyarrow's default pool (mimalloc) kept what its worker threads freed
    # until they ran again (18-27 MiB after reading the 49 MB, 2-hour still log: 0.5-0.7 of a copy of its numbers)
    pa.set_memory_pool(pool)
    try:
        from optcal.core.progress import stage

        with stage(f"reading {p.name}"):  # its elapsed time on a terminal when it takes long
            for th in threads:
                th.start()
            read(0)
            for th in threads:
                th.join()
    finally:
        pa.set_memory_pool(default)
        release_unused(pool)
    for exc in failed:
        if isinstance(exc, (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError)):
            return None
        if exc is not None:
            raise exc
    if any(aside):  # a region overflowed: the ranges joined in a new block
        joined = ColumnBlock(width, sum(filled) + sum(len(b[0]) for side in aside for b in side))
        for k in range(len(ranges)):
            joined.append([block.block[starts[k]:starts[k] + filled[k], j] for j in range(width)])
            for cols in aside[k]:
                joined.append(cols)
        return joined if joined.n else None
    n = filled[0]
    for k in range(1, len(ranges)):  # each range's rows moved down after the previous range's
        if filled[k] and starts[k] > n:
            for j in range(width):
                block.block[n:n + filled[k], j] = block.block[starts[k]:starts[k] + filled[k], j]
            block.release_rows(n + filled[k], starts[k] + filled[k])
        n += filled[k]
    block.n = n
    return block if n else None


def arrow_streamed_block(p: Path, layout: TextLayout, comments: CommentLines | None = None) -> ColumnBlock | None:
    """The file's numbers by pyarrow's streaming reader, one block of text at a time, or ``None`` (see :func:`_arrow_block`).

    ``comments``: comment lines among the data, left out (the file is read through :class:`UncommentedStream`).
    """
    skip_comments = comments is not None and comments.count > 0
    options = _arrow_options(p, layout, skip_rows=0 if skip_comments else None)
    if options is None:
        return None
    import pyarrow as pa
    import pyarrow.csv as pacsv

    width = len(layout.names)
    blank_delimited = layout.delimiter == " "
    try:
        source: Any = UncommentedStream(p, comments) if comments is not None and skip_comments else p
        reader = pacsv.open_csv(source, **options)
        rows = estimated_rows(p, layout)
        block = ColumnBlock(width, rows)
        from optcal.core.progress import progress

        with reader:  # a bar (rows read) when the command line asked for one: only files streamed, > 1 GiB
            for batch in progress(reader, total=rows, desc=f"reading {p.name}", unit="rows", scale=True,
                                  size=lambda b: b.num_rows):
                if blank_delimited and any(batch.column(j).null_count for j in range(width)):
                    return None  # a run of blanks: fields are not single-blank separated
                block.append([arrow_numbers(batch.column(j)) for j in range(width)])
    except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError):
        return None
    return block if block.n else None


def iter_number_chunks(path: str | Path, layout: TextLayout, chunk_rows: int = CHUNK_ROWS) -> Iterator[list[NDArray[np.float64]]]:
    """Stream a file's data rows as lists of float columns, ``chunk_rows`` rows at a time."""
    for cols, _ in _pandas_chunks(Path(path), layout, chunk_rows):
        yield cols


def read_frame(path: str | Path) -> tuple[Any, dict[str, str]]:
    """The whole file as a pandas frame (its own dtypes: text columns stay text) and its metadata lines."""
    import pandas as pd

    p = Path(path)
    layout = sniff_layout(p)
    try:
        frame = pd.read_csv(
            p, sep=r"\s+" if layout.delimiter == " " else layout.delimiter, header=None, names=layout.names,
            skiprows=layout.first_data_line, decimal="," if layout.decimal_comma else ".", comment="#",
            skipinitialspace=True, encoding="utf-8-sig", encoding_errors="replace", skip_blank_lines=True,
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise InputError(f"{p}: not a readable {_NAMES[layout.delimiter]}-separated file ({str(exc).splitlines()[0]})") from exc
    if len(frame) == 0:
        raise InputError(f"{p}: no data rows after the header")
    return frame, layout.metadata


def _numpy_read(p: Path, layout: TextLayout) -> NDArray[np.float64]:
    data = np.loadtxt(
        p,
        delimiter=None if layout.delimiter == " " else layout.delimiter,
        skiprows=layout.first_data_line,
        comments=None,  # a comment line fails: it is counted on the other paths (parse_numbers)
        ndmin=2,
        encoding="utf-8-sig",
    )
    if data.shape[1] != len(layout.names) or data.shape[0] == 0:
        raise ValueError("column count differs")
    return data


def _pandas_chunks(
    p: Path, layout: TextLayout, chunk_rows: int, comments: CommentLines | None = None
) -> Iterator[tuple[list[NDArray[np.float64]], dict[int, tuple[int, int, str]]]]:
    import pandas as pd

    width = len(layout.names)
    skip = comments is not None and comments.count > 0  # read without the comment lines, from the data's first line
    try:
        reader = pd.read_csv(
            io.BufferedReader(UncommentedStream(p, comments)) if comments is not None and skip else p,
            sep=r"\s+" if layout.delimiter == " " else layout.delimiter,
            header=None,
            names=list(range(width)),
            skiprows=0 if skip else layout.first_data_line,
            decimal="," if layout.decimal_comma else ".",
            comment="#",  # a note after a row's numbers (whole comment lines are left out above)
            skipinitialspace=True,
            encoding="utf-8-sig",
            encoding_errors="replace",
            chunksize=chunk_rows,
            on_bad_lines="error",
            skip_blank_lines=True,
        )
        with reader:
            offset = 0
            while True:
                # low_memory parsing (≈ 20 % faster); a column of mixed numbers and text comes as
                # objects and is coerced cell by cell below, so pandas' mixed-type warning says nothing new
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", pd.errors.DtypeWarning)
                    chunk = next(reader, None)
                if chunk is None:
                    break
                cols: list[NDArray[np.float64]] = []
                bad: dict[int, tuple[int, int, str]] = {}
                for j in range(width):
                    raw = chunk[j]
                    if pd.api.types.is_numeric_dtype(raw):
                        cols.append(raw.to_numpy(dtype=float))
                        continue
                    values = pd.to_numeric(raw, errors="coerce")
                    idx = np.flatnonzero(values.isna().to_numpy() & raw.notna().to_numpy())
                    if idx.size:
                        bad[j] = (int(idx.size), offset + int(idx[0]) + 1, str(raw.iloc[idx[0]]))
                    cols.append(values.to_numpy(dtype=float))
                offset += len(chunk)
                yield cols, bad
    except pd.errors.EmptyDataError as exc:
        raise InputError(f"{p}: no data rows after the header") from exc
    except pd.errors.ParserError as exc:
        raise InputError(
            f"{p}: not a readable {_NAMES[layout.delimiter]}-separated file ({str(exc).splitlines()[0]}); "
            "every data row needs one value per column"
        ) from exc
