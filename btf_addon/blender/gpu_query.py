"""Evaluate BTFs at query lists with the same GLSL inside Blender (``gpu`` module, offscreen).

Background Blender needs its GPU context first: call inside ``RenderEngine.render()`` with
``bl_use_gpu_context`` or after one rendered frame (tests/blender_helpers.init_gpu_module).
"""

from __future__ import annotations

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from ..core.model import BTF, DelegatingBTF, Queries
from ..core.packed import pack
from ..gl.interface import QUERY_SHADER
from ..gl.query import query_textures
from .gpu_draw import shader, texture


class BlenderGPUEvaluator:
    """Valid queries → (M, 3) float64 values by the query shader in Blender's ``gpu`` module
    (offscreen); the BTF's packed tables stay uploaded between calls."""

    def __init__(self, btf: BTF):
        packed = pack(btf)
        self.shader = shader(QUERY_SHADER)
        self.int_tex = texture(packed.ints, "R32F")
        self.float_tex = texture(packed.floats, "R32F")
        self.batch = batch_for_shader(
            self.shader,
            "TRIS",
            {"pos": [(-1, -1), (1, -1), (-1, 1), (-1, 1), (1, -1), (1, 1)]},
        )

    def __call__(self, q: Queries) -> np.ndarray:
        n = len(q.uv)
        a, b, (w, h) = query_textures(q)
        tex_a = texture(a, "RGBA32F")
        tex_b = texture(b, "RGBA32F")
        offscreen = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
        try:
            with offscreen.bind():
                fb = gpu.state.active_framebuffer_get()
                fb.clear(color=(0.0, 0.0, 0.0, 0.0))
                # Every query fragment must be written, whatever state an earlier draw left
                # (Blender 4.2 leaves depth test LESS_EQUAL after a render: nothing drew).
                gpu.state.depth_test_set("NONE")
                gpu.state.blend_set("NONE")
                self.shader.bind()
                self.shader.uniform_sampler("btf_int_tables", self.int_tex)
                self.shader.uniform_sampler("btf_float_tables", self.float_tex)
                self.shader.uniform_sampler("query_a", tex_a)
                self.shader.uniform_sampler("query_b", tex_b)
                self.batch.draw(self.shader)
                pixels = fb.read_color(0, 0, w, h, 4, 0, "FLOAT")
            pixels.dimensions = w * h * 4
            out = np.array(pixels, dtype=np.float32).reshape(h * w, 4)
        finally:
            offscreen.free()
        return out[:n, :3].astype(np.float64)


def blender_gpu_btf(btf: BTF) -> DelegatingBTF:
    """``btf`` evaluated by the GLSL shaders in Blender's ``gpu`` module."""
    return DelegatingBTF(btf, BlenderGPUEvaluator(btf))
