"""Figures of a diagnosis, drawn on :class:`matplotlib.figure.Figure` (the user's backend is never touched)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import AXES

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from optcal.applications.diagnosis.gyro_diagnosis import GyroDiagnosis
    from optcal.applications.diagnosis.result import Diagnosis


def residual_figure(diag: "Diagnosis") -> "Figure":
    """Norm residuals against temperature, time (s from the start) and the force on each axis, before and after."""
    from matplotlib.figure import Figure

    poses = diag.poses
    xs: list[tuple[str, NDArray[np.float64]]] = []
    if poses.temp is not None:
        xs.append(("temperature (°C)", poses.temp))
    if poses.t is not None:  # seconds from the start (from each session's own start when several), never epoch
        several = diag.sessions is not None
        start = (np.zeros(poses.n) if several else np.full(poses.n, float(np.min(poses.t))))
        xs.append(("time from the session's start (s)" if several else "time from the start (s)", poses.t - start))
    for i, ax in enumerate(AXES):
        xs.append((f"force along {ax} (g)", diag.fitted_directions[:, i]))
    kept = diag.kept
    extended = diag.final.describe() != diag.baseline.describe()
    rows = [("paper's model", diag.baseline.residuals, "C0")]
    if extended:  # with nothing found, a second row would repeat the first under another name
        rows.append(("extended model", diag.final.residuals, "C2"))
    fig = Figure(figsize=(3.2 * len(xs), 3.4 * len(rows) + 0.4))
    axes = fig.subplots(len(rows), len(xs), sharey="row", squeeze=False)
    for col, (label, x) in enumerate(xs):
        for row, (name, r, colour) in enumerate(rows):
            a = axes[row][col]
            a.axhline(0, color="0.6", lw=0.8)
            a.plot(x[kept], 1e3 * r[kept], "o", ms=3, color=colour, label=f"pose ({name})")
            if (~kept).any():
                a.plot(x[~kept], 1e3 * r[~kept], "x", ms=6, color="C3", label="outlier pose (zero weight)")
            a.set_xlabel(label)
            if col == 0:
                a.set_ylabel(f"|a| − 1 g, {name} (mg)")
    handles, labels = [], []
    for a in axes[:, 0]:
        for h, lab in zip(*a.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    title = (f"What is left after calibration: the paper's model (top) and {diag.final.describe_plain()} (bottom)"
             if extended else "What is left after calibration with the paper's model (no extension was found)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout(rect=(0, 0.05 if extended else 0.09, 1, 0.97 if extended else 0.94))
    return fig


def simulation_figure(diag: "Diagnosis") -> "Figure | None":
    """The simulation check of the baseline: each statistic against its simulated band (``None`` if not run)."""
    from matplotlib.figure import Figure

    stats = diag.simulation.statistics
    names = [k for k, v in stats.items() if np.all(np.isfinite(v.band))]
    if not names:
        return None
    fig = Figure(figsize=(10, 0.34 * len(names) + 2.0), layout="constrained")
    a = fig.subplots()
    for k, name in enumerate(names):
        st = stats[name]
        lo, hi = st.band
        mid, half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-300)
        a.plot([-1, 1], [k, k], color="0.7", lw=6, solid_capstyle="butt",
               label="range of the simulations" if k == 0 else None)
        z = (st.measured - mid) / half
        colour = "C3" if st.outside else "C0"
        if abs(z) <= 4:
            a.plot(z, k, "o", color=colour)
        else:  # far outside: an arrow at the edge, with the measured value in band units
            a.plot(4 * np.sign(z), k, ">" if z > 0 else "<", color=colour, ms=8)
            a.annotate(f"{z:+.3g}", (4 * np.sign(z), k), xytext=(-6 if z > 0 else 6, 6), textcoords="offset points",
                       ha="right" if z > 0 else "left", fontsize=7, color=colour)
    a.plot([], [], "o", color="C0", label="measured: inside")
    a.plot([], [], "o", color="C3", label="measured: outside (the simulation gets this wrong)")
    a.plot([], [], ">", color="C3", label="measured: far outside (value written beside it)")
    a.set_yticks(range(len(names)))
    a.set_yticklabels([stats[n].meaning for n in names], fontsize=7)
    a.set_xlim(-4.4, 4.4)
    a.set_xlabel(f"measured value, scaled so that the simulated {diag.simulation.band * 100:g} % range is −1 to 1",
                 fontsize=8)
    a.set_title("Does data simulated from the calibrated model look like the measurements?", fontsize=9)
    fig.legend(fontsize=7, loc="outside lower center", ncol=2, frameon=False)
    return fig


def gyro_figure(gyro: "GyroDiagnosis") -> "Figure":
    """Each move's gravity-prediction angle under the paper's model and the final model against its noise band
    (:mod:`optcal.applications.diagnosis.gyro_diagnosis`)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 3.2), layout="constrained")
    a = fig.add_subplot()
    k = np.arange(1, gyro.angles_deg.size + 1)
    a.fill_between(k, 0.0, gyro.band_deg, step="mid", color="0.88",
                   label=(f"band of {gyro.band_runs} simulations" if gyro.band_runs else "noise band")
                   + " (family-wise over the moves)")
    a.plot(k, gyro.angles_deg, "o", color="tab:red", ms=4, label="paper's model")
    a.plot(k, gyro.final_angles_deg, "s", color="tab:blue", ms=3, label="final model")
    outside = gyro.outside
    a.plot(k[outside], gyro.angles_deg[outside], "o", mfc="none", mec="k", ms=8, label="outside the band")
    a.set_xlabel("move")
    a.set_ylabel("gravity prediction (°)")
    named = "; ".join(f.effect + (f"({','.join(f.axes)})" if f.axes else "") for f in gyro.findings) or "none named"
    a.set_title(f"Gyroscope: the moves' gravity prediction against its noise band ({named})", fontsize=9)
    fig.legend(fontsize=7, loc="outside lower center", ncol=4, frameon=False)
    return fig


def save_figures(diag: "Diagnosis", directory: str | Path, gyro: "GyroDiagnosis | None" = None) -> list[str]:
    """Write ``residuals.png``, ``simulation_check.png`` (and with ``gyro``, ``gyro_moves.png``) into ``directory``;
    returns the paths written."""
    out_dir = Path(directory)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    figures = [("residuals.png", residual_figure(diag)), ("simulation_check.png", simulation_figure(diag))]
    if gyro is not None:
        figures.append(("gyro_moves.png", gyro_figure(gyro)))
    for name, fig in figures:
        if fig is not None:
            path = out_dir / name
            from optcal.core.atomic import atomic_path

            with atomic_path(path) as tmp:  # whole or not at all
                fig.savefig(tmp, dpi=110)
            paths.append(str(path))
    return paths
