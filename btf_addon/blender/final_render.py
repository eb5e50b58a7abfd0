"""F12: the scene camera's image.

With OpenCL (the device chosen in the preferences, else the best one): the ray-traced final
render in the mode the render settings choose — Virtual Lights (exactly the viewport's N lights,
deterministic) or Sampled (path tracing, shown pass by pass) — with Blender's lights, shadow
rays where the scene can have shadows, and Combined, Depth, Normal and UV passes, for every
view Blender asks for (Output › Stereoscopy: each eye from its own camera, as Blender places
it). Without a
usable OpenCL device the render says so and falls back to the GLSL drawer (no shadows) in an
offscreen buffer; a kernel that fails to compile is an error, never a fallback.

This is the one render path: the CLI's ``render --blend`` runs it through
``bpy.ops.render.render(write_still=True)`` as F12 and ``blender -b file.blend -f 1`` do.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import bpy
import numpy as np

from ..cl import warm
from ..cl.context import OpenCLUnavailableError, create_context
from ..cl.frame import render_frame
from ..cl.programs import OpenCLCompileError, is_cached
from ..cl.renderer import KERNELS, CLRenderer, program_defines
from ..core.errors import BTFError
from ..render.lighting import frame_lights
from ..scene.analysis import analyse
from ..scene.scene import Camera
from .export import export_scene
from .export.camera import export_camera
from .glsl_fallback import render_glsl
from .paths import missing_message, missing_sources, with_error_colour
from .preferences import MISSING_FAIL, missing_source_behaviour, opencl_help, preferred_device
from .sync import frame_size, render_settings

#: What the last F12 rendered on, for the render panel: "OpenCL on <device>" or the fallback.
last_device = ""


class Region(NamedTuple):
    """The pixels Blender's render result holds: the Render Region (Ctrl+B) of a w × h frame,
    or the whole frame. x, y: offset of its bottom-left pixel from the frame's, in pixels."""

    x: int
    y: int
    w: int
    h: int

    def crop(self, bottom_first: np.ndarray) -> np.ndarray:
        """The region of a (frame h, frame w, …) image whose row 0 is the bottom row."""
        return bottom_first[self.y : self.y + self.h, self.x : self.x + self.w]


def render_region(render, w: int, h: int) -> Region:
    """The part of the w × h frame Blender's result covers: with Render Region on, Blender sizes
    the result to the region, whose corners it computes as float(border) · int(size) truncated
    to int (render_pipeline's disprect), which float32 reproduces here."""
    if not render.use_border:
        return Region(0, 0, w, h)
    f32 = np.float32
    x0, x1 = (int(f32(v) * f32(w)) for v in (render.border_min_x, render.border_max_x))
    y0, y1 = (int(f32(v) * f32(h)) for v in (render.border_min_y, render.border_max_y))
    x0, y0 = min(max(x0, 0), w - 1), min(max(y0, 0), h - 1)
    return Region(x0, y0, max(1, min(x1, w) - x0), max(1, min(y1, h) - y0))


def render(engine, depsgraph) -> None:
    global last_device
    warm.query_platforms()  # OpenCL's platforms open while the scene exports (cl/warm.py)
    scene = depsgraph.scene
    settings = render_settings(scene)  # with the film filter of scene.cycles
    w, h = frame_size(scene.render)
    region = render_region(scene.render, w, h)
    transparent = scene.render.film_transparent
    try:
        exported = export_scene(depsgraph, w, h, light_bake=False)
    except BTFError as exc:
        engine.report({"ERROR"}, str(exc))
        return
    missing = missing_sources(exported)
    if missing and missing_source_behaviour() == MISSING_FAIL:
        # A farm must not deliver a plausible wrong frame: fail, naming every missing source.
        report_error(engine, missing_message(missing))
        return
    exported = with_error_colour(exported, missing)
    for message in exported.messages:
        engine.report({"WARNING"}, message)
    try:
        cl_context = create_context(preferred_device())
        features = analyse(exported)
        defines = program_defines(features)
        if not is_cached(cl_context.context, cl_context.device, KERNELS, defines):
            engine.update_stats(
                "",
                f"BTF | compiling the render kernels for {cl_context.device_name} "
                "(first render with these scene features; cached afterwards)",
            )
        for skipped, why in cl_context.skipped:  # the user's device, or a better one, cannot build
            engine.report({"WARNING"}, f"OpenCL device {skipped.label} skipped: {why}")
        renderer = CLRenderer(
            exported,
            w,
            h,
            cl_context,
            features,
            film=settings.film(),
            importance_tables=settings.sampled and settings.btf_importance_sampling,
        )
        for note in renderer.notes:
            engine.report({"WARNING"}, note)
    except OpenCLCompileError as exc:
        # A bug in kernels/ or a driver rejecting valid code: falling back would hide it
        # behind a different image, so the render fails and says where the compiler stopped.
        report_error(engine, compile_error_message(exc))
        return
    except (OpenCLUnavailableError, BTFError) as exc:
        # The exception's own advice is for a shell: say it in Blender's words.
        if isinstance(exc, OpenCLUnavailableError):
            why = f"OpenCL unavailable ({exc.reason})"
            advice = " ".join(opencl_help().splitlines())
        else:  # OpenCL is there; this scene's data is what it cannot take
            why, advice = f"The OpenCL final render cannot take this scene ({exc})", ""
        engine.report({"WARNING"}, fallback_warning(why, advice))
        last_device = "GLSL fallback (no OpenCL device that builds)"
        for view in view_names(engine):
            exported.camera = view_camera(engine, depsgraph, w, h, view)
            combined = render_glsl(engine, exported, settings, w, h, transparent)
            if combined is None:  # it failed and reported why
                return
            write_result(engine, depsgraph.view_layer, region, {"Combined": combined}, view)
        return
    last_device = f"OpenCL on {renderer.ctx.device_name}"
    views = view_names(engine)
    for i, view in enumerate(views):
        renderer.scene.camera = view_camera(engine, depsgraph, w, h, view)
        if not _render_view(engine, depsgraph, renderer, settings, region, transparent, view,
                            (i, len(views))):  # fmt: skip
            return  # Esc: the views drawn so far stay


def fallback_warning(why: str, advice: str) -> str:
    """F12's one warning when it draws with the GLSL path (quoted in the user guide)."""
    return (
        f"{why}; rendering with the GLSL viewport path instead (no shadows); no "
        f"Depth/Normal/UV passes. {advice}".rstrip()
    )


def view_names(engine) -> list[str]:
    """The views Blender asks for: "" without Stereoscopy, else each view of Output ›
    Stereoscopy (left/right, or every view of Multi-View), in the result's order."""
    return [view.name for view in engine.get_result().views] or [""]


def view_camera(engine, depsgraph, w: int, h: int, view: str) -> Camera:
    """The camera of one view: Blender moves and shifts each eye of a stereo camera by its
    Stereoscopy settings (convergence mode, interocular distance, pivot); ask it, as Cycles
    does, rather than repeat its rules here."""
    scene = depsgraph.scene
    if not view:
        return export_camera(scene, w, h, depsgraph=depsgraph)
    engine.active_view_set(view)
    camera = scene.camera.evaluated_get(depsgraph)
    spherical = engine.use_spherical_stereo(camera)
    matrix = np.array(engine.camera_model_matrix(camera, use_spherical_stereo=spherical))
    shift_x = engine.camera_shift_x(camera, use_spherical_stereo=spherical)
    return export_camera(scene, w, h, view=(matrix, shift_x))


def _render_view(engine, depsgraph, renderer, settings, region, transparent, view, index) -> bool:
    """One view's passes into its result; False when the user stopped the render."""
    exported = renderer.scene
    cam = exported.camera
    sampled = settings.sampled
    # The Sampled mode draws from the World itself: no virtual lights (cl/frame.py).
    lights = None if sampled else frame_lights(settings, exported, cam.world_from_camera[:3, 2])
    lighting = (
        f"{settings.samples} samples, {settings.max_bounces} bounces"
        if sampled
        else f"{len(lights.pdf)} virtual lights"
    )
    film = settings.film()
    if film is not None:
        aa = "" if sampled else f" × {settings.aa_samples} subpixels"
        lighting += f", {film.type.replace('_', '-').title()} {film.width:g} px{aa}"
    which = f" | {view} view" if view else ""
    stats = (
        f"BTF | OpenCL on {renderer.ctx.device_name}{which} | {renderer.triangle_count} "
        f"triangles, {lighting}, {len(exported.lights)} Blender lights, "
        f"shadows {'on' if renderer.features.shadows else 'off (none possible)'}"
    )
    engine.update_stats("", stats)
    started = time.perf_counter()
    done, count = index
    stopped = False

    def progress(fraction: float) -> bool:
        nonlocal stopped
        engine.update_progress((done + fraction) / count)
        engine.update_stats("", f"{stats} | {fraction:.0%}, {time.perf_counter() - started:.1f} s")
        stopped = stopped or engine.test_break()
        return not stopped

    view_layer = depsgraph.view_layer
    for enabled, name, channels, chan_id in (
        (view_layer.use_pass_z, "Depth", 1, "Z"),
        (view_layer.use_pass_normal, "Normal", 3, "XYZ"),
        (view_layer.use_pass_uv, "UV", 3, "UVA"),
    ):
        if enabled and done == 0:  # passes must exist before the first result is created
            engine.add_pass(name, channels, chan_id, layer=view_layer.name)
    result = engine.begin_result(0, 0, region.w, region.h, layer=view_layer.name, view=view)
    layer = result.layers[0]
    check_result_size(layer, region)

    def show(combined: np.ndarray) -> None:
        """Progressive display of the Sampled mode: the image after each pass."""
        set_pass(layer.passes["Combined"], region, combined[::-1])
        engine.update_result(result)

    # Without a display (background Blender: farms, the command line) nothing shows a preview,
    # and each is a copy of the image into Blender: none is made (Cycles' headless rule).
    preview = None if bpy.app.background else show
    passes = render_frame(renderer, settings, lights, progress, preview, transparent)
    top_first = {
        "Combined": passes.combined,  # Film › Transparent: alpha is the kernels' coverage
        "Depth": passes.depth[..., None],
        "Normal": passes.normal,
        "UV": np.concatenate([passes.uv, np.ones_like(passes.depth)[..., None]], axis=-1),
    }
    # Blender's buffers: bottom row first.
    set_passes(layer, region, {name: image[::-1] for name, image in top_first.items()})
    engine.end_result(result)
    return not stopped


def check_result_size(layer, region: Region) -> None:
    """Blender's result must hold exactly the region's pixels; a mismatch is a bug here, said
    plainly instead of a failed array assignment after the whole render."""
    pixels = len(layer.passes["Combined"].rect)
    if pixels != region.w * region.h:
        raise RuntimeError(
            f"render result holds {pixels} pixels, expected {region.w}×{region.h} "
            f"(region at {region.x}, {region.y})"
        )


def set_pass(render_pass, region: Region, bottom_first: np.ndarray) -> None:
    """Write the region of a whole-frame image (row 0 at the bottom) into ``render_pass``."""
    pixels = region.crop(bottom_first)
    render_pass.rect = np.ascontiguousarray(pixels).reshape(region.w * region.h, -1)


def write_result(engine, view_layer, region: Region, bottom_first: dict, view: str = "") -> None:
    """One result (of ``view``) with the given whole-frame passes (row 0 at the bottom)."""
    result = engine.begin_result(0, 0, region.w, region.h, layer=view_layer.name, view=view)
    layer = result.layers[0]
    check_result_size(layer, region)
    set_passes(layer, region, bottom_first)
    engine.end_result(result)


def set_passes(layer, region: Region, bottom_first: dict) -> None:
    """Each whole-frame image (row 0 at the bottom) into the layer's pass of its name, where
    the layer has one (passes the view layer turned off are skipped)."""
    for name, image in bottom_first.items():
        render_pass = layer.passes.find_by_name(name, "")
        if render_pass is not None:
            set_pass(render_pass, region, image)


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
