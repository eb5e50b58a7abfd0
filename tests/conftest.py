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


@pytest.fixture(scope="session")
def gl_ctx():
    """One headless OpenGL (EGL) context for the session's GLSL tests."""
    from btf_addon.gl.query import create_gl_context

    try:
        ctx = create_gl_context()
    except RuntimeError as exc:
        pytest.skip(f"no headless OpenGL here ({exc}); setup installs Mesa's EGL")
    yield ctx
    ctx.release()


@pytest.fixture(scope="session")
def cl_context():
    """An OpenCL context on the default device (best GPU, else CPU)."""
    from btf_addon.cl.context import OpenCLUnavailableError, create_context

    try:
        return create_context()
    except OpenCLUnavailableError as exc:
        pytest.skip(f"no OpenCL device ({exc}); setup installs PoCL")
