"""The same GLSL inside Blender's gpu module (offscreen, background mode) against numpy."""

from __future__ import annotations

import numpy as np
from blender_helpers import extension_submodule, init_gpu_module
from helpers import random_queries, shared_material

from btf_addon.core.analytic import GGXBTF
from btf_addon.core.mlvq import MLVQBTF


def test_blender_gpu_decode_matches_numpy(bpy_module, fresh_scene, rng):
    init_gpu_module(bpy_module)
    gpu_query = extension_submodule("btf_addon.blender.gpu_query")
    # The extension's own core classes: its module path differs from the checkout's.
    mlvq = extension_submodule("btf_addon.core.mlvq")
    btf = mlvq.MLVQBTF.from_directory(shared_material("alu"))
    reference = MLVQBTF.from_directory(shared_material("alu"))
    n = 10_000
    q = random_queries(rng, n)
    got = gpu_query.BlenderGPUBTF(btf).evaluate_angles(q)
    want = reference.evaluate_angles(q)
    raw_error = np.abs(got - want) / reference.meta.value_scale
    assert raw_error.max() <= 1.0, raw_error.max()  # one 8-bit step, as on moderngl
    assert want.max() > 0


def test_blender_gpu_ggx(bpy_module, fresh_scene, rng):
    init_gpu_module(bpy_module)
    gpu_query = extension_submodule("btf_addon.blender.gpu_query")
    analytic = extension_submodule("btf_addon.core.analytic")
    n = 2_000
    q = random_queries(rng, n)
    got = gpu_query.BlenderGPUBTF(analytic.GGXBTF(0.8, 0.5)).evaluate_angles(q)
    want = GGXBTF(0.8, 0.5).evaluate_angles(q)
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-5 * float(want.max()))
