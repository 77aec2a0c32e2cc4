"""Shared fixtures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optcal.core.model import lu2017_reference_model

#: ../shared beside the repository (real recordings and the papers); tests skip without it.
SHARED = Path(__file__).resolve().parents[1].parent / "shared"


@pytest.fixture
def lu_model():
    return lu2017_reference_model()


@pytest.fixture
def shared_data() -> Path:
    d = SHARED / "data"
    if not d.is_dir():
        pytest.skip("../shared/data is not present")
    return d


def rngs(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent generators for directions and noise (never share one stream)."""
    return np.random.default_rng([seed, 1]), np.random.default_rng([seed, 2])
