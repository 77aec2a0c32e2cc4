"""Progress of a diagnosis (bars on every slow stage, none in captured output) and figures in plain words."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from helpers.diagnosis_cases import make_case, write_pose_table

from optcal.cli.main import main
from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings
from optcal.report.diagnosis_figures import residual_figure, simulation_figure
from optcal.applications.diagnosis.progress import Progress


def test_no_bar_text_when_stderr_is_not_a_terminal(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = write_pose_table(make_case("temperature_bias", 5, n_range=(40, 40)).poses, tmp_path / "p.csv")
    assert main(["diagnose", str(path), str(path), "--simulations", "5"]) == 0
    err = capsys.readouterr().err
    assert "... fitting the paper's model" in err and "... forward selection" in err  # stage messages instead
    assert "\r" not in err and "it/s" not in err and "%|" not in err  # no bar drawn into a file or a pipe
    assert main(["diagnose", str(path), "--simulations", "5", "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_every_slow_stage_has_a_bar(capsys: pytest.CaptureFixture) -> None:
    """With bars on (a terminal) and no delay, each stage draws its bar on stderr."""
    sessions = [make_case(None, seed, n_range=(30, 30)).poses for seed in (6, 7)]
    Diagnoser(DiagnosisSettings(simulations=3, folds=4), Progress(bars=True, delay=0.0)).run_sessions(sessions)
    captured = capsys.readouterr()
    assert captured.out == ""
    for stage in ("fitting the paper's model", "4-fold held-out error", "simulation check", "selection step 1",
                  "detection limits"):
        assert stage in captured.err, stage


def figure_texts(fig) -> list[str]:
    texts = [t.get_text() for t in fig.texts]
    for legend in fig.legends:
        texts += [t.get_text() for t in legend.get_texts()]
    for ax in fig.axes:
        texts += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        texts += [t.get_text() for t in ax.get_xticklabels() + ax.get_yticklabels()]
        texts += [t.get_text() for t in ax.texts]
    return [t for t in texts if t]


def test_figures_speak_plain_words_with_one_legend_and_seconds_from_the_start() -> None:
    case = make_case("temperature_bias", 8, n_range=(40, 40))
    poses = case.poses
    poses.t = poses.t + 1.7e9  # epoch stamps: the figure must still count seconds from the start
    diag = Diagnoser(DiagnosisSettings(simulations=10)).run(poses)
    assert diag.finding("temperature_bias") is not None
    for fig in (residual_figure(diag), simulation_figure(diag)):
        texts = figure_texts(fig)
        internal = [t for t in texts if re.search(r"[a-z]+_[a-z]+", t)]
        assert internal == [], internal  # no corr_temperature_bias_z, no temperature_bias(z)
        legends = len(fig.legends) + sum(ax.get_legend() is not None for ax in fig.axes)
        assert legends == 1
    fig = residual_figure(diag)
    time_axes = [ax for ax in fig.axes if ax.get_xlabel() == "time from the start (s)"]
    assert time_axes
    for ax in time_axes:
        x = np.concatenate([line.get_xdata() for line in ax.get_lines() if len(line.get_xdata()) > 2])
        assert x.min() >= 0 and x.max() <= np.ptp(poses.t) + 1e-6
    assert any("bias changing with temperature on" in t for t in figure_texts(fig))
