"""The engine's viewport: progressive GLSL drawing, restarted by any change.

view_update records what the depsgraph says changed; view_draw re-exports the scene only when
something was (re-upload), restarts the accumulation when the view or scene changed, adds K
lights per redraw and asks for another redraw until all N are in.
"""

from __future__ import annotations

import gpu
import numpy as np
from gpu_extras.presets import draw_texture_2d

from ..core.errors import BTFError
from ..gl.interface import ShaderCompileError
from ..render.lighting import frame_lights
from ..render.settings import RenderSettings
from .export import ExportCache, changed_ids, export_scene
from .gpu_draw import SceneDrawer


class ViewportState:
    def __init__(self):
        self.drawer: SceneDrawer | None = None
        self.cache = ExportCache()
        self.scene_dirty = True
        self.view_key: tuple | None = None
        self.size: tuple[int, int] = (0, 0)
        self.background = self.accumulation = self.output = None
        self.error = ""

    def free_buffers(self) -> None:
        for offscreen in (self.background, self.accumulation, self.output):
            if offscreen is not None:
                offscreen.free()
        self.background = self.accumulation = self.output = None


def _state(engine) -> ViewportState:
    if not hasattr(engine, "btf_viewport"):
        engine.btf_viewport = ViewportState()
    return engine.btf_viewport


def view_update(engine, context, depsgraph) -> None:
    """Record what changed: the next draw re-exports and re-uploads only that (ExportCache,
    SceneDrawer(previous=...)); anything else (transforms, settings, added objects) is cheap
    and handled by the re-export, which also restarts the accumulation."""
    state = _state(engine)
    objects, materials, world = changed_ids(depsgraph)
    state.cache.invalidate(objects, materials, world)
    if any(True for _ in depsgraph.updates):
        state.scene_dirty = True


def view_draw(engine, context, depsgraph) -> None:
    state = _state(engine)
    region, rv3d = context.region, context.region_data
    scene = depsgraph.scene
    settings = RenderSettings.from_properties(scene.btf_render)
    size = (region.width, region.height)
    if state.scene_dirty or state.drawer is None:
        try:
            scene_data = export_scene(depsgraph, *size, cache=state.cache, viewport=True)
            state.drawer = SceneDrawer(scene_data, previous=state.drawer)
            state.error = ""
        except (BTFError, ShaderCompileError) as exc:
            state.drawer, state.error = None, str(exc)
            engine.report({"ERROR"}, state.error)
            return
        state.scene_dirty = False
        state.view_key = None  # new scene: new lights, restart below
    drawer = state.drawer
    clip_from_world = np.array(rv3d.perspective_matrix, dtype=np.float64)
    world_from_view = np.linalg.inv(np.array(rv3d.view_matrix, dtype=np.float64))
    if rv3d.is_perspective:
        camera = [*world_from_view[:3, 3], 1.0]
    else:
        camera = [*world_from_view[:3, 2], 0.0]
    key = (
        tuple(clip_from_world.round(9).ravel()),
        size,
        settings.lighting,
        settings.lights_total,
        settings.lights_per_redraw,
        settings.progressive,
        settings.seed,
    )
    if size != state.size:
        state.free_buffers()
        state.size = size
        state.background = gpu.types.GPUOffScreen(*size, format="RGBA32F")
        state.accumulation = gpu.types.GPUOffScreen(*size, format="RGBA32F")
        state.output = gpu.types.GPUOffScreen(*size, format="RGBA16F")
    if key != state.view_key:
        per_pass = settings.lights_per_redraw if settings.progressive else settings.lights_total
        drawer.set_lights(frame_lights(settings, drawer.scene, world_from_view[:3, 2]), per_pass)
        drawer.restart(state.background, state.accumulation, clip_from_world, camera, size)
        state.view_key = key
    drawer.add_batch(state.accumulation, clip_from_world, camera)
    with state.output.bind():
        drawer.draw_resolve(state.accumulation.texture_color, state.background.texture_color)
    gpu.state.blend_set("ALPHA_PREMULT")
    engine.bind_display_space_shader(scene)
    draw_texture_2d(state.output.texture_color, (0, 0), *size)
    engine.unbind_display_space_shader()
    gpu.state.blend_set("NONE")
    if not drawer.state.converged:
        engine.tag_redraw()
