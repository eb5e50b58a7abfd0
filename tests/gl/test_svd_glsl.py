"""The svd codec's GLSL decode (shaders/btf_svd_lib.glsl) against the numpy reference."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import random_queries
from svd_cases import svd_cases


@pytest.mark.parametrize("case", ["yuv", "log-rgb", "rotated-rings"])
def test_glsl_svd_matches_numpy_within_1_255(gl_ctx, rng, case):
    """|GLSL − numpy| ≤ 1/255 of a white reflectance factor (value × π)."""
    from btf_addon.gl.query import glsl_btf

    btf = svd_cases()[case]
    q = random_queries(rng, 5_000)
    got = glsl_btf(btf, gl_ctx).evaluate_angles(q)
    want = btf.evaluate_angles(q)
    assert want.max() * np.pi > 0.05
    assert np.abs(got - want).max() * np.pi <= 1.0 / 255.0
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-5 * float(want.max()))
