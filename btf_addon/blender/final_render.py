"""F12: the scene camera's image.

With OpenCL (the device chosen in the preferences, else the best one): the ray-traced final
render in the mode the render settings choose — Virtual Lights (exactly the viewport's N lights,
deterministic) or Sampled (path tracing, shown pass by pass) — with Blender's lights, shadow
rays where the scene can have shadows, and Combined, Depth, Normal and UV passes. Without a
usable OpenCL device the render says so and falls back to the GLSL drawer (no shadows) in an
offscreen buffer; a kernel that fails to compile is an error, never a fallback.

This is the one render path: the CLI's ``render --blend`` runs it through
``bpy.ops.render.render(write_still=True)`` as F12 and ``blender -b file.blend -f 1`` do.
"""

from __future__ import annotations

import time

import numpy as np

from ..cl.context import OpenCLUnavailableError, create_context
from ..cl.programs import OpenCLCompileError, is_cached
from ..cl.renderer import KERNELS, CLRenderer
from ..core.errors import BTFError
from ..render.lighting import frame_lights
from ..render.settings import RenderSettings
from ..scene.analysis import analyse
from .export import export_scene
from .glsl_fallback import render_glsl
from .preferences import preferred_device


def render(engine, depsgraph) -> None:
    scene = depsgraph.scene
    settings = RenderSettings.from_scene(scene)  # with the film filter of scene.cycles
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
        renderer = CLRenderer(exported, w, h, cl_context, features, film=settings.film())
    except OpenCLCompileError as exc:
        # A bug in kernels/ or a driver rejecting valid code: falling back would hide it
        # behind a different image, so the render fails and says where the compiler stopped.
        report_error(engine, compile_error_message(exc))
        return
    except (OpenCLUnavailableError, BTFError) as exc:
        engine.report(
            {"WARNING"},
            f"OpenCL unavailable ({exc}); rendering with the GLSL "
            "viewport path instead (no shadows)",
        )
        render_glsl(engine, exported, settings, w, h)
        return
    cam = exported.camera
    lights = frame_lights(settings, exported, cam.world_from_camera[:3, 2])
    sampled = settings.sampled
    lighting = (
        f"{settings.samples} samples, {settings.max_bounces} bounces"
        if sampled
        else f"{len(lights.pdf)} virtual lights"
    )
    film = settings.film()
    if film is not None:
        aa = "" if sampled else f" × {settings.aa_samples} subpixels"
        lighting += f", {film.type.replace('_', '-').title()} {film.width:g} px{aa}"
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
        passes = renderer.render_direct(lights, progress, aa_samples=settings.aa_samples)
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


#: Lines of the compiler's log quoted in the error: the first error and its context (the
#: whole log stays on the exception's ``build_log``).
LOG_LINES = 8


def compile_error_message(exc: OpenCLCompileError) -> str:
    """One report for a failed kernel compile: file, device and the log's first lines (they
    name the line and column in the compiled source)."""
    lines = [line for line in exc.build_log.strip().splitlines() if line.strip()]
    quoted = "\n".join(lines[:LOG_LINES])
    more = f"\n… {len(lines) - LOG_LINES} more lines" if len(lines) > LOG_LINES else ""
    return (
        f"OpenCL compile error in {exc.kernel} on {exc.device_name.strip()}; "
        f"nothing rendered:\n{quoted}{more}"
    )


def report_error(engine, message: str) -> None:
    """Fail the render with ``message``: ``error_set`` (Blender 4.x+) shows it after the
    render, ``report`` makes ``bpy.ops.render.render`` raise it headless."""
    if hasattr(engine, "error_set"):
        engine.error_set(message)
    engine.report({"ERROR"}, message)
