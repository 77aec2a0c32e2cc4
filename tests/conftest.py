"""Fixtures shared by every test (plain helpers live in tests/helpers)."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers.common import SHARED
from optcal.core.model import LumpedModel, lu2017_reference_model


@pytest.fixture
def lu_model() -> LumpedModel:
    return lu2017_reference_model()


@pytest.fixture
def shared_data() -> Path:
    d = SHARED / "data"
    if not d.is_dir():
        pytest.skip("../shared/data is not present")
    return d
