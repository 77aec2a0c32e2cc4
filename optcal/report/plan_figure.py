"""The orientation sphere: planned (and given) gravity directions, drawn on a Figure.

Both hemispheres (z up and z down) are shown in the Lambert azimuthal equal-area projection,
so that equal areas of the sphere look equal and a uniform design looks uniform.  Axes: the
sensor's x to the right and y upward in both panels (the lower hemisphere seen through the
sphere from above).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    from optcal.applications.plan.candidates import Cap


def equal_area(directions: NDArray, hemisphere: int) -> NDArray[np.float64]:
    """Projection of unit directions onto the disc of their hemisphere (+1: z ≥ 0, −1: z < 0)."""
    d = np.asarray(directions, float).reshape(-1, 3)
    r = np.sqrt(np.clip(1.0 - hemisphere * d[:, 2], 0.0, None))
    horizontal = np.linalg.norm(d[:, :2], axis=1)
    scale = np.divide(r, horizontal, out=np.zeros_like(r), where=horizontal > 1e-12)
    return d[:, :2] * scale[:, None]


def sphere_figure(planned: ArrayLike, given: ArrayLike | None = None, candidates: ArrayLike | None = None,
                  cap: "Cap | None" = None, title: str = "") -> "Figure":
    """Figure of planned poses (numbered), given poses (crosses), candidates (dots) and a cap.

    Parameters
    ----------
    planned : array_like, shape (K, 3)
    given : array_like, shape (n, 3), optional
    candidates : array_like, shape (m, 3), optional
    cap : Cap, optional
        Its boundary is drawn.
    title : str
    """
    from matplotlib.figure import Figure

    planned = np.asarray(planned, float).reshape(-1, 3)
    given = np.zeros((0, 3)) if given is None else np.asarray(given, float).reshape(-1, 3)
    fig = Figure(figsize=(9.0, 4.8), layout="constrained")
    axes = fig.subplots(1, 2)
    boundary = cap.boundary(360) if cap is not None else None
    for ax, hemisphere, name in zip(axes, (1, -1), ("z up (upper hemisphere)", "z down (lower hemisphere)")):
        ax.add_patch(_circle())
        for label, pts, style in (("candidates", candidates, dict(s=2, c="0.8", marker=".")),
                                  ("given", given, dict(s=40, c="tab:gray", marker="x")),
                                  ("planned", planned, dict(s=60, c="tab:red", marker="o", edgecolors="k"))):
            if pts is None:
                continue
            pts = np.asarray(pts, float).reshape(-1, 3)
            side = pts[:, 2] >= 0 if hemisphere > 0 else pts[:, 2] < 0
            xy = equal_area(pts[side], hemisphere)
            ax.scatter(xy[:, 0], xy[:, 1], label=f"{label} ({int(side.sum())})", zorder=3, **style)
            if label == "planned":
                for k, (x, y) in zip(np.flatnonzero(side) + 1, xy):
                    ax.annotate(str(k), (x, y), xytext=(5, 5), textcoords="offset points", fontsize=8)
        if cap is not None and boundary is not None:
            side = boundary[:, 2] >= 0 if hemisphere > 0 else boundary[:, 2] < 0
            xy = np.where(side[:, None], equal_area(boundary, hemisphere), np.nan)
            ax.plot(xy[:, 0], xy[:, 1], "b--", lw=1, label=f"cap ({cap.describe()})")
        for vec, text in (((1, 0), "+x"), ((-1, 0), "−x"), ((0, 1), "+y"), ((0, -1), "−y")):
            ax.annotate(text, (1.08 * vec[0], 1.08 * vec[1]), ha="center", va="center", fontsize=9)
        ax.annotate("+z" if hemisphere > 0 else "−z", (0, 0), xytext=(-12, -12), textcoords="offset points", fontsize=9)
        ax.set_title(name, fontsize=10)
        ax.set_xlim(-1.2, 1.2)
        ax.set_ylim(-1.2, 1.2)
        ax.set_aspect("equal")
        ax.axis("off")
        ax.legend(loc="lower left", fontsize=7, frameon=False, bbox_to_anchor=(-0.05, -0.12))
    fig.suptitle(title or "gravity directions in the sensor frame (equal-area projection)", fontsize=11)
    return fig


def _circle() -> "Circle":
    from matplotlib.patches import Circle

    return Circle((0, 0), 1.0, fill=False, color="k", lw=1)


__all__ = ["equal_area", "sphere_figure"]
