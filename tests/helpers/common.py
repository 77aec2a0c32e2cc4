"""Shared by many tests: where ../shared is, and independent random streams."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: ../shared beside the repository (real recordings and the papers); tests skip without it.
SHARED = Path(__file__).resolve().parents[2].parent / "shared"


def rngs(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent generators for directions and noise (never share one stream)."""
    return np.random.default_rng([seed, 1]), np.random.default_rng([seed, 2])
