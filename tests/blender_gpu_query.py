"""Evaluate BTFs at query lists with the same GLSL inside Blender (``gpu`` module, offscreen):
the check that Blender's own GPU pipeline decodes every codec as the standalone one does
(test_gpu_query.py, test_svd_blender.py). Test code: the product never evaluates queries
through Blender's ``gpu`` module, so this lives beside its tests, over the installed
extension's modules.

Background Blender needs its GPU context first: call after one rendered frame
(tests/blender_helpers.init_gpu_module).
"""

from __future__ import annotations

import gpu
import numpy as np
from blender_helpers import extension_submodule
from gpu_extras.batch import batch_for_shader

from btf_addon.core.model import BTF, Queries


def _ext(name: str):
    return extension_submodule(f"btf_addon.{name}")


class BlenderGPUEvaluator:
    """Valid queries → (M, 3) float64 values by the query shader in Blender's ``gpu`` module
    (offscreen); the BTF's packed tables stay uploaded between calls."""

    def __init__(self, btf: BTF):
        packed = _ext("core.codecs.packed").pack(btf)
        texture = _ext("blender.gpu_draw").texture
        self.shader = _ext("blender.gpu_draw").shader(_ext("gl.interface").QUERY_SHADER)
        self.int_tex = texture(packed.ints, "R32F")
        self.float_tex = texture(packed.floats, "R32F")
        self.batch = batch_for_shader(
            self.shader,
            "TRIS",
            {"pos": [(-1, -1), (1, -1), (-1, 1), (-1, 1), (1, -1), (1, 1)]},
        )

    def __call__(self, q: Queries) -> np.ndarray:
        n = len(q.uv)
        texture = _ext("blender.gpu_draw").texture
        a, b, (w, h) = _ext("gl.query").query_textures(q)
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


def blender_gpu_btf(btf: BTF):
    """``btf`` (the installed extension's class) evaluated by the GLSL shaders in Blender's
    ``gpu`` module, as the extension's own ``DelegatingBTF``."""
    return _ext("core.model").DelegatingBTF(btf, BlenderGPUEvaluator(btf))
