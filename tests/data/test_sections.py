"""A sample counter that steps back where a section label changes (imucal's annotated session) is not time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optcal.data import load_recording
from optcal.errors import InputError


def _write(path: Path, labels: list[str], counter: np.ndarray) -> Path:
    rng = np.random.default_rng(0)
    lines = ["part,samples,acc_x,acc_y,acc_z"]
    for lab, c in zip(labels, counter):
        a = np.array([0.0, 0.0, 1.0]) + 0.001 * rng.standard_normal(3)
        lines.append(f"{lab},{int(c)}," + ",".join(f"{v:.6f}" for v in a))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_counter_stepping_back_at_label_changes_reads(tmp_path: Path) -> None:
    # two sections stored in the order b, a, each with its own sample numbers (a: 0-99, b: 100-199)
    counter = np.concatenate([np.arange(100, 200), np.arange(0, 100)])
    rec = load_recording(_write(tmp_path / "s.csv", ["b"] * 100 + ["a"] * 100, counter), rate=100.0)
    assert "sample counter" in rec.decisions.time_base.reason
    assert np.all(np.diff(rec.t) > 0)  # the row number over the rate, not the counter


def test_counter_stepping_back_inside_a_section_is_refused(tmp_path: Path) -> None:
    counter = np.concatenate([np.arange(100, 150), np.arange(0, 150)])
    with pytest.raises(InputError, match="runs backwards"):
        load_recording(_write(tmp_path / "s.csv", ["b"] * 100 + ["a"] * 100, counter), rate=100.0)
