"""An encoded material decodes the same in numpy, OpenCL (PoCL) and GLSL (moderngl/EGL):
the encoder writes nothing the device decoders read differently. 4×4 texels, small
codebooks: the encode takes ~1 s, each device comparison a few seconds (program build)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import random_queries

from btf_addon.core.encoders.mlvq import encode_mlvq


@pytest.fixture(scope="module")
def encoded():
    from core.test_encoder_mlvq import SMALL, synthetic

    return encode_mlvq(synthetic(), SMALL)[0]


@pytest.mark.opencl
def test_opencl_decodes_the_encoding_like_numpy(encoded, rng, cl_context):
    from btf_addon.cl.evaluate import device_btf

    device = device_btf(encoded, cl_context)
    q = random_queries(rng, 20_000)
    got, want = device.evaluate_angles(q), encoded.evaluate_angles(q)
    # The same bound as the shared materials' device test (tests/kernels): float32 device
    # maths against the float64 reference, 2e-4 of the peak absolute, 2e-3 relative.
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=2e-4 * float(want.max()))
    assert want.max() > 0


def test_glsl_decodes_the_encoding_like_numpy(encoded, gl_ctx, rng):
    from btf_addon.gl.query import glsl_btf

    q = random_queries(rng, 10_000)
    got, want = glsl_btf(encoded, gl_ctx).evaluate_angles(q), encoded.evaluate_angles(q)
    # One raw decoder unit (1/255 of the 8-bit scale), the bound of tests/gl for MLVQ.
    raw_error = np.abs(got - want) / encoded.meta.value_scale
    assert raw_error.max() <= 1.0, raw_error.max()
    assert want.max() / encoded.meta.value_scale > 10  # bright values were compared
