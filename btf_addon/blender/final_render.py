"""F12: the scene camera's image through the GLSL drawer in an offscreen buffer.

Until the OpenCL ray tracer lands (issue: final render through OpenCL), the final render is the
viewport's direct lighting from all N virtual lights at full resolution — no shadows, no
interreflection — with progress, cancel and warnings as a render should have.
"""

from __future__ import annotations

import gpu
import numpy as np

from ..core.errors import BTFError
from ..gl.interface import ShaderCompileError
from .export import export_scene
from .gpu_draw import SceneDrawer
from .lighting import frame_lights

BATCH = 16  # lights per pass: progress and cancel are checked between passes


def render(engine, depsgraph) -> None:
    scene = depsgraph.scene
    pct = scene.render.resolution_percentage / 100
    w = max(1, int(scene.render.resolution_x * pct))
    h = max(1, int(scene.render.resolution_y * pct))
    try:
        exported = export_scene(depsgraph, w, h)
        drawer = SceneDrawer(exported)
    except (BTFError, ShaderCompileError) as exc:
        engine.report({"ERROR"}, str(exc))
        return
    for message in exported.messages:
        engine.report({"WARNING"}, message)
    cam = exported.camera
    clip_from_world = cam.projection(w / h) @ np.linalg.inv(cam.world_from_camera)
    camera = [*cam.position, 1.0] if cam.perspective else [*cam.world_from_camera[:3, 2], 0.0]
    drawer.set_lights(frame_lights(scene.btf_render, exported, cam.world_from_camera[:3, 2]), BATCH)
    engine.update_stats("", f"BTF | {len(exported.meshes)} meshes, {drawer.state.total} lights")

    background = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    accumulation = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    output = gpu.types.GPUOffScreen(w, h, format="RGBA32F")
    try:
        with background.bind():
            drawer.draw_background(clip_from_world, (w, h))
        with accumulation.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            drawer.draw_surfaces(clip_from_world, camera, 0, 0, depth_only=True)
            while not drawer.state.converged:
                first, count = drawer.state.next_batch()
                drawer.draw_surfaces(clip_from_world, camera, first, count, depth_only=False)
                drawer.state.advance(count)
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
