"""The figure of ``optcal segment``: a raw recording with the static intervals its detector found."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from optcal.data.static import (FEW_STRETCHES, LOUD_STRETCHES, ODD_STRETCHES, SHORT_STRETCHES, SWEEPING_STRETCHES,
                                TURNING_STRETCHES, WOBBLE_STRETCHES)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from optcal.data.static import Segmentation

#: The still stretches the model rejected, by reason: a short label and a colour for each.
REJECTED = {
    SHORT_STRETCHES: ("shorter than the dwell", "0.6"),
    FEW_STRETCHES: ("too few independent samples", "tab:purple"),
    SWEEPING_STRETCHES: ("mean creeps", "tab:orange"),
    TURNING_STRETCHES: ("gyro turns", "tab:red"),
    WOBBLE_STRETCHES: ("wobbles", "tab:pink"),
    LOUD_STRETCHES: ("noisier than an accelerometer at rest", "tab:brown"),
    ODD_STRETCHES: ("far noisier than the rests", "tab:olive"),
}


def segmentation_figure(seg: Segmentation) -> Figure:
    """|a| (nominal g) with the intervals shaded (green) and the still stretches the model rejected marked by reason,
    and the rest model's step and gyro tests over their critical values.

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
    fig = Figure(figsize=(13, 7 if has_gyro else 5))
    axes = fig.subplots(3 if has_gyro else 2, 1, sharex=True)
    ax = axes[0]
    ax.plot(t, tr["norm_g"], lw=0.5, color="0.3")
    for iv in seg.intervals:
        for a in axes:
            a.axvspan(iv.t_start, iv.t_end, color="tab:green", alpha=0.15, lw=0)
    shown: set[str] = set()
    for t0, t1, reason in tr.get("rejected", []):
        label, colour = REJECTED.get(reason, (reason, "0.4"))
        ax.axvspan(t0, t1, ymin=0.0, ymax=0.08, color=colour, alpha=0.8, lw=0,
                   label=None if reason in shown else f"rejected: {label}")
        shown.add(reason)
    ax.axvspan(np.nan, np.nan, color="tab:green", alpha=0.15, lw=0, label="static interval")
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=7, borderaxespad=0.0)  # beside |a|, not on it
    ax.set_ylabel("|a| (nominal g)")
    ax.set_title(f"{seg.recording.path}: {len(seg.intervals)} static intervals")
    ax = axes[1]
    ax.semilogy(t, np.maximum(tr["step"], 1e-3), lw=0.5, label="step between block means / its critical value")
    ax.axhline(1.0, color="C0", ls="--", lw=0.8)
    ax.set_ylabel("step test")
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=7, borderaxespad=0.0)
    if has_gyro:
        ax = axes[2]
        ax.semilogy(t, np.maximum(tr["gyro"], 1e-3), lw=0.5, color="C2")
        ax.axhline(1.0, color="C2", ls="--", lw=0.8)
        ax.set_ylabel("gyro test (block mean rate off the bias)")
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    return fig
