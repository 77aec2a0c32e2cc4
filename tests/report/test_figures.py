"""Figures outside the diagnosis are drawn on their own matplotlib Figure: the user's backend and
pyplot's figures are left as they were, and no library module switches the backend."""

from pathlib import Path

import numpy as np

from optcal.report.segmentation_figure import segmentation_figure
from optcal.data import load_with_segmentation
from optcal.families.simulate.recording import synthesize_recording
from optcal.core.model import lu2017_reference_model
from optcal.families.simulate.poses import uniform_directions
from optcal.families.noise.allan import simulate_noise
from optcal.families.noise.analysis import allan_figure, analyse_static_log, plot_allan

LIBRARY = Path(__file__).resolve().parents[2] / "optcal"


def test_no_library_module_switches_the_backend_or_uses_pyplot():
    offenders = [
        f"{path.relative_to(LIBRARY.parent)}:{k + 1}"
        for path in sorted(LIBRARY.rglob("*.py"))
        for k, line in enumerate(path.read_text(encoding="utf-8").splitlines())
        if "matplotlib.use(" in line or "import matplotlib.pyplot" in line or "from matplotlib import pyplot" in line
    ]
    assert offenders == []


def test_figures_leave_the_backend_and_pyplot_alone(tmp_path):
    import matplotlib
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    backend = matplotlib.get_backend()
    open_figures = plt.get_fignums()

    rng = np.random.default_rng(3)
    log = np.column_stack([simulate_noise(20_000, 100.0, 3e-4, 5e-5, 0.0, rng) for _ in range(3)]) + [0, 0, 1]
    analysis = analyse_static_log(log, 100.0, "g")
    fig = allan_figure(analysis, title="test")
    assert isinstance(fig, Figure) and len(fig.axes) == 3
    assert all(ax.get_xscale() == "log" for ax in fig.axes)
    saved = plot_allan(analysis, tmp_path / "sub" / "allan.png")
    assert saved.stat().st_size > 10_000

    recording = synthesize_recording(lu2017_reference_model(), uniform_directions(8, rng=3), dwell_s=2.0,
                                     transition_s=1.0, sigma=0.002, rng=4)
    path = tmp_path / "r.csv"
    recording.frame.to_csv(path, index=False)
    seg = load_with_segmentation(path).segmentation
    fig = segmentation_figure(seg)
    assert isinstance(fig, Figure) and len(fig.axes) >= 2
    assert len(fig.axes[0].patches) >= len(seg.intervals)  # one shaded span per static interval

    assert matplotlib.get_backend() == backend
    assert plt.get_fignums() == open_figures
