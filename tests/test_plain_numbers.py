"""The fast reader of plain decimal numbers gives bit for bit what ``numpy.loadtxt`` gives, or declines.

Every accepted text is compared with ``numpy.loadtxt`` of the same text (the bits of every
double, so ``-0.0`` and the last ulp count); texts it must decline (exponents, ``nan``, empty
fields, lines of blanks, more than 15 digits, a bare carriage return, comments) are listed.
"""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optcal.data.plain_numbers import MAX_DIGITS, parse_plain_numbers, read_plain_numbers
from optcal.data.text import parse_numbers, sniff_layout

PROFILE = settings(max_examples=150, deadline=None)


def loadtxt(text: bytes, delimiter: str, n_columns: int) -> np.ndarray | None:
    """``numpy.loadtxt`` of ``text`` as optcal calls it, or None when it fails or finds another width."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = np.loadtxt(io.StringIO(text.decode("utf-8")), delimiter=None if delimiter == " " else delimiter,
                              comments="#", ndmin=2)
    except (ValueError, UnicodeDecodeError):
        return None
    return data if data.shape[0] and data.shape[1] == n_columns else None


def same_bits(a: np.ndarray, b: np.ndarray | None) -> bool:
    return b is not None and a.shape == b.shape and bool((a.view(np.int64) == b.view(np.int64)).all())


@pytest.mark.parametrize("text, delimiter, expected", [
    (b"0.029840,33108,-33329\n0.039857,+33096,.5\n", ",", [[0.02984, 33108, -33329], [0.039857, 33096, 0.5]]),
    (b"1, 2\r\n3 ,4\r\n\r\n5,6", ",", [[1, 2], [3, 4], [5, 6]]),
    (b" 1\t2  \n-0 5.\n", " ", [[1, 2], [-0.0, 5]]),
    (b"1;2\n", ";", [[1, 2]]),
    (b"1\t 2\n", "\t", [[1, 2]]),
    (b"123456789012345|0.00000000000001\n", "|", [[123456789012345, 1e-14]]),
])
def test_plain_tables_are_read_exactly(text, delimiter, expected):
    data = parse_plain_numbers(text, delimiter, len(expected[0]))
    assert data is not None
    assert data.tolist() == expected
    assert same_bits(data, loadtxt(text, delimiter, data.shape[1]))
    assert np.signbit(parse_plain_numbers(b"-0,1\n", ",", 2)[0, 0])


@pytest.mark.parametrize("text", [
    b"1e3,1\n", b"nan,1\n", b"inf,1\n", b"1,,2\n1,2\n", b"1,2,\n", b"1,2\n3\n", b"1,2\n   \n3,4\n", b"1,2\r3,4\n",
    b"1,2 # note\n", b"1.2.3,4\n", b"--1,2\n", b"1-2,3\n", b".,1\n", b"-,1\n", b"1,2 3\n", b"",
    b"\xc3\xa91,2\n", b"1\t,2\n", ("1" * (MAX_DIGITS + 1) + ",2\n").encode(),
])
def test_anything_else_is_declined(text):
    assert parse_plain_numbers(text, ",", 2) is None


ROWS = st.lists(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=3, max_size=3), min_size=1, max_size=20)


@PROFILE
@given(rows=ROWS, decimals=st.integers(0, 8), delimiter=st.sampled_from([",", ";", "\t", "|", " "]),
       pad=st.sampled_from(["", " "]), line_end=st.sampled_from(["\n", "\r\n"]), final=st.booleans())
def test_formatted_tables_equal_loadtxt(rows, decimals, delimiter, pad, line_end, final):
    """What loggers write (fixed decimals, any delimiter, blanks after it, CRLF): read, and equal to loadtxt."""
    sep = delimiter + (pad if delimiter != " " else "")
    text = (line_end.join(sep.join(f"{v:.{decimals}f}" for v in row) for row in rows) + (line_end if final else "")).encode()
    data = parse_plain_numbers(text, delimiter, 3)
    assert data is not None
    assert same_bits(data, loadtxt(text, delimiter, 3))


@PROFILE
@given(text=st.binary(max_size=40).map(bytes) | st.text("0123456789.-+, \t\r\n;e#", max_size=40).map(str.encode),
       delimiter=st.sampled_from([",", " ", "\t", ";"]), n_columns=st.integers(1, 3))
def test_any_text_is_read_as_loadtxt_reads_it_or_declined(text, delimiter, n_columns):
    data = parse_plain_numbers(text, delimiter, n_columns)
    if data is not None:
        assert same_bits(data, loadtxt(text, delimiter, n_columns))


def test_a_file_with_a_header_and_a_byte_order_mark(tmp_path):
    path = tmp_path / "log.csv"
    path.write_bytes(b"\xef\xbb\xbft,ax,ay,az\r\n0.01,1,2,3\r\n0.02,-1,.5,3.25\r\n")
    layout = sniff_layout(path)
    parsed = parse_numbers(path, layout)
    assert parsed.engine == "numpy"
    assert [c.tolist() for c in parsed.columns] == [[0.01, 0.02], [1, -1], [2, 0.5], [3, 3.25]]
    assert read_plain_numbers(path, ",", 5, 4) is None  # fewer lines than the header claims


def test_imutk_xsens_recording_equals_loadtxt(shared_data):
    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    data = read_plain_numbers(path, ",", 1, 7)
    assert data is not None and data.shape == (51175, 7)
    assert same_bits(data, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2))
