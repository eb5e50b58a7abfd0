"""The same GLSL inside Blender's gpu module (offscreen, background mode) against numpy."""

from __future__ import annotations

import numpy as np
from blender_helpers import extension_submodule, init_gpu_module
from helpers import random_queries, shared_material

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.mlvq import MLVQBTF


def test_blender_gpu_decode_matches_numpy(bpy_module, fresh_scene, rng):
    init_gpu_module(bpy_module)
    import blender_gpu_query as gpu_query

    # The extension's own core classes: its module path differs from the checkout's.
    mlvq = extension_submodule("btf_addon.core.codecs.mlvq")
    btf = mlvq.MLVQBTF.from_directory(shared_material("alu"))
    reference = MLVQBTF.from_directory(shared_material("alu"))
    n = 10_000
    q = random_queries(rng, n)
    got = gpu_query.blender_gpu_btf(btf).evaluate_angles(q)
    want = reference.evaluate_angles(q)
    raw_error = np.abs(got - want) / reference.meta.value_scale
    assert raw_error.max() <= 1.0, raw_error.max()  # one 8-bit step, as on moderngl
    assert want.max() > 0


def test_blender_gpu_ggx(bpy_module, fresh_scene, rng):
    init_gpu_module(bpy_module)
    import blender_gpu_query as gpu_query

    analytic = extension_submodule("btf_addon.core.codecs.analytic")
    n = 2_000
    q = random_queries(rng, n)
    got = gpu_query.blender_gpu_btf(analytic.GGXBTF(0.8, 0.5)).evaluate_angles(q)
    want = GGXBTF(0.8, 0.5).evaluate_angles(q)
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-5 * float(want.max()))


def test_blender_shaders_see_the_python_layout(bpy_module, fresh_scene, tmp_path):
    """The create-info path (GPUShaderCreateInfo.define) gives the layout macros exactly
    core/codecs/packed.py's numbers: a probe with the query shader's interface and libraries writes
    the i-th macro's value at pixel i (integers below 2^24: exact in the float target)."""
    import dataclasses

    import gpu
    from gpu_extras.batch import batch_for_shader

    init_gpu_module(bpy_module)
    interface = extension_submodule("btf_addon.gl.interface")
    layout = extension_submodule("btf_addon.core.codecs.packed").defines()
    names = list(layout)
    (tmp_path / "probe_frag.glsl").write_text(
        "void main()\n{\n"
        f"  int values[{len(names)}] = int[{len(names)}]({', '.join(names)});\n"
        "  frag_color = vec4(float(values[int(gl_FragCoord.x)]), 0.0, 0.0, 1.0);\n}\n"
    )
    probe = dataclasses.replace(
        interface.QUERY_SHADER, name="layout_probe", fragment_file=str(tmp_path / "probe_frag.glsl")
    )
    shader = gpu.shader.create_from_info(probe.blender_create_info())
    quad = [(-1, -1), (1, -1), (-1, 1), (-1, 1), (1, -1), (1, 1)]
    batch = batch_for_shader(shader, "TRIS", {"pos": quad})
    offscreen = gpu.types.GPUOffScreen(len(names), 1, format="RGBA32F")
    # Every declared sampler gets a texture although the probe reads none, and the state a
    # render left is reset: Blender 5.3 crashed (segfault) drawing this probe without both.
    dummy = gpu.types.GPUTexture((1, 1), format="RGBA32F")
    try:
        with offscreen.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(-1.0, 0.0, 0.0, 0.0))
            gpu.state.depth_test_set("NONE")
            gpu.state.blend_set("NONE")
            shader.bind()
            for _slot, _kind, name in probe.samplers:
                shader.uniform_sampler(name, dummy)
            batch.draw(shader)
            pixels = fb.read_color(0, 0, len(names), 1, 4, 0, "FLOAT")
        pixels.dimensions = len(names) * 4
        values = np.array(pixels, dtype=np.float32).reshape(-1, 4)[:, 0]
    finally:
        offscreen.free()
    assert dict(zip(names, values.astype(int).tolist(), strict=True)) == layout
