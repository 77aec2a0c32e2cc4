"""What the data layer does to be fast gives the same numbers as the plain way: medians and quantiles by one
partition (numpy's values bit for bit), pyarrow's threaded reader (the streaming reader's numbers bit for
bit), and the gyro statistics computed in a second thread (the segmentation of the sequential path)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import optcal.data.static as static
import optcal.data.column_block as column_block
import optcal.data.text as text
from optcal.data.quantiles import column_medians, median, np_column_medians, np_median, np_quantile, quantiles
from optcal.data.readers import source_from_frame
from optcal.data.recording import recording_from_source
from optcal.families.simulate.recording import synthesize_recording
from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import uniform_directions


def test_median_and_quantiles_are_numpys_bit_for_bit():
    rng = np.random.default_rng(7)
    for trial in range(400):
        n = int(rng.integers(1, 40)) if trial % 2 else int(rng.integers(1, 3000))
        x = rng.normal(size=n) * 10 ** rng.uniform(-4, 6)
        if trial % 3 == 0:
            x = np.round(x)  # ties
        assert median(x) == np.median(x)
        probabilities = [float(rng.uniform()), 0.1, 0.02, 0.0, 1.0]
        assert quantiles(x, probabilities) == list(np.quantile(x, probabilities))
        assert quantiles(x, probabilities, scratch=np.empty(n + 3)) == list(np.quantile(x, probabilities))
    block = rng.normal(size=(101, 3))
    assert np.array_equal(column_medians(block), np.median(block, axis=0))



def _same(a: object, b: object) -> bool:
    """The same values bit for bit, NaN equal to NaN, and the same shape."""
    x, y = np.asarray(a), np.asarray(b)
    return x.shape == y.shape and bool(np.array_equal(x, y, equal_nan=True))


def test_np_median_and_np_quantile_are_numpys_with_nan_infinities_and_integers():
    """The drop-ins the rest model uses in place of np.median and np.quantile (which import numpy.ma, 15 ms of a
    process): numpy's values for finite floats, integers (block counts), odd and even sizes, columns, and NaN or
    infinities (numpy's own path)."""
    rng = np.random.default_rng(11)
    with np.errstate(invalid="ignore"):  # inf − inf in numpy's own interpolation, on both sides
        for trial in range(300):
            n = int(rng.integers(1, 50)) if trial % 2 else int(rng.integers(1, 2000))
            x = rng.normal(size=(n, 3)) * 10 ** rng.uniform(-6, 6) + rng.normal(size=3) * 10 ** rng.uniform(-3, 3)
            if trial % 5 == 1:
                x = np.round(x)  # ties
            if trial % 7 == 2:
                x[rng.integers(0, n), rng.integers(0, 3)] = [np.nan, np.inf, -np.inf][trial % 3]
            p = float(rng.uniform())
            assert _same(np_median(x), float(np.median(x)))
            assert _same(np_column_medians(x), np.median(x, axis=0))
            assert _same(np_median(x[:, 0]), float(np.median(x[:, 0])))
            assert _same(np_quantile(x[:, 1], p), np.quantile(x[:, 1], p))
            assert _same(np_quantile(x[:, 2], 0.99), np.percentile(x[:, 2], 99))
            counts = rng.integers(1, 400, size=n)
            assert _same(np_median(counts), float(np.median(counts)))
    with pytest.warns(RuntimeWarning):  # numpy's own warning of an empty median, as before
        assert np.isnan(np_median(np.array([]))) and np_column_medians(np.zeros((0, 3))).shape == (3,)


def test_the_rest_model_does_not_import_numpy_ma(tmp_path):
    """numpy's median and quantile import numpy.ma the first time (≈ 15 ms of CPU at each process's start): the
    read and segmentation of a recording with a gyro does not."""
    import subprocess
    import sys

    model = LumpedModel.from_physical([16300, 16400, 16700], 0.01, -0.005, 0.008, [700, -360, -1800])
    path = tmp_path / "rec.csv"
    synthesize_recording(model, uniform_directions(12, rng=3), sigma=60.0, quantum=1.0, units="counts",
                         rng=4).to_csv(str(path), float_format="%.6f")
    probe = ("import sys; from optcal.data import load; p = load(sys.argv[1]); "
             "print(p.n, 'numpy.ma' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", probe, str(path)], capture_output=True, text=True, check=True)
    n, imported = done.stdout.split()
    assert int(n) == 12 and imported == "False"

@pytest.fixture(scope="module")
def counts_recording():
    model = LumpedModel.from_physical([16300, 16400, 16700], 0.01, -0.005, 0.008, [700, -360, -1800])
    return synthesize_recording(model, uniform_directions(10, rng=4), sigma=60.0, quantum=1.0, units="counts",
                                rng=5, temperature=(25.0, 0.001))


@pytest.mark.parametrize("sep", [",", " "])
def test_ranged_and_streaming_readers_agree_bit_for_bit(tmp_path, monkeypatch, counts_recording, sep):
    path = tmp_path / "rec.txt"
    counts_recording.frame.to_csv(path, sep=sep, index=False, float_format="%.6f")
    monkeypatch.setattr(text, "ARROW_STREAM_BLOCK_BYTES", 32 * 1024)  # many blocks: several batches per reader
    layout = text.sniff_layout(path)
    ranged = text.arrow_ranged_block(path, layout)
    streamed = text.arrow_streamed_block(path, layout)
    assert ranged is not None and streamed is not None and ranged.n == streamed.n == len(counts_recording.frame)
    for a, b in zip(ranged.columns(), streamed.columns()):
        assert a.tobytes() == b.tobytes()
    # the ranged reader is the one used for a file above the small-file size and below THREADED_READ_BYTES
    monkeypatch.setattr(text, "SMALL_FILE_BYTES", 1024)
    parsed = text.parse_numbers(path, layout)
    assert parsed.engine == "pyarrow" and all(np.array_equal(a, b) for a, b in zip(parsed.columns, streamed.columns()))



@pytest.mark.parametrize("sep", [",", " "])
def test_ranged_reader_gives_the_streaming_readers_numbers_whatever_the_ranges(tmp_path, monkeypatch,
                                                                               counts_recording, sep):
    """The file cut at line starts into ranges parsed at once (text.arrow_ranged_block, the reader of files up to
    THREADED_READ_BYTES): the same numbers to the bit as one streaming reader over the whole file, in the file's
    order, for one range and for many; a bad cell in a later range leaves the file to pandas (None), and no thread
    is left running."""
    import threading

    path = tmp_path / "rec.txt"
    counts_recording.frame.to_csv(path, sep=sep, index=False, float_format="%.6f")
    monkeypatch.setattr(text, "ARROW_STREAM_BLOCK_BYTES", 32 * 1024)  # several batches per range
    layout = text.sniff_layout(path)
    whole_file = text.arrow_streamed_block(path, layout)
    assert whole_file is not None
    size = path.stat().st_size
    for parts in (1, 2, 7):
        ranges = text.text_ranges(path, layout, parts)
        assert len(ranges) == parts and ranges[0][0] == 0 and ranges[-1][1] == size
        assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))
        raw = path.read_bytes()
        assert all(raw[a - 1:a] == b"\n" for a, _ in ranges[1:])  # each later range starts a line
        ranged = text.arrow_ranged_block(path, layout, parts)
        assert ranged is not None and ranged.n == whole_file.n
        for a, b in zip(ranged.columns(), whole_file.columns()):
            assert a.tobytes() == b.tobytes()
    # lines shorter after the head than in it: a range holds more rows than its region, kept aside and joined
    mixed = tmp_path / "mixed.txt"
    head, *rows = path.read_text().splitlines()
    short = [sep.join(f"{float(v):.1f}" for v in row.split(sep)) for row in rows[200:]]
    mixed.write_text("\n".join([head, *rows[:200], *short]) + "\n")
    whole = text.arrow_streamed_block(mixed, text.sniff_layout(mixed))
    for parts in (2, 5):
        ranged = text.arrow_ranged_block(mixed, text.sniff_layout(mixed), parts)
        assert ranged is not None and whole is not None and ranged.n == whole.n == len(rows)
        assert all(a.tobytes() == b.tobytes() for a, b in zip(ranged.columns(), whole.columns()))
    bad = tmp_path / "bad.txt"
    bad.write_text(path.read_text() + sep.join(["1"] * (len(layout.names) - 1) + ["three"]) + "\n")
    before = threading.active_count()
    assert text.arrow_ranged_block(bad, text.sniff_layout(bad), 3) is None  # pandas then reads and counts the cell
    assert threading.active_count() == before
    monkeypatch.setattr(text, "SMALL_FILE_BYTES", 1024)
    parsed = text.parse_numbers(path, layout)
    assert parsed.engine == "pyarrow" and all(a.tobytes() == b.tobytes() for a, b in zip(parsed.columns,
                                                                                          whole_file.columns()))


def test_a_csv_read_does_not_import_the_container_readers(tmp_path):
    """Every read asks whether the file is a MATLAB or HDF5 container (optcal.data.container_kind); the container
    readers and their tables of names (optcal.data.containers, ≈ 4 ms of a process's start) come only with one."""
    import subprocess
    import sys

    path = tmp_path / "poses.csv"
    path.write_text("ax,ay,az\n" + "\n".join(f"{x},{y},{z}" for x, y, z in np.eye(3).tolist() * 4) + "\n")
    probe = ("import sys; from optcal.data import load; from optcal.data.containers import container_type as c; "
             "import optcal.data.container_kind as k; print(c is k.container_type)")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "True"  # the old name still reaches the function
    probe = "import sys; from optcal.data import load; p = load(sys.argv[1]); print(p.n, 'optcal.data.containers' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", probe, str(path)], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["12", "False"]
def test_ranged_reader_restores_pyarrows_default_pool_and_hands_memory_back(tmp_path, monkeypatch, counts_recording):
    """The ranged reader sets pyarrow's default pool to the system allocator for its call only (its readers' own
    buffers too), also when pyarrow refuses the file, and hands the freed memory back once every range is read."""
    import pyarrow as pa

    before = pa.default_memory_pool().backend_name
    trims: list[int] = []
    monkeypatch.setattr(column_block, "_malloc_trim", lambda: trims.append)
    path = tmp_path / "rec.csv"
    counts_recording.frame.to_csv(path, index=False, float_format="%.6f")
    layout = text.sniff_layout(path)
    block = text.arrow_ranged_block(path, layout, 2)
    assert block is not None and block.n == len(counts_recording.frame)
    assert pa.default_memory_pool().backend_name == before
    assert len(trims) == 1  # once, after the ranges are read
    bad = tmp_path / "bad.csv"
    bad.write_text(path.read_text() + "1,2,three\n")
    assert text.arrow_ranged_block(bad, text.sniff_layout(bad), 2) is None  # pandas then reads and counts the cell
    assert pa.default_memory_pool().backend_name == before
    assert len(trims) == 2


def test_the_readers_block_is_an_anonymous_mapping_of_base_pages_and_grows_keeping_its_rows():
    """ColumnBlock's array is an anonymous mapping (base pages, not numpy's huge-page allocation): Fortran order,
    writable, and a block grown by append keeps the rows already filled."""
    import mmap

    block = text.ColumnBlock(3, 4)
    assert isinstance(block.block.base, mmap.mmap) and block.block.flags["F_CONTIGUOUS"] and block.block.flags.writeable
    block.append([np.arange(3.0) + 10 * j for j in range(3)])
    block.append([np.arange(3.0, 6.0) + 10 * j for j in range(3)])  # 6 rows > 4: grown
    assert isinstance(block.block.base, mmap.mmap) and block.block.flags["F_CONTIGUOUS"]
    assert [c.tolist() for c in block.columns()] == [list(np.arange(6.0) + 10 * j) for j in range(3)]


def test_a_blocks_released_rows_are_whole_pages_inside_the_range_and_read_as_zero():
    """ColumnBlock.release_rows (the ranged reader's rows left behind by a move): only whole pages inside the rows
    given, in every column, are handed back; every other row keeps its number."""
    import mmap

    rows = 4 * mmap.PAGESIZE // 8 + 3  # columns not starting on a page boundary
    block = text.ColumnBlock(3, rows)
    block.append([np.arange(rows, dtype=float) + 1 + 10 * rows * j for j in range(3)])
    kept = block.block.copy()
    block.release_rows(100, 100 + 2 * mmap.PAGESIZE // 8)
    released = block.block == 0
    assert released.any(axis=0).all()  # in every column
    for j in range(3):
        gone = np.flatnonzero(released[:, j])
        assert gone[0] >= 100 and gone[-1] < 100 + 2 * mmap.PAGESIZE // 8
        assert gone.size * 8 % mmap.PAGESIZE == 0 and gone.size == gone[-1] - gone[0] + 1
        keep = ~released[:, j]
        assert np.array_equal(block.block[keep, j], kept[keep, j])


def _mapping(address: int) -> tuple[str, int]:
    """The permissions and resident kB of the mapping of this process that holds ``address`` (/proc/self/smaps)."""
    perms, inside = "", False
    with open("/proc/self/smaps") as fh:
        for line in fh:
            head = line.split()
            if "-" in head[0] and len(head) > 1 and len(head[1]) == 4:  # a mapping's first line: range, permissions
                lo, hi = (int(v, 16) for v in head[0].split("-"))
                inside, perms = lo <= address < hi, head[1]
            elif inside and head[0] == "Rss:":
                return perms, int(head[1])
    raise LookupError(hex(address))


@pytest.mark.skipif(not Path("/proc/self/smaps").exists() or column_block.PRIVATE_MAPPING is None,
                    reason="Linux's smaps and a private mapping")
def test_a_blocks_pages_are_private_and_released_rows_leave_its_memory():
    """The block is a private mapping (a private page's first touch costs less than a shared one's), and the rows
    release_rows hands back leave the process's resident memory (MADV_DONTNEED frees a private page; on a shared one
    it would only unmap it, the memory kept)."""
    import mmap

    page = mmap.PAGESIZE
    rows = 64 * page // 8
    block = text.ColumnBlock(2, rows)
    block.append([np.ones(rows), np.ones(rows)])
    perms, resident = _mapping(block.block.ctypes.data)
    assert perms.endswith("p") and resident * 1024 >= 2 * rows * 8
    block.release_rows(8 * page // 8, 40 * page // 8)  # 32 whole pages of each column
    assert _mapping(block.block.ctypes.data)[1] * 1024 == resident * 1024 - 2 * 32 * page
    assert not block.block[8 * page // 8:40 * page // 8].any() and block.block[:8 * page // 8].all()


def test_median_selected_in_a_bracket_is_numpys_on_adversarial_arrays(monkeypatch):
    """The large-array median (the middle values selected inside a bracket read from a subsample, the whole
    partitioned where it misses) is np.median's value bit for bit: odd and even sizes, ties at the middle (counts),
    heavy tails, all equal, two values, sorted either way, infinities in the tails, zeros of both signs at the
    middle; the bracket is taken where it should be, and a bracket made to miss (no half-width) still gives it."""
    import optcal.data.quantiles as quantiles_module
    from optcal.data.quantiles import BRACKET_MIN_VALUES, _middle_in_bracket

    rng = np.random.default_rng(40)
    n = BRACKET_MIN_VALUES + 1001
    cases = {
        "normal": rng.normal(size=n), "counts": np.round(rng.normal(size=n) * 2.0) + 300.0,
        "cauchy": rng.standard_cauchy(size=n), "pareto": rng.pareto(0.7, size=n) + 1e-3,
        "equal": np.full(n, 0.1), "two values": np.where(rng.random(n) < 0.5, 2.0, 3.0),
        "ascending": np.sort(rng.normal(size=n)), "descending": -np.sort(-rng.exponential(size=n)),
        "infinite tails": np.r_[rng.normal(size=n - 100) + 5.0, np.full(50, np.inf), np.full(50, -np.inf)],
        "signed zeros": np.where(rng.random(n) < 0.5, -0.0, 0.0) * (rng.random(n) < 0.9) + (rng.random(n) < 0.1),
        "a tie across the middle": np.r_[np.full(n // 2 - 3, 1.0), np.full(7, 2.0), np.full(n - n // 2 - 4, 3.0)],
    }
    for name, x in cases.items():
        for values in (x, x[:-1]):  # odd and even sizes
            expected = float(np.median(values))
            assert _same(quantiles_module.median(values), expected) and (
                np.signbit(quantiles_module.median(values)) == np.signbit(expected)), name
            lower, upper = (values.size - 1) // 2, values.size // 2
            ordered = np.sort(values)
            middle = _middle_in_bracket(values, lower, upper)
            if name not in ("signed zeros",):  # every other case is selected inside its bracket
                assert middle == (ordered[lower], ordered[upper]), name
            else:
                assert middle is None  # a zero's sign is the whole partition's to pick
    for name, x in cases.items():  # the columns' medians, selected in brackets: the whole partition's, signs included
        for values in (x, x[:-1]):
            stack = np.column_stack([values, values[::-1], -values])
            mid = stack.shape[0] // 2
            part = np.partition(stack, mid, axis=0)
            whole = part[mid] if stack.shape[0] % 2 else (part[:mid].max(axis=0) + part[mid]) / 2
            got = column_medians(stack)
            assert _same(got, whole) and np.array_equal(np.signbit(got), np.signbit(whole)), name
    monkeypatch.setattr(quantiles_module, "BRACKET_SIGMAS", 0.0)  # a bracket of no width: it misses, or holds ties
    for name, x in cases.items():
        assert _same(quantiles_module.median(x[:-1]), float(np.median(x[:-1]))), name
    import subprocess
    import sys

    probe = ("import sys, numpy as np; from optcal.data.quantiles import median; median(np.arange(70000.0)); "
             "print('numpy.random' in sys.modules)")  # its subsample is no reason to import numpy.random (7 MB)
    assert subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.strip() == "False"


def test_block_moments_by_pieces_are_the_whole_columns(monkeypatch):
    """The blocks' means and variances summed piece by piece (pieces of whole blocks, the first from sample 0) are
    the same bit for bit as one pass over each whole column: pieces of a few blocks, cut beside breaks and inside
    segments, against the unpieced sums; the rounding term's extremes over every sample (a spike in the last piece)."""
    import optcal.data.rest_model as rm

    rng = np.random.default_rng(11)
    m = 20_011
    x = rng.normal(size=(m, 3)) * [1e-3, 2.0, 50.0] + [0.0, -1.0, 1e4]
    x[:, 0] = 5.0  # a noise-free column: its blocks' variances are the rounding term of its largest deviation,
    x[-3, 0] += 1.0  # which is in the last piece
    t = np.arange(m) / 100.0
    breaks = np.array([37, 5000, 5003, 12_345], dtype=np.int64)

    def whole_columns(x, starts, n, quant_var):  # one pass over each column (the plain formula)
        mean, var = np.empty((starts.size, 3)), np.empty((starts.size, 3))
        for j in range(3):
            col = x[:, j]
            centre = median(col[:: max(1, col.size // 1000)])
            dev = col - centre
            s1 = np.add.reduceat(dev, starts)
            largest = max(float(dev.max()), -float(dev.min()))
            s2 = np.add.reduceat(dev * dev, starts)
            mu = s1 / n
            mean[:, j] = mu + centre
            rounding = (rm.ROUNDING_ULPS * np.finfo(float).eps * float(np.max(n)) * largest) ** 2
            var[:, j] = np.maximum(s2 - n * mu * mu, 0.0) / np.maximum(n - 1.0, 1.0) + quant_var + rounding
        return mean, var

    for piece in (rm.BLOCK_PIECE, 64, 1000):
        monkeypatch.setattr(rm, "BLOCK_PIECE", piece)
        b = rm.make_blocks(t, x, x[::-1] * 3.0, 25, breaks, 0.5, 0.0)
        mean, var = whole_columns(x, b.start, b.n, 0.5**2 / 12.0)
        gmean, gvar = whole_columns(x[::-1] * 3.0, b.start, b.n, 0.0)
        assert _same(b.mean, mean) and _same(b.var, var) and _same(b.gmean, gmean) and _same(b.gvar, gvar), piece


def test_quantum_and_gap_search_chunk_by_chunk_are_the_whole_columns(monkeypatch):
    """:func:`quantum` (its steps through one buffer, the non-zero ones taken by position where zeros are few, the
    columns left unread once the span decides) and the rest model's search for time gaps (piece by piece) give what
    whole-column passes give: the non-zero steps, their smallest and every stride-th of them as ``d[d > 0]`` (few
    zeros, most zeros, none, NaN); the converter's step or None on counts, counts with 2 % odd steps, printed
    decimals, a NaN, a wide first column whose span decides before the last is read; the gaps at every place, the pieces' edges included."""
    import optcal.data.quantisation as qz
    from optcal.data.quantisation import _non_zero_steps, quantum

    rng = np.random.default_rng(14)
    for zeros in (0.0, 1e-3, 0.3, 0.7, 1.0):
        d = np.abs(np.round(rng.normal(size=5003) * 4.0)) + 1.0
        d[rng.random(d.size) < zeros] = 0.0
        d[rng.integers(0, d.size, 3)] = np.nan if zeros == 0.3 else d[0]
        for first, stride in ((0, 1), (5, 7), (40, 129), (6000, 3)):
            kept = d[d > 0]
            steps, q, sample = _non_zero_steps(d.copy(), first, stride)
            assert steps == kept.size and q == (kept.min() if kept.size else np.inf), (zeros, first, stride)
            assert np.array_equal(sample, kept[first::stride]), (zeros, first, stride)

    def whole_columns(x):  # the plain definition: every column's non-zero |diff| at once
        q, span, n_steps, sample = np.inf, 0.0, 0, []
        stride = max(1, (x.shape[0] - 1) * x.shape[1] // qz.QUANTUM_CHECK_STEPS)
        for col in x.T:
            d = np.abs(np.diff(col))
            d = d[d > 0]
            if d.size:
                q = min(q, float(d.min()))
                sample.append(d[::stride])
            n_steps += d.size
            span = max(span, float(np.max(col) - np.min(col)))
        if n_steps < 10 or span > (2**16 + 1) * q or (q < 1.0 and abs(np.log10(q) - round(np.log10(q))) < 1e-6):
            return None
        off = np.abs(np.concatenate(sample) / q - np.round(np.concatenate(sample) / q))
        return q if np.count_nonzero(off < 1e-3) / off.size >= 0.99 else None

    counts = np.round(rng.normal(size=(6000, 3)) * [3.0, 0.2, 40.0] + 100.0) * 0.0625  # many zero steps on one axis
    odd = counts.copy()
    odd[rng.random(odd.shape) < 0.02] += 0.01
    nan = counts.copy()
    nan[100, 1] = np.nan
    wide = counts.copy()
    wide[:, 0] *= 2.0**15  # spans more than 2¹⁶ of the other columns' step: decided on the first column
    cases = {"counts": counts, "odd steps": odd, "printed": np.round(rng.normal(size=(6000, 3)), 6),
             "a NaN": nan, "wide first": wide, "constant": np.ones((50, 2))}
    expected = {"counts": 0.0625, "odd steps": None, "printed": None, "a NaN": 0.0625, "wide first": None,
                "constant": None}
    for chunk, steps in ((qz.STEP_CHUNK, qz.QUANTUM_CHECK_STEPS), (97, 1000)):
        monkeypatch.setattr(qz, "STEP_CHUNK", chunk)
        monkeypatch.setattr(qz, "QUANTUM_CHECK_STEPS", steps)
        for name, x in cases.items():
            assert quantum(x) == whole_columns(x) == expected[name], (name, chunk)

    t = np.cumsum(rng.choice([0.01, 0.01, 0.01, 0.2], size=3000))
    for piece in (static.GAP_PIECE, 64, 1, 2999, 3000):
        monkeypatch.setattr(static, "GAP_PIECE", piece)
        for times in (t, t[:1], t[:2], np.r_[0.0, 1.0], np.r_[t[:700], np.nan, t[700:]]):
            got = static._gaps(times, 0.05)
            assert got.dtype == np.int64 and np.array_equal(got, np.flatnonzero(np.diff(times) > 0.05) + 1), piece


def test_one_quantile_of_many_values_selected_in_a_bracket_is_numpys():
    """A single quantile of at least BRACKET_MIN_VALUES values (the noise colour's), its two order statistics selected
    inside a bracket, is np.quantile's value bit for bit: at 0, ¼, ½, ⅓ and 1, on noise, counts (ties), a tie across
    the quantile, ratios with zeros at the quartile (refused by the bracket: the whole partitioned)."""
    from optcal.data.quantiles import BRACKET_MIN_VALUES, _quantile_in_bracket, column_quantile

    rng = np.random.default_rng(41)
    n = BRACKET_MIN_VALUES + 7
    cases = {"chi2": rng.chisquare(3, size=n), "counts": np.round(rng.normal(size=n) * 2.0) + 300.0,
             "tie": np.r_[np.full(n // 4 - 2, 1.0), np.full(9, 2.0), np.full(n - n // 4 - 7, 3.0)],
             "zeros": np.where(rng.random(n) < 0.3, 0.0, rng.exponential(size=n))}
    for name, x in cases.items():
        for p in (0.0, 0.25, 0.5, 1.0 / 3.0, 1.0):
            assert quantiles(x, [p]) == [float(np.quantile(x, p))], (name, p)
            assert quantiles(x, [p, p]) == [float(np.quantile(x, p))] * 2, (name, p)
        stack = np.column_stack([x, x[::-1] * 2.0])
        assert np.array_equal(column_quantile(stack, 0.25), np.quantile(stack, 0.25, axis=0)), name
    assert _quantile_in_bracket(cases["chi2"], 0.25) == float(np.quantile(cases["chi2"], 0.25))
    assert _quantile_in_bracket(cases["zeros"], 0.25) is None  # the quartile is a zero: the bracket refuses it
