"""Property tests (hypothesis) on every reader: whatever the bytes, the shape or the dtypes of a
file, reading it ends in data or in one :class:`~optcal.errors.InputError`, never a traceback."""

from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from optcal.cli.main import main
from optcal.data import load_with_segmentation
from optcal.errors import InputError

PROFILE = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
#: Magic bytes of each binary reader, so that random bodies reach every reader.
MAGIC = [b"", b"ULog\x01\x12\x35", b"#ROSBAG V2.0\n", b"PAR1", b"SQLite format 3\x00", b"\x89MCAP0\r\n"]
SUFFIX = ["csv", "ulg", "bag", "parquet", "db3", "mcap"]


def read(path) -> None:
    """Read like every command does; only InputError may escape."""
    try:
        load_with_segmentation(path)
    except InputError as exc:
        assert str(exc)


@PROFILE
@given(kind=st.integers(0, len(MAGIC) - 1), body=st.binary(max_size=2000))
def test_random_bytes_never_raise_anything_but_input_error(tmp_path, kind, body):
    path = tmp_path / f"f.{SUFFIX[kind]}"
    path.write_bytes(MAGIC[kind] + body)
    read(path)


CELL = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.integers(-(2**40), 2**40),
    st.sampled_from(["", "nan", "inf", "-", "oops", "1,5", "1e400", " ", '"x"', "0x10"]),
)
SEPARATORS = [",", ";", "\t", "|", " "]


@PROFILE
@given(
    header=st.sampled_from([None, "t,ax,ay,az", "ax,ay,az", "t,ax,ay,az,gx,gy,gz", "ax,ay", "x,y,z", "acc_x_g,acc_y_g,acc_z_g"]),
    rows=st.lists(st.lists(CELL, min_size=1, max_size=8), min_size=0, max_size=60),
    sep=st.sampled_from(SEPARATORS),
)
def test_random_text_tables_never_raise_anything_but_input_error(tmp_path, header, rows, sep):
    lines = [] if header is None else [header.replace(",", sep)]
    lines += [sep.join(str(c) for c in r) for r in rows]
    path = tmp_path / "f.csv"
    path.write_text("\n".join(lines) + "\n")
    read(path)


@PROFILE
@given(
    n=st.integers(0, 400),
    columns=st.lists(st.sampled_from(["t", "ax", "ay", "az", "gx", "gy", "gz", "temp", "sigma", "label"]),
                     min_size=1, max_size=8, unique=True),
    dtype=st.sampled_from(["float64", "float32", "int16", "int64", "object"]),
    scale=st.sampled_from([1e-3, 1.0, 9.81, 16384.0, 1e300]),
    seed=st.integers(0, 2**16),
)
def test_random_parquet_and_csv_frames(tmp_path, n, columns, dtype, scale, seed):
    rng = np.random.default_rng(seed)
    frame = pd.DataFrame({c: (rng.standard_normal(n) * scale) for c in columns})
    if "t" in frame:
        frame["t"] = np.sort(rng.uniform(0, n / 100.0, n))
    if "label" in frame:
        frame["label"] = [f"l{i}" for i in range(n)]
    with np.errstate(all="ignore"):
        frame = frame.astype({c: dtype for c in columns if c != "label"}, errors="ignore")
    frame.to_parquet(tmp_path / "f.parquet")
    frame.to_csv(tmp_path / "f.csv", index=False)
    read(tmp_path / "f.parquet")
    read(tmp_path / "f.csv")


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(body=st.binary(max_size=500), command=st.sampled_from(["segment", "calibrate", "allan", "check"]))
def test_command_line_gives_an_exit_code_not_a_traceback(tmp_path, capsys, body, command):
    path = tmp_path / "f.csv"
    path.write_bytes(body)
    argv = [command, str(path)] if command != "check" else [command, str(path), str(path)]
    code = main(argv)
    _, err = capsys.readouterr()
    assert code in (0, 2) and "Traceback" not in err
