"""Shared fixtures: seeded randomness and the real BTFbase materials."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import MATERIALS, shared_material

SEED = 20261122


@pytest.fixture
def rng() -> np.random.Generator:
    """The one source of randomness in tests: seeded, so every run draws the same numbers."""
    return np.random.default_rng(SEED)


@pytest.fixture(params=MATERIALS)
def material_dir(request) -> Path:
    return shared_material(request.param)
