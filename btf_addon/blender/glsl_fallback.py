"""F12 without an OpenCL device: the progressive drawer (gl/drawer.py) on a headless moderngl
context of its own (no shadows). Not Blender's ``gpu`` module: the engine asks Blender for no
GPU context in ``render()`` (blender/engine.py), so an OpenCL render never needs OpenGL, and
a machine without a usable EGL gets this fallback's clear error instead of an abort. The
host's context, where one was current, is current again afterwards (gl/host_context.py)."""

from __future__ import annotations

from ..core.errors import BTFMaterialsError
from ..gl import host_context
from ..gl.converge import converge
from ..gl.drawer import ProgressiveDrawer, ViewAccumulation
from ..gl.moderngl_device import ModernGLDevice
from ..render.lighting import frame_lights
from ..render.settings import RenderSettings

BATCH = 16  # lights per pass: progress and cancel are checked between passes


def render_glsl(
    engine, exported, settings: RenderSettings, w: int, h: int, transparent: bool = False
):
    """The (h, w, 4) float32 Combined image, row 0 at the bottom (Blender's order), or None
    after reporting why there is none. ``transparent``: Film › Transparent, alpha 0 (premultiplied)
    where no surface was drawn."""
    with host_context.kept():
        return _render(engine, exported, settings, w, h, transparent)


def _render(engine, exported, settings, w, h, transparent):
    try:
        device = ModernGLDevice()
    except RuntimeError as exc:  # no usable EGL/OpenGL on this machine (what to install)
        engine.report({"ERROR"}, f"GLSL fallback: {exc}; nothing rendered")
        return None
    try:
        drawer = ProgressiveDrawer(device, exported)
    except BTFMaterialsError as exc:  # bad input or a shader that does not compile
        device.close()
        engine.report({"ERROR"}, str(exc))
        return None
    cam = exported.camera
    try:
        view = ViewAccumulation(drawer.device, w, h)
    except Exception as exc:  # a target the driver refuses (size, memory)
        drawer.release()
        device.close()
        engine.report({"ERROR"}, f"GLSL fallback: no {w}×{h} float buffers on the GPU ({exc})")
        return None
    try:
        view.set_lights(frame_lights(settings, exported, cam.world_from_camera[:3, 2]), BATCH)
        engine.update_stats("", f"BTF | {len(exported.meshes)} meshes, {view.state.total} lights")

        def progress(fraction: float) -> bool:
            engine.update_progress(fraction)
            return not engine.test_break()  # Esc: the lights drawn so far are the result

        drawn = converge(
            drawer,
            view,
            cam.clip_from_world(w / h),
            cam.shader_vector(),
            film=settings.film(),
            transparent=transparent,
            progress=progress,
        )
        return drawn.image  # row 0 at the bottom, as Blender's results
    finally:
        view.release()
        drawer.release()
        device.close()
