"""Issue 26 (items 2 and 8): kind and time by weighed evidence, the decisions printed on the error path,
and one pass of evidence along the recording path.  Each regression test fails on the data layer before
issue 26."""

from __future__ import annotations

import sys
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import optcal.data.decisions as decisions
from helpers.cli_run import run
from helpers.common import SHARED
from optcal.data import load, load_recording, load_with_segmentation
from optcal.errors import InputError
from optcal.families.simulate.poses import uniform_directions

XSENS = SHARED / "data" / "imutk-xsens" / "xsens_imutk.csv"
needs_xsens = pytest.mark.skipif(not XSENS.exists(), reason="needs ../shared/data/imutk-xsens")


def dense_pose_table(path: Path, n: int = 2000, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``t,ax,ay,az``: n poses 5-10 s apart, t in seconds (as README documents for pose tables), in g."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(5.0, 10.0, n))
    acc = uniform_directions(n, rng=seed + 1) + 1e-4 * rng.standard_normal((n, 3))
    pd.DataFrame({"t": t, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(path, index=False, float_format="%.7f")
    return t, acc


# 2 --------------------------------------------------------------------- kind and time by weighed evidence
def test_a_dense_pose_table_with_t_in_seconds_is_a_pose_table(tmp_path):
    """2000 poses 5-10 s apart: seconds give 0.13 Hz, no recording's rate; the column is not re-read as
    milliseconds (131 Hz), at which rate no recording changes by 140 % of 1 g between rows."""
    t, acc = dense_pose_table(tmp_path / "poses.csv")
    poses = load(tmp_path / "poses.csv")
    assert poses.source == "pose table" and poses.n == 2000
    assert np.allclose(poses.t, t)  # seconds, never rescaled
    reason = poses.decisions.kind.reason
    assert "as distinct poses do" in reason and "in seconds, as documented" in reason
    assert "were t in ms" in reason and f"{100 * decisions.max_recording_step_g(1e3 / np.mean(np.diff(t))):.3g} %" in reason


def test_the_step_bound_is_a_turn_and_the_noise():
    """The model: a turn at 2000 °/s between two samples, and the noise of two samples at 50 mg per axis."""
    max_recording_step_g = decisions.max_recording_step_g
    noise = np.sqrt(6.0) * 0.05
    assert max_recording_step_g(100.0) == pytest.approx(2 * np.sin(np.deg2rad(2000.0) / 200.0) + noise)
    assert max_recording_step_g(1.0) == pytest.approx(2.0 + noise)  # any change: a reversal
    rates = [10.0, 100.0, 1000.0]
    assert all(max_recording_step_g(a) > max_recording_step_g(b) for a, b in zip(rates, rates[1:]))


@needs_xsens
def test_a_unit_is_never_re_read_from_the_spacing_alone(tmp_path):
    """The Xsens log with its time written in milliseconds under a name that does not say so: in seconds
    it is 0.1 Hz, and the evidence does not say ms, so it is refused naming --time-unit (before: read as
    ms, an assumption from the spacing)."""
    x = pd.read_csv(XSENS)
    f = pd.DataFrame({"time": x["t_s"] * 1e3, "ax": x["acc_x_counts"], "ay": x["acc_y_counts"], "az": x["acc_z_counts"]})
    f.to_csv(tmp_path / "ms.csv", index=False)
    with pytest.raises(InputError, match=r"not re-read from the spacing alone: pass --time-unit ms \(100 Hz\)"):
        load(tmp_path / "ms.csv")
    with pytest.raises(InputError, match="--time-unit ms"):  # a raw recording required: the same refusal
        load_recording(tmp_path / "ms.csv", required_by="the allan command")
    loaded = load_with_segmentation(tmp_path / "ms.csv", time_unit="ms")
    assert loaded.decisions.kind.value == "raw recording"
    assert loaded.decisions.rate.value == pytest.approx(100.0, rel=0.01)
    assert "given with --time-unit" in loaded.decisions.time_base.reason


def test_a_rate_in_the_header_settles_the_unit_of_the_time_column(tmp_path):
    """``Fs,100`` above a time column counting milliseconds: the stated rate and the stamps agree in ms."""
    n = 3000
    rng = np.random.default_rng(4)
    d = np.repeat(uniform_directions(6, rng=5), n // 6, axis=0)
    acc = d + 0.002 * rng.standard_normal((n, 3))
    lines = ["Fs,100", "time,ax,ay,az"] + [f"{10.0 * k:.1f},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f}" for k, a in enumerate(acc)]
    (tmp_path / "fs.csv").write_text("\n".join(lines) + "\n")
    loaded = load_with_segmentation(tmp_path / "fs.csv")
    assert loaded.decisions.rate.value == pytest.approx(100.0)
    assert "the header states 100 Hz" in loaded.decisions.time_base.reason and "in ms" in loaded.decisions.time_base.reason
    assert loaded.poses.n == 6


def test_a_regular_recording_is_still_a_recording(tmp_path):
    """A 100 Hz recording's rows differ by noise, far within what a recording can change."""
    rng = np.random.default_rng(2)
    n = 4000
    d = np.repeat(uniform_directions(8, rng=3), n // 8, axis=0)
    acc = d + 0.003 * rng.standard_normal((n, 3))
    pd.DataFrame({"t": np.arange(n) / 100.0, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(
        tmp_path / "rec.csv", index=False)
    loaded = load_with_segmentation(tmp_path / "rec.csv")
    assert loaded.decisions.kind.value == "raw recording" and "within the 47 %" in loaded.decisions.kind.reason
    assert not loaded.decisions.warnings


# 2 --------------------------------------------------------------------- the decisions on the error path
def test_a_refusal_after_decisions_carries_them(tmp_path):
    """The evidence refuses the time column: the columns and the layout, decided before, come with the error."""
    n = 400
    rng = np.random.default_rng(6)
    acc = np.repeat(uniform_directions(4, rng=7), n // 4, axis=0) + 0.002 * rng.standard_normal((n, 3))
    pd.DataFrame({"stamp": 10.0 * np.arange(n), "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(
        tmp_path / "ms.csv", index=False)
    with pytest.raises(InputError) as info:
        load(tmp_path / "ms.csv")
    made = getattr(info.value, "decisions", [])
    assert any(line.startswith("columns: t←stamp") for line in made)
    assert any(line.startswith("read: comma-separated") for line in made)


def test_the_command_line_prints_the_decisions_before_the_error(tmp_path, capsys):
    """A recording that never rests is read (kind, columns, units, time decided) and then refused by the
    segmentation: the decisions are printed (standard output, as on success), then the one-line error."""
    rng = np.random.default_rng(8)
    n = 3000
    t = np.arange(n) / 100.0
    angle = np.cumsum(rng.uniform(0.02, 0.05, n))  # always turning
    acc = np.column_stack([np.cos(angle), np.sin(angle) * np.cos(0.3 * angle), np.sin(angle) * np.sin(0.3 * angle)])
    acc += 0.002 * rng.standard_normal((n, 3))
    pd.DataFrame({"t": t, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2]}).to_csv(tmp_path / "turning.csv", index=False)
    code, out, err = run(["calibrate", tmp_path / "turning.csv"], capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1  # the one-line error, as before
    assert out.startswith(f"DATA: {tmp_path / 'turning.csv'} refused; the decisions made before:")  # as on success
    assert "kind: raw recording" in out and "units: g" in out and "time: stamps, 100 Hz" in out
    code, out, err = run(["calibrate", tmp_path / "turning.csv", "--json"], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1  # --json: nothing on standard output on an error


# 8 --------------------------------------------------------------------- one pass of evidence
def profile_calls(action: Callable[[], object], watch: set[str]) -> list[tuple[str, int, tuple[str, ...]]]:
    """Calls of the functions named in ``watch`` while ``action`` runs: (name, size of the first array
    argument or -1, names of the functions on the stack)."""
    calls: list[tuple[str, int, tuple[str, ...]]] = []
    stack: list[str] = []

    def profiler(frame, event, arg):  # noqa: ANN001 - sys.setprofile's signature
        if event == "call":
            name = frame.f_code.co_name
            if name in watch and "/optcal/" in frame.f_code.co_filename:
                first = next(iter(frame.f_locals.values()), None)
                size = int(np.size(first)) if isinstance(first, np.ndarray) else -1
                calls.append((name, size, tuple(stack)))
            stack.append(name)
        elif event == "return" and stack:
            stack.pop()

    sys.setprofile(profiler)
    try:
        action()
    finally:
        sys.setprofile(None)
    return calls


def unsigned_recording(path: Path) -> int:
    """A 16-bit unsigned-counts recording (mid-scale 32768, 4000 counts per g) with gyro, at 100 Hz."""
    rng = np.random.default_rng(11)
    n = 6000
    d = np.repeat(uniform_directions(10, rng=12), n // 10, axis=0)
    acc = np.round(32768 + 4000 * d + 3 * rng.standard_normal((n, 3)))
    gyro = np.round(32768 + 20 * rng.standard_normal((n, 3)))
    f = pd.DataFrame(np.column_stack([np.arange(n) / 100.0, acc, gyro]),
                     columns=["t_s", "acc_x_counts", "acc_y_counts", "acc_z_counts", "gx", "gy", "gz"])
    f.to_csv(path, index=False)
    return n


@pytest.mark.parametrize("how", ["load", "load_recording"])
def test_the_evidence_is_gathered_once_on_the_recording_path(tmp_path, how):
    """Every statistic of the whole recording before its segmentation (the median norm, the step, the time
    steps, the column medians and norm of the nominal conversion of counts) is taken once, by the
    evidence: neither the decisions nor the conversion take them again."""
    n = unsigned_recording(tmp_path / "counts.csv")
    if how == "load":
        def action() -> object:
            return load_with_segmentation(tmp_path / "counts.csv")
    else:
        def action() -> object:
            return load_recording(tmp_path / "counts.csv")
    calls = profile_calls(action, {"gather_evidence", "median", "column_medians", "detect_static"})
    assert Counter(name for name, _, _ in calls)["gather_evidence"] == 1
    before_segmentation = [c for c in calls if "detect_static" not in c[2] and c[0] != "detect_static"]
    whole = [(name, stack) for name, size, stack in before_segmentation
             if name in ("median", "column_medians") and size >= n - 1]
    outside = [stack[-3:] for name, stack in whole if "gather_evidence" not in stack]
    assert outside == [], f"statistics of the whole recording taken again outside the evidence: {outside}"
    assert len(whole) >= 4  # norm, step, time steps, and the mid-scale statistics of the counts


def module_entries(action: Callable[[], object]) -> list[str]:
    """The optcal/data modules entered, in order: calls of a module-level function from another module
    (methods of the data objects and the order statistics of data/quantiles.py left out)."""
    entries: list[str] = []

    def module(code) -> str | None:  # noqa: ANN001 - a code object
        return code.co_filename.split("/optcal/", 1)[1] if "/optcal/" in code.co_filename else None

    def profiler(frame, event, arg):  # noqa: ANN001 - sys.setprofile's signature
        code = frame.f_code
        name = module(code)
        if event != "call" or name is None or not name.startswith("data/") or name == "data/quantiles.py":
            return
        if "." in code.co_qualname.replace("<locals>.", "") or code.co_name.startswith("<"):
            return
        back = frame.f_back
        while back is not None and module(back.f_code) is None:
            back = back.f_back
        if back is None or module(back.f_code) != name:
            entries.append(f"{name[5:-3]}.{code.co_name}")

    sys.setprofile(profiler)
    try:
        action()
    finally:
        sys.setprofile(None)
    return entries


@pytest.mark.parametrize("how", ["load", "load_recording"])
def test_the_path_through_the_data_layer_visits_each_step_once(tmp_path, how):
    """read → evidence → decisions → conversion, each step's module entered once, in that order (before:
    the readers entered four times, the decisions twice, the evidence gathered by the conversion)."""
    unsigned_recording(tmp_path / "counts.csv")
    if how == "load":
        entries = module_entries(lambda: load_with_segmentation(tmp_path / "counts.csv"))
        entries = entries[: entries.index("static.detect_static")]
    else:
        entries = module_entries(lambda: load_recording(tmp_path / "counts.csv"))
    steps = [e.split(".")[0] for e in entries if e.split(".")[0] in ("readers", "evidence", "decisions", "recording")]
    assert steps == ["readers", "evidence", "decisions", "recording"], entries
