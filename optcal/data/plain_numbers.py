"""A fast, exact reader for delimited text that holds only plain decimal numbers.

Most raw recordings are tables of plain numbers (``0.029840,33108,33329,...``): digits, at
most one decimal point, an optional leading sign.  :func:`parse_plain_numbers` parses such
text with a handful of vectorised numpy passes over its bytes, about three times faster
than ``numpy.loadtxt`` (whose per-character parser is most of the time of reading a
recording of 10⁵ rows), and gives bit for bit the numbers ``numpy.loadtxt`` gives.

Exactness: a field of at most :data:`MAX_DIGITS` (15) significant digits is the integer of
its digits, ``m < 10¹⁵ < 2⁵³``, divided by ``10^d`` (``d`` decimals, ``10^d`` exact for
``d ≤ 22``).  Both operands are exact doubles, so the one IEEE division is the correctly
rounded value of the decimal (Clinger's fast path), which is what a correctly rounding
parser (``loadtxt``'s, ``float()``) returns.

Anything else (an exponent, ``nan``, a comment, a missing or extra field, a line of blanks,
more digits, a bare carriage return, other bytes) makes the function return ``None`` and the
caller reads the file the general way; nothing is guessed here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

#: Significant digits a field may have for the exact fast path (10¹⁵ < 2⁵³).
MAX_DIGITS: int = 15
#: Characters a field may have: the digits, a sign and a decimal point.
MAX_FIELD_WIDTH: int = MAX_DIGITS + 2
#: Exact powers of ten (each an exactly representable double).
_POW10: NDArray[np.float64] = np.array([float(10**k) for k in range(MAX_FIELD_WIDTH + 1)])
_NL, _CR, _SPACE, _TAB, _DOT, _MINUS, _PLUS, _ZERO = 10, 13, 32, 9, 46, 45, 43, 48


def read_plain_numbers(path: str | Path, delimiter: str, skip_lines: int, n_columns: int) -> NDArray[np.float64] | None:
    """The numbers of a delimited file below its first ``skip_lines`` lines, or ``None``.

    Parameters
    ----------
    path : str or Path
        The file (UTF-8, an optional byte-order mark).
    delimiter : str
        One character, or ``" "`` for any run of blanks (spaces, tabs).
    skip_lines : int
        Lines above the data (header, metadata), skipped as they are.
    n_columns : int
        Fields per row.

    Returns
    -------
    ndarray of shape (rows, n_columns), or None
        ``None`` unless every data line holds exactly ``n_columns`` plain decimal numbers.
    """
    raw = Path(path).read_bytes()
    start = 3 if raw.startswith(b"\xef\xbb\xbf") else 0
    for _ in range(skip_lines):
        end = raw.find(b"\n", start)
        if end < 0:
            return None
        start = end + 1
    if b"\r" in raw[:start].replace(b"\r\n", b""):
        return None  # a line break by carriage return alone: let the general reader count lines
    return parse_plain_numbers(raw[start:], delimiter, n_columns)


def parse_plain_numbers(text: bytes, delimiter: str, n_columns: int) -> NDArray[np.float64] | None:
    """Parse ``text``, rows of ``n_columns`` plain decimal numbers, into a (rows, n_columns) array, or ``None``.

    Parameters
    ----------
    text : bytes
        The data lines (``\\n`` or ``\\r\\n`` line ends; empty lines are skipped).
    delimiter : str
        One ASCII character, or ``" "`` for any run of blanks.
    n_columns : int
        Fields per row (at least 1).

    Returns
    -------
    ndarray or None
        The numbers, or ``None`` when ``text`` is anything else (see the module docstring).
    """
    if n_columns < 1 or len(delimiter) != 1 or ord(delimiter) > 127 or not text.strip():
        return None
    u = np.frombuffer(text + b"\n" * (MAX_FIELD_WIDTH + 1), np.uint8)  # a field never reads past the end
    blank_delimited = delimiter == " "
    newline = u == _NL
    cr = np.flatnonzero(u == _CR)
    if cr.size and not newline[cr + 1].all():
        return None
    digit = (u - np.uint8(_ZERO)) < 10
    dot = u == _DOT
    sign = (u == _MINUS) | (u == _PLUS)
    space = (u == _SPACE) | (u == _TAB) if blank_delimited else u == _SPACE
    separator = newline | space
    separator[cr] = True
    if not blank_delimited:
        is_delimiter = u == ord(delimiter)
        separator |= is_delimiter
    if not (digit | dot | sign | separator).all():
        return None
    in_field = ~separator
    starts = np.flatnonzero(in_field[1:] & separator[:-1]) + 1
    if in_field[0]:
        starts = np.concatenate(([0], starts))
    ends = np.flatnonzero(separator[1:] & in_field[:-1]) + 1
    n = starts.size
    if n == 0 or n % n_columns or ends.size != n:
        return None
    width = ends - starts
    if width.max() > MAX_FIELD_WIDTH:
        return None
    signs = np.flatnonzero(sign)
    if signs.size and not separator[signs - 1].all():  # u[-1] is a newline: a sign at byte 0 passes
        return None
    dots = np.flatnonzero(dot)
    dot_field = np.searchsorted(starts, dots, "right") - 1
    if dots.size > 1 and not (dot_field[1:] > dot_field[:-1]).all():
        return None
    decimals = np.zeros(n, np.intp)
    decimals[dot_field] = ends[dot_field] - dots - 1
    n_digits = width - sign[starts]
    n_digits[dot_field] -= 1
    if n_digits.min() < 1 or n_digits.max() > MAX_DIGITS:
        return None
    if not _rows_are_regular(u, starts, ends, n_columns, newline, space, None if blank_delimited else is_delimiter):
        return None
    mantissa = _digits_as_integers(u, starts, width, n_columns)
    values = mantissa / _POW10[decimals]
    np.negative(values, out=values, where=u[starts] == _MINUS)
    return values.reshape(-1, n_columns)


def _rows_are_regular(
    u: NDArray[np.uint8],
    starts: NDArray[np.intp],
    ends: NDArray[np.intp],
    n_columns: int,
    newline: NDArray[np.bool_],
    space: NDArray[np.bool_],
    is_delimiter: NDArray[np.bool_] | None,
) -> bool:
    """Fields of a row apart by one delimiter (or blanks) on one line, rows apart by line ends, no line of blanks only."""
    row_break = np.zeros(starts.size - 1, bool)
    row_break[n_columns - 1::n_columns] = True
    gap_start, gap_end = ends[:-1], starts[1:]
    n_rows = starts.size // n_columns
    if (gap_end - gap_start == 1).all():  # one byte between fields (the common case)
        gap = u[gap_start]
        if not np.array_equal(gap == _NL, row_break):
            return False
    else:
        at_newline = np.flatnonzero(newline)
        crossing = np.searchsorted(at_newline, gap_end) - np.searchsorted(at_newline, gap_start)
        if not np.array_equal(crossing > 0, row_break):
            return False
    if is_delimiter is not None:
        at_delimiter = np.flatnonzero(is_delimiter)
        if at_delimiter.size != n_rows * (n_columns - 1):
            return False  # a leading, trailing or doubled delimiter (an empty field)
        between = np.searchsorted(at_delimiter, gap_end) - np.searchsorted(at_delimiter, gap_start)
        if not np.array_equal(between, (~row_break).astype(between.dtype)):
            return False
        at_space = np.flatnonzero(space)
        if at_space.size:  # loadtxt refuses a line of blanks when the delimiter is not a blank
            bounds = np.concatenate(([-1], np.flatnonzero(newline)))
            fields_per_line = np.diff(np.searchsorted(starts, bounds))
            spaces_per_line = np.diff(np.searchsorted(at_space, bounds))
            if (spaces_per_line[fields_per_line == 0] > 0).any():
                return False
    return True


def _digits_as_integers(u: NDArray[np.uint8], starts: NDArray[np.intp], width: NDArray[np.intp], n_columns: int) -> NDArray[np.float64]:
    """The integer of each field's digits (sign and point skipped), exact in float64 (≤ 15 digits).

    Horner's scheme over the character positions, one column at a time: the fields of a
    column have similar widths, so few positions are read beyond a field's end.
    """
    mantissa = np.empty(starts.size)
    for j in range(n_columns):
        at = starts[j::n_columns].copy()
        column_width = width[j::n_columns]
        value = np.zeros(at.size)
        char = np.empty(at.size, np.uint8)
        is_digit = np.empty(at.size, bool)
        narrowest = int(column_width.min())
        for k in range(int(column_width.max())):
            np.take(u, at, out=char)
            np.subtract(char, _ZERO, out=char)  # digits 0..9; a sign or point wraps above 9
            np.less(char, 10, out=is_digit)
            if k >= narrowest:
                is_digit &= k < column_width
            np.multiply(value, 10.0, out=value, where=is_digit)
            np.add(value, char, out=value, where=is_digit)
            at += 1
        mantissa[j::n_columns] = value
    return mantissa
