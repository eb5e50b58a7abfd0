"""The engine's viewport: progressive GLSL drawing, restarted by any change.

view_update records what the depsgraph says changed; view_draw re-exports the scene only when
something was (re-upload), restarts the accumulation when the view or scene changed, adds K
lights per redraw and asks for another redraw until all N are in.
"""

from __future__ import annotations

import gpu
import numpy as np
from gpu_extras.presets import draw_texture_2d

from ..core.errors import BTFMaterialsError
from ..core.mat4 import inverse
from ..gl.drawer import ProgressiveDrawer, ViewAccumulation
from ..render.lighting import frame_lights
from .export import ExportCache, changed_ids, export_scene
from .export.light_bake import remember_status
from .gpu_draw import BlenderGPUDevice
from .sync import render_settings


class ViewportState:
    """One 3D view of the engine: the scene's drawer (replaced, reusing uploads, when the scene
    changes) and the view's accumulation (replaced when the region is resized)."""

    def __init__(self):
        self.device = BlenderGPUDevice()
        self.drawer: ProgressiveDrawer | None = None
        self.view: ViewAccumulation | None = None
        self.cache = ExportCache()
        self.scene_dirty = True
        self.view_key: tuple | None = None
        self.error = ""

    def free_buffers(self) -> None:
        if self.view is not None:
            self.view.release()
        self.view = None


def _state(engine) -> ViewportState:
    if not hasattr(engine, "btf_viewport"):
        engine.btf_viewport = ViewportState()
    return engine.btf_viewport


def view_update(engine, context, depsgraph) -> None:
    """Record what changed: the next draw re-exports and re-uploads only that (ExportCache,
    ProgressiveDrawer(previous=...)); anything else (transforms, settings, added objects) is cheap
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
    settings = render_settings(scene)  # with the film filter (jitter per pass)
    size = (region.width, region.height)
    if state.scene_dirty or state.drawer is None:
        try:
            scene_data = export_scene(depsgraph, *size, cache=state.cache, viewport=True)
            state.drawer = ProgressiveDrawer(state.device, scene_data, previous=state.drawer)
            remember_status(scene, state.drawer)  # for the Light Bake panel
            state.error = ""
        except BTFMaterialsError as exc:  # bad input or a shader that does not compile
            state.drawer, state.error = None, str(exc)
            engine.report({"ERROR"}, state.error)
            return
        state.scene_dirty = False
        state.view_key = None  # new scene: new lights, restart below
    drawer = state.drawer
    clip_from_world = np.array(rv3d.perspective_matrix, dtype=np.float64)
    world_from_view = inverse(np.array(rv3d.view_matrix, dtype=np.float64))
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
        settings.film(),
    )
    if state.view is None or state.view.size != size:
        state.free_buffers()
        # Half floats are enough for display; the accumulation itself is 32-bit.
        state.view = ViewAccumulation(state.device, *size, output_format="RGBA16F")
    view = state.view
    if key != state.view_key:
        per_pass = settings.lights_per_redraw if settings.progressive else settings.lights_total
        view.set_lights(frame_lights(settings, drawer.scene, world_from_view[:3, 2]), per_pass)
        view.jitter = settings.film()  # subpixel offset per pass: anti-aliased once converged
        drawer.restart(view, clip_from_world, camera)
        state.view_key = key
    drawer.add_batch(view)
    drawer.resolve(view)
    gpu.state.blend_set("ALPHA_PREMULT")
    engine.bind_display_space_shader(scene)
    draw_texture_2d(state.device.target_texture(view.output), (0, 0), *size)
    engine.unbind_display_space_shader()
    gpu.state.blend_set("NONE")
    if not view.state.converged:
        engine.tag_redraw()
