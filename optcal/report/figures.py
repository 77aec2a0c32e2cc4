"""Figures of the reports, drawn on :class:`matplotlib.figure.Figure` (no pyplot state).

Each ``*_figure`` function returns a Figure; :func:`embed` turns one into markup that needs no
file and no network: inline SVG, or a base64 PNG for dense traces.
"""

from __future__ import annotations

import base64
import io
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray


#: Width of every report figure, inches (it scales to the page width in the HTML).
WIDTH_IN: float = 7.0


@dataclass(frozen=True)
class EmbeddedFigure:
    """A figure ready for the page.

    Attributes
    ----------
    caption : str
        What it shows, in words.
    markup : str
        ``<svg ...>`` or ``<img src="data:image/png;base64,...">``.
    """

    caption: str
    markup: str


def _figure(height_in: float, **kwargs: Any) -> Any:
    from matplotlib.figure import Figure

    return Figure(figsize=(WIDTH_IN, height_in), layout="constrained", **kwargs)


def embed(fig: Any, caption: str, fmt: Literal["svg", "png"] = "svg") -> EmbeddedFigure:
    """Figure → markup: inline SVG (text as paths, so no font is needed) or a base64 PNG."""
    buf = io.BytesIO()
    if fmt == "svg":
        fig.savefig(buf, format="svg", metadata={"Date": None})
        text = buf.getvalue().decode("utf-8")
        markup = text[text.index("<svg"):]
        markup = markup.replace("<svg ", f'<svg role="img" aria-label="{caption.replace(chr(34), "")}" ', 1)
    else:
        fig.savefig(buf, format="png", dpi=110)
        data = base64.b64encode(buf.getvalue()).decode("ascii")
        markup = f'<img alt="{caption.replace(chr(34), "")}" src="data:image/png;base64,{data}">'
    return EmbeddedFigure(caption, markup)


def residual_figure(
    residuals_g: NDArray[np.float64],
    labels: list[str],
    noise_g: NDArray[np.float64] | None = None,
    flagged: list[int] | None = None,
    title: str = "Norm residual of each pose after calibration",
) -> Any:
    """Norm residual ``‖ā_k‖ − 1`` of each pose (mg) with its ±2σ noise band."""
    fig = _figure(2.8)
    ax = fig.add_subplot()
    k = np.arange(residuals_g.size)
    ax.axhline(0, color="0.6", lw=0.8)
    if noise_g is not None:
        ax.fill_between(k, -2e3 * noise_g, 2e3 * noise_g, step="mid", color="tab:green", alpha=0.2, lw=0,
                        label="±2σ of the pose noise")
    ax.plot(k, 1e3 * residuals_g, "o", ms=4, color="C0", label="residual")
    if flagged:
        ax.plot(np.asarray(flagged), 1e3 * residuals_g[flagged], "x", ms=9, mew=2, color="C3", label="outlier")
    step = max(1, int(np.ceil(len(labels) / 20)))
    ax.set_xticks(k[::step], [labels[i] for i in k[::step]], rotation=90, fontsize=7)
    ax.set_xlabel("pose")
    ax.set_ylabel("|a| − 1 g (mg)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, loc="best")
    return fig


def sphere_map_figure(directions: NDArray[np.float64], suggestions: NDArray[np.float64] | None = None) -> Any:
    """Orientation coverage: each pose's gravity direction on a Mollweide map of the sphere."""
    fig = _figure(3.4)
    ax = fig.add_subplot(projection="mollweide")
    lon = np.arctan2(directions[:, 1], directions[:, 0])
    lat = np.arcsin(np.clip(directions[:, 2], -1, 1))
    ax.plot(lon, lat, "o", ms=6, color="C0", alpha=0.8, label="pose")
    axes_dirs = np.vstack([np.eye(3), -np.eye(3)])
    for d, name in zip(axes_dirs, ["+x", "+y", "+z", "−x", "−y", "−z"]):
        ax.annotate(name, (np.arctan2(d[1], d[0]), np.arcsin(d[2])), fontsize=8, color="0.35", ha="center",
                    va="center", xytext=(0, 9), textcoords="offset points")
        ax.plot(np.arctan2(d[1], d[0]), np.arcsin(d[2]), "+", color="0.35", ms=6)
    if suggestions is not None and len(suggestions):
        ax.plot(np.arctan2(suggestions[:, 1], suggestions[:, 0]), np.arcsin(np.clip(suggestions[:, 2], -1, 1)), "*",
                ms=13, color="C1", label="suggested pose")
    ax.set_xticklabels([])
    ax.grid(True, lw=0.4)
    ax.set_title("Direction of gravity in sensor axes, one mark per pose", fontsize=10, pad=16)
    ax.legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.05, -0.12))
    return fig


def before_after_figure(labels: list[str], before_g: NDArray[np.float64], after_g: NDArray[np.float64],
                        noise_g: NDArray[np.float64] | None = None) -> Any:
    """|a| − 1 g of each pose before (nominal conversion) and after calibration, mg."""
    fig = _figure(3.0)
    ax = fig.add_subplot()
    k = np.arange(len(labels))
    ax.axhline(0, color="0.6", lw=0.8)
    if noise_g is not None:
        ax.fill_between(k, -2e3 * noise_g, 2e3 * noise_g, step="mid", color="tab:green", alpha=0.2, lw=0,
                        label="±2σ of the pose noise")
    ax.plot(k, 1e3 * before_g, "s", ms=4, color="0.55", label="before (nominal)")
    ax.plot(k, 1e3 * after_g, "o", ms=4, color="C0", label="after calibration")
    ax.set_yscale("symlog", linthresh=max(1e3 * float(np.median(np.abs(after_g))), 1e-3))
    step = max(1, int(np.ceil(len(labels) / 20)))
    ax.set_xticks(k[::step], [labels[i] for i in k[::step]], rotation=90, fontsize=7)
    ax.set_ylabel("|a| − 1 g (mg, symmetric log)")
    ax.set_title("Norm error of each pose before and after calibration", fontsize=10)
    ax.legend(fontsize=7)
    return fig
