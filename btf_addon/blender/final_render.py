"""F12: the scene camera's image.

With OpenCL (the device chosen in the preferences, else the best one): the ray-traced final
render in the mode the render settings choose — Virtual Lights (exactly the viewport's N lights,
deterministic) or Sampled (path tracing, shown pass by pass) — with Blender's lights, shadow
rays where the scene can have shadows, and Combined, Depth, Normal and UV passes. Without a
usable OpenCL device the render says so and falls back to the GLSL drawer (no shadows) in an
offscreen buffer.
"""

from __future__ import annotations

import time

import numpy as np

from ..cl.context import OpenCLUnavailableError, create_context
from ..cl.programs import is_cached
from ..cl.renderer import KERNELS, CLRenderer
from ..core.errors import BTFError
from ..render.lighting import frame_lights
from ..render.settings import RenderSettings
from ..scene.analysis import analyse
from .addon import ADDON_PACKAGE
from .export import export_scene
from .glsl_fallback import render_glsl


def render(engine, depsgraph) -> None:
    scene = depsgraph.scene
    pct = scene.render.resolution_percentage / 100
    w = max(1, int(scene.render.resolution_x * pct))
    h = max(1, int(scene.render.resolution_y * pct))
    try:
        exported = export_scene(depsgraph, w, h)
    except BTFError as exc:
        engine.report({"ERROR"}, str(exc))
        return
    for message in exported.messages:
        engine.report({"WARNING"}, message)
    try:
        cl_context = create_context(preferred_device())
        features = analyse(exported)
        if not is_cached(cl_context.context, cl_context.device, KERNELS, features.defines()):
            engine.update_stats(
                "",
                f"BTF | compiling the render kernels for {cl_context.device_name} "
                "(first render with these scene features; cached afterwards)",
            )
        renderer = CLRenderer(exported, w, h, cl_context, features)
    except (OpenCLUnavailableError, RuntimeError, BTFError) as exc:
        engine.report(
            {"WARNING"},
            f"OpenCL unavailable ({exc}); rendering with the GLSL "
            "viewport path instead (no shadows)",
        )
        render_glsl(engine, exported, RenderSettings.from_properties(scene.btf_render), w, h)
        return
    cam = exported.camera
    settings = RenderSettings.from_properties(scene.btf_render)
    lights = frame_lights(settings, exported, cam.world_from_camera[:3, 2])
    sampled = settings.sampled
    lighting = (
        f"{settings.samples} samples, {settings.max_bounces} bounces"
        if sampled
        else f"{len(lights.pdf)} virtual lights"
    )
    stats = (
        f"BTF | OpenCL on {renderer.ctx.device_name} | {renderer.triangle_count} triangles, "
        f"{lighting}, {len(exported.lights)} Blender lights, "
        f"shadows {'on' if renderer.features.shadows else 'off (none possible)'}"
    )
    engine.update_stats("", stats)
    started = time.perf_counter()

    def progress(fraction: float) -> bool:
        engine.update_progress(fraction)
        engine.update_stats("", f"{stats} | {fraction:.0%}, {time.perf_counter() - started:.1f} s")
        return not engine.test_break()

    view_layer = depsgraph.view_layer
    for enabled, name, channels, chan_id in (
        (view_layer.use_pass_z, "Depth", 1, "Z"),
        (view_layer.use_pass_normal, "Normal", 3, "XYZ"),
        (view_layer.use_pass_uv, "UV", 3, "UVA"),
    ):
        if enabled:  # passes must exist before the result is created
            engine.add_pass(name, channels, chan_id, layer=view_layer.name)
    result = engine.begin_result(0, 0, w, h, layer=view_layer.name)
    layer = result.layers[0]

    def show(combined: np.ndarray) -> None:
        """Progressive display of the Sampled mode: the image after each pass."""
        layer.passes["Combined"].rect = np.ascontiguousarray(combined[::-1]).reshape(w * h, 4)
        engine.update_result(result)

    if sampled:
        # Depth, normal and UV come from the deterministic kernel with one light (cheap).
        passes = renderer.render_direct(lights.prefix(1))
        passes.combined = renderer.render_sampled(
            settings.samples,
            settings.seed,
            progress,
            max_bounces=settings.max_bounces,
            preview=show,
        )
    else:
        passes = renderer.render_direct(lights, progress)
    bottom_first = {  # Blender's render buffers start at the bottom row
        "Combined": passes.combined,
        "Depth": passes.depth[..., None],
        "Normal": passes.normal,
        "UV": np.concatenate([passes.uv, np.ones_like(passes.depth)[..., None]], axis=-1),
    }
    for name, image in bottom_first.items():
        render_pass = layer.passes.find_by_name(name, "")
        if render_pass is not None:
            render_pass.rect = np.ascontiguousarray(image[::-1]).reshape(w * h, -1)
    engine.end_result(result)


def preferred_device() -> int | None:
    """The device index from the add-on preferences, or None for automatic."""
    import bpy

    addon = bpy.context.preferences.addons.get(ADDON_PACKAGE)
    choice = getattr(getattr(addon, "preferences", None), "opencl_device", "AUTO")
    return int(choice[3:]) if choice.startswith("DEV") else None
