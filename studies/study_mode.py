"""Quick mode and output paths shared by the studies (the percent scripts and their paired notebooks).

``OPTCAL_STUDY_QUICK=1`` runs every study small (CI executes the notebooks so); the quick
run writes into ``studies/results/quick/`` (not kept), the full run into ``studies/results/``.
Import it as ``from study_mode import QUICK, RESULTS, FIGURES, size``: ``python studies/X.py``
puts ``studies/`` on the path, and a notebook runs with ``studies/`` as its working directory.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")

#: Whether the studies run in quick mode (``OPTCAL_STUDY_QUICK`` set to anything but ``0``).
QUICK: bool = os.environ.get("OPTCAL_STUDY_QUICK", "") not in ("", "0")
#: The ``studies/`` folder.
STUDIES: Path = Path(__file__).resolve().parent
#: Where tables go: ``studies/results`` (full) or ``studies/results/quick``.
RESULTS: Path = STUDIES / "results" / ("quick" if QUICK else "")
#: Where figures go.
FIGURES: Path = RESULTS / "figures"
FIGURES.mkdir(parents=True, exist_ok=True)


def size(full: T, quick: T) -> T:
    """``full`` normally, ``quick`` in quick mode (number of runs, seeds, simulations)."""
    return quick if QUICK else full


def show(path: Path) -> Path:
    """Show a saved figure inline when running as a notebook (a script just keeps the file); returns ``path``."""
    try:
        from IPython import get_ipython
        from IPython.display import Image, display
    except ImportError:
        return path
    if get_ipython() is not None:
        display(Image(filename=str(path)))
    return path


def wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson 95 % interval of the proportion k/n (scipy's; NaN when n = 0)."""
    if n == 0:
        return (float("nan"), float("nan"))
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)
