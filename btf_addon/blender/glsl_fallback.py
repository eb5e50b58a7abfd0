"""F12 without an OpenCL device: the progressive drawer (gl/drawer.py) through Blender's ``gpu``
module into offscreen buffers (no shadows); the engine has a GPU context in ``render()``."""

from __future__ import annotations

from ..core.errors import BTFError
from ..gl.drawer import ViewAccumulation
from ..gl.interface import ShaderCompileError
from ..render.lighting import frame_lights
from ..render.settings import RenderSettings
from .gpu_draw import scene_drawer

BATCH = 16  # lights per pass: progress and cancel are checked between passes


def render_glsl(
    engine, exported, settings: RenderSettings, w: int, h: int, transparent: bool = False
):
    """The (h, w, 4) float32 Combined image, row 0 at the bottom (Blender's order), or None
    after reporting why there is none. ``transparent``: Film › Transparent, alpha 0 (premultiplied)
    where no surface was drawn."""
    try:
        drawer = scene_drawer(exported)
    except (BTFError, ShaderCompileError) as exc:
        engine.report({"ERROR"}, str(exc))
        return None
    cam = exported.camera
    try:
        view = ViewAccumulation(drawer.device, w, h)
    except Exception as exc:  # Blender's GPUOffScreen raises a bare Exception (size, memory)
        drawer.release()
        engine.report({"ERROR"}, f"GLSL fallback: no {w}×{h} float buffers on the GPU ({exc})")
        return None
    try:
        view.set_lights(frame_lights(settings, exported, cam.world_from_camera[:3, 2]), BATCH)
        state = view.state
        engine.update_stats("", f"BTF | {len(exported.meshes)} meshes, {state.total} lights")
        view.jitter = settings.film()  # each pass at the film filter's next subpixel offset
        view.jitter_world = not transparent  # a transparent film keeps the World out of the sum
        drawer.restart(view, cam.clip_from_world(w / h), cam.shader_vector())
        while drawer.add_batch(view):
            engine.update_progress(state.done / state.total)
            if engine.test_break():
                break
        with drawer.device.bound(view.output):
            drawer.draw_resolved(view, transparent_background=transparent)
        return view.read().reshape(h, w, 4)  # row 0 at the bottom, as Blender's results
    finally:
        view.release()
        drawer.release()
