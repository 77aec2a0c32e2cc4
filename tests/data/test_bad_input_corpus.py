"""A corpus of bad input, generated here (no one's data copied): each file with its exact expected
outcome on the command line: the exit code, the kind of message, and what was counted."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from optcal.cli.main import main
from optcal.families.simulate.poses import uniform_directions

RATE = 100.0


def recording(n_poses: int = 8, dwell: int = 300, move: int = 100, sigma: float = 0.002, seed: int = 0) -> np.ndarray:
    """Columns t, ax, ay, az (g): rests in random orientations joined by linear moves."""
    rng = np.random.default_rng(seed)
    dirs = uniform_directions(n_poses, rng=seed + 1)
    parts = []
    for k, d in enumerate(dirs):
        parts.append(np.repeat(d[None], dwell, axis=0))
        if k + 1 < n_poses:
            w = np.linspace(0, 1, move)[:, None]
            path = (1 - w) * d + w * dirs[k + 1]
            parts.append(path / np.linalg.norm(path, axis=1, keepdims=True))
    acc = np.vstack(parts) + sigma * rng.standard_normal((sum(len(p) for p in parts), 3))
    t = np.arange(acc.shape[0]) / RATE
    return np.column_stack([t, acc])


def csv_text(rows: np.ndarray, header: str = "t,ax,ay,az") -> str:
    body = "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows)
    return (header + "\n" if header else "") + body + "\n"


@dataclass
class Case:
    """One corpus entry: how to write the file, the command, and the expected outcome."""

    name: str
    write: Callable[[Path], Path]
    command: str = "segment"
    extra: list[str] = field(default_factory=list)
    code: int = 2
    message: str = ""
    counted: dict[str, int] = field(default_factory=dict)
    poses: int | None = None


def text(content: str | bytes, name: str = "f.csv") -> Callable[[Path], Path]:
    def write(d: Path) -> Path:
        p = d / name
        p.write_bytes(content if isinstance(content, bytes) else content.encode())
        return p
    return write


def with_cells(edit: Callable[[np.ndarray], np.ndarray], header: str = "t,ax,ay,az", **kw: object) -> Callable[[Path], Path]:
    def write(d: Path) -> Path:
        p = d / "f.csv"
        p.write_text(csv_text(edit(recording(**kw)), header))  # type: ignore[arg-type]
        return p
    return write


def _nan_inf(r: np.ndarray) -> np.ndarray:
    r = r.copy()
    r[100, 1], r[200, 2], r[300, 3] = np.nan, np.inf, -np.inf
    return r


def _duplicated(r: np.ndarray) -> np.ndarray:
    return np.insert(r, [500, 900], r[[499, 899]], axis=0)


def _backwards(r: np.ndarray) -> np.ndarray:
    r = r.copy()
    r[1000:, 0] -= 5.0
    return r


def _saturated(r: np.ndarray) -> np.ndarray:
    r = r.copy()
    r[[330, 331, 735, 736], 1] = 2.0  # a ±2 g rail, hit in the moves
    r[[332, 737], 1] = -2.0
    return r


def _still(r: np.ndarray) -> np.ndarray:
    rng = np.random.default_rng(3)
    n = 3000
    acc = np.array([0.0, 0.0, 1.0]) + 0.002 * rng.standard_normal((n, 3))
    return np.column_stack([np.arange(n) / RATE, acc])


def _spinning(r: np.ndarray) -> np.ndarray:
    t = np.arange(0, 30, 0.01)
    a = np.column_stack([np.cos(0.8 * t), np.sin(0.8 * t) * np.cos(0.3 * t), np.sin(0.8 * t) * np.sin(0.3 * t)])
    return np.column_stack([t, a])


def _coplanar_poses(d: Path) -> Path:
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    acc = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)])
    p = d / "poses.csv"
    p.write_text(csv_text(acc, "ax,ay,az"))
    return p


def _absurd(r: np.ndarray) -> np.ndarray:
    r = r.copy()
    r[150, 2] = 1e308
    r[160, 3] = -1e300
    return r


def _folder(d: Path) -> Path:
    (d / "folder").mkdir()
    return d / "folder"


CORPUS = [
    Case("empty", text(""), message="the file is empty"),
    Case("blank lines only", text("\n\n  \n"), message="the file is empty"),
    Case("header only", text("t,ax,ay,az\n"), message="no data rows"),
    Case("binary", text(bytes(range(256)) * 8, "f.bin"), message="not a text file"),
    Case("header and row disagree", text("ax,ay,az\n1,2\n"), message="looks like the header (3 columns"),
    Case("missing column", with_cells(lambda r: r[:, :3], "t,ax,ay"), message="no accelerometer column(s) for az"),
    Case("unknown --columns name", with_cells(lambda r: r), extra=["--columns", "acc=ax"], message="unknown name 'acc'"),
    Case("--columns names a missing column", with_cells(lambda r: r), extra=["--columns", "ax=nope,ay=ay,az=az"],
         message="there is no column 'nope'"),
    Case("--columns position out of range", with_cells(lambda r: r), extra=["--columns", "ax=9,ay=3,az=4"],
         message="or give a 1-based position 1..4"),
    Case("directory instead of file", _folder, message="is a directory but not a ROS 2 bag"),
    Case("no such file", lambda d: d / "missing.csv", message="no such file or directory"),
    Case("NaN and inf cells", with_cells(_nan_inf), code=0,
         counted={"non-finite samples (empty, non-numeric or truncated cells)": 3}, poses=8),
    Case("absurd values", with_cells(_absurd), code=0,
         counted={"samples beyond any full scale (an axis above 64 g)": 2}, poses=8),
    Case("duplicated timestamps", with_cells(_duplicated), code=0,
         counted={"duplicated samples (same time and values as the previous one)": 2}, poses=8),
    Case("backwards timestamps", with_cells(_backwards), message="time runs backwards at data row 1001"),
    Case("saturated", with_cells(_saturated), code=0, counted={"saturated samples": 6}, poses=8),
    Case("never static", with_cells(_spinning), extra=["--format", "raw"], message="no static interval found"),
    Case("one orientation", with_cells(_still), command="calibrate", message="only 1 poses"),
    Case("coplanar poses", _coplanar_poses, command="calibrate", message="coplanar"),
    Case("headerless, 5 columns", text("1 2 3 4 5\n" * 20), message="fit no common layout"),
    Case("pipe-delimited", text(csv_text(recording()).replace(",", "|")), code=0, poses=8),
    Case("decimal commas", text(csv_text(recording()).replace(",", ";").replace(".", ",")), code=0, poses=8),
    Case("units contradict the norm", with_cells(lambda r: r), extra=["--units", "m/s^2"],
         message="units m/s^2 (given with --units) contradict the data"),
    Case("ambiguous kind", text(csv_text(np.column_stack([
        np.repeat(uniform_directions(20, rng=5), 3, axis=0)
        + 0.03 * np.random.default_rng(6).standard_normal((60, 3))]), "ax,ay,az")),
         message="cannot tell a pose table from a raw recording"),
]


@pytest.mark.parametrize("case", CORPUS, ids=[c.name for c in CORPUS])
def test_corpus(case: Case, tmp_path, capsys):
    path = case.write(tmp_path)
    json_flag = ["--json"] if case.command == "segment" and case.code == 0 else []
    code = main([case.command, str(path), *case.extra, *json_flag])
    out, err = capsys.readouterr()
    assert code == case.code, err
    assert "Traceback" not in err
    if case.code == 2:
        assert err.startswith("error: ") and err.count("\n") == 1
        assert out == "" or out.startswith(f"DATA: {path} refused; the decisions made before:")  # issue 26
        assert case.message in err
        return
    data = json.loads(out)["data"]
    for what, count in case.counted.items():
        assert data["exclusions"][what] == count
    if case.poses is not None:
        assert data["n_poses"] == case.poses
