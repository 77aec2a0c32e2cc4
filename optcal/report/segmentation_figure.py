"""The figure of ``optcal segment``: a raw recording with the static intervals its detector found."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from optcal.data.static import Segmentation


def segmentation_figure(seg: Segmentation) -> Figure:
    """|a| (nominal g) with the intervals shaded, and the rest model's step and gyro tests over their critical values.

    Drawn on a :class:`matplotlib.figure.Figure` of its own (no pyplot state, the backend untouched).

    Parameters
    ----------
    seg : Segmentation
        The static detection of a recording (:func:`optcal.data.static.detect_static`), with its trace.

    Returns
    -------
    Figure
    """
    from matplotlib.figure import Figure

    tr = seg.trace
    t = tr["t"]
    has_gyro = "gyro" in tr
    fig = Figure(figsize=(11, 7 if has_gyro else 5))
    axes = fig.subplots(3 if has_gyro else 2, 1, sharex=True)
    ax = axes[0]
    ax.plot(t, tr["norm_g"], lw=0.5, color="0.3")
    for iv in seg.intervals:
        for a in axes:
            a.axvspan(iv.t_start, iv.t_end, color="tab:green", alpha=0.15, lw=0)
    ax.set_ylabel("|a| (nominal g)")
    ax.set_title(f"{seg.recording.path}: {len(seg.intervals)} static intervals")
    ax = axes[1]
    ax.semilogy(t, np.maximum(tr["step"], 1e-3), lw=0.5, label="step between block means / its critical value")
    ax.axhline(1.0, color="C0", ls="--", lw=0.8)
    ax.set_ylabel("step test")
    ax.legend(loc="upper right", fontsize=8)
    if has_gyro:
        ax = axes[2]
        ax.semilogy(t, np.maximum(tr["gyro"], 1e-3), lw=0.5, color="C2")
        ax.axhline(1.0, color="C2", ls="--", lw=0.8)
        ax.set_ylabel("gyro test (block mean rate off the bias)")
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    return fig
