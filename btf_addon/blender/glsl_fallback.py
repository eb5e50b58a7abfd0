"""F12 without an OpenCL device: the viewport's GLSL drawer into offscreen buffers (no
shadows), through Blender's ``gpu`` module (the engine has a GPU context in ``render()``)."""

from __future__ import annotations

import gpu
import numpy as np

from ..core.errors import BTFError
from ..gl.interface import ShaderCompileError
from ..render.lighting import frame_lights
from ..render.settings import RenderSettings
from .gpu_draw import SceneDrawer

BATCH = 16  # lights per pass: progress and cancel are checked between passes


def render_glsl(engine, exported, settings: RenderSettings, w: int, h: int) -> None:
    try:
        drawer = SceneDrawer(exported)
    except (BTFError, ShaderCompileError) as exc:
        engine.report({"ERROR"}, str(exc))
        return
    cam = exported.camera
    clip_from_world = cam.clip_from_world(w / h)
    camera = cam.shader_vector()
    drawer.set_lights(frame_lights(settings, exported, cam.world_from_camera[:3, 2]), BATCH)
    engine.update_stats("", f"BTF | {len(exported.meshes)} meshes, {drawer.state.total} lights")

    background = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    accumulation = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    output = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    try:
        drawer.restart(background, accumulation, clip_from_world, camera, (w, h))
        while drawer.add_batch(accumulation, clip_from_world, camera):
            engine.update_progress(drawer.state.done / drawer.state.total)
            if engine.test_break():
                break
        with output.bind():
            drawer.draw_resolve(accumulation.texture_color, background.texture_color)
            pixels = gpu.state.active_framebuffer_get().read_color(0, 0, w, h, 4, 0, "FLOAT")
        pixels.dimensions = w * h * 4
        rect = np.array(pixels, dtype=np.float32).reshape(w * h, 4)
    finally:
        for offscreen in (background, accumulation, output):
            offscreen.free()
    result = engine.begin_result(0, 0, w, h)
    result.layers[0].passes["Combined"].rect = rect
    engine.end_result(result)
