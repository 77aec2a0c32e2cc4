"""The reading evidence computed piece by piece (:data:`optcal.data.evidence.EVIDENCE_PIECE`) is the
evidence of whole-column operations: every count, mask and median the same, bit for bit."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

import optcal.data.evidence as evidence
from optcal.data.readers import read_source


def _write(path: Path, rows: np.ndarray) -> Path:
    lines = ["time,ax,ay,az,gx,gy,gz"]
    for row in rows:
        lines.append(",".join("" if not np.isfinite(v) else f"{v:.9g}" for v in row))
    path.write_text("\n".join(lines) + "\n")
    return path


def _log(n: int, rng: np.random.Generator, counts: bool = False) -> np.ndarray:
    t = np.arange(n) / 100.0
    acc = rng.normal(0.0, 2e-3, (n, 3)) + [0.0, 0.0, 1.0]
    gyro = rng.normal(0.0, 0.05, (n, 3))
    if counts:  # an unsigned 16-bit converter's counts about mid-scale (the counts statistics are taken)
        acc = np.rint(32768 + acc * 4096)
        gyro = np.rint(32768 + gyro * 100)
    return np.column_stack([t, acc, gyro])


def _evidence(path: Path, piece: int, monkeypatch: pytest.MonkeyPatch, parallel: int = 10**9) -> evidence.Evidence:
    monkeypatch.setattr(evidence, "EVIDENCE_PIECE", piece)
    monkeypatch.setattr(evidence, "PARALLEL_ROWS", parallel)
    return evidence.gather_evidence(read_source(str(path)))


def _same(a: evidence.Evidence, b: evidence.Evidence) -> None:
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert np.array_equal(x, y), f.name
        elif isinstance(x, float) and np.isnan(x):
            assert isinstance(y, float) and np.isnan(y), f.name
        else:
            assert x == y, f.name


@pytest.mark.parametrize("counts", [False, True])
def test_pieces_give_the_whole_columns_evidence(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, counts: bool) -> None:
    rng = np.random.default_rng(3)
    rows = _log(1000, rng, counts)
    rows[[17, 400], 2] = np.nan  # an empty cell: non-finite rows
    rows[[5, 333, 998], 1:] = 0.0  # an unfilled buffer: all-zero rows
    rows[[64, 650], 3] = rows[[64, 650], 3] * 1e4  # beyond any full scale: absurd samples
    path = _write(tmp_path / "log.csv", rows)
    whole = _evidence(path, 10**9, monkeypatch)  # one piece: the whole-column operations
    assert (whole.non_finite, whole.zero_rows, whole.absurd) == (2, 3, 2)
    for piece in (1, 7, 64, 999):  # pieces across every boundary, a last piece of one row
        _same(_evidence(path, piece, monkeypatch), whole)
        _same(_evidence(path, piece, monkeypatch, parallel=2), whole)  # two threads, each over half the rows


def test_the_two_thread_passes_cover_every_row_once_and_raise_the_helpers_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """evidence._over_rows: each row given to one of the two threads once; the helper thread's error raised."""
    monkeypatch.setattr(evidence, "PARALLEL_ROWS", 2)
    seen = np.zeros(11, dtype=int)

    def work(lo: int, hi: int) -> None:
        seen[lo:hi] += 1
        if lo:
            raise ValueError("helper")

    with pytest.raises(ValueError, match="helper"):
        evidence._over_rows(11, work)
    assert seen.tolist() == [1] * 11


def test_the_medians_are_numpys_on_the_usable_rows(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(4)
    rows = _log(777, rng)
    rows[100, 1] = np.nan
    path = _write(tmp_path / "log.csv", rows)
    ev = _evidence(path, 13, monkeypatch)
    acc = read_source(str(path)).data
    a = np.column_stack([acc["ax"], acc["ay"], acc["az"]])
    usable = np.all(np.isfinite(a), axis=1)
    assert np.array_equal(ev.usable, usable)
    assert ev.median_norm == np.median(np.linalg.norm(a[usable], axis=1))
    assert ev.median_step == pytest.approx(np.median(np.linalg.norm(np.diff(a[usable], axis=0), axis=1)), rel=1e-15)


@pytest.mark.parametrize("piece", [3, 10**9])
def test_time_evidence_is_numpys_on_the_steps_in_order(monkeypatch: pytest.MonkeyPatch, piece: int) -> None:
    monkeypatch.setattr(evidence, "EVIDENCE_PIECE", piece)
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.choice([0.0, 0.01, 0.01, 0.01, 0.02, 0.5], 500) + rng.normal(0, 1e-4, 500))
    t[[50, 300]] -= 1.0  # two stamps backwards: the first one's row is kept in order
    d = np.diff(t)
    med = float(np.median(d))
    ev = evidence.time_evidence(t)
    assert ev.median_step == med
    assert ev.first_backwards == int(np.flatnonzero(d < 0)[0] + 1) and ev.backwards == int(np.count_nonzero(d < 0))
    assert ev.regular_fraction == float(np.mean(np.abs(d - med) <= 0.5 * med))
    assert ev.min_positive_step == float(d[d > 0].min()) and ev.repeated == int(np.count_nonzero(d == 0))
    assert evidence.time_evidence(t[:1]).regular_fraction == 0.0
