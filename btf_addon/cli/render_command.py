"""``render``: a .blend or the demo scene, rendered headless through the add-on's renderer."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from ..core.errors import BTFError
from ..core.imageio import srgb8_from_linear, write_exr, write_png
from .btf_commands import add_device_argument


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render a .blend or the demo scene headless")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--blend", type=Path, help="the .blend file to render (its active scene)")
    source.add_argument("--demo", action="store_true", help="the demo scene (no file needed)")
    p.add_argument("-o", "--output", required=True, type=Path, help=".png or .exr")
    p.add_argument(
        "--engine",
        choices=["opencl", "glsl"],
        default="opencl",
        help="opencl: the final render (ray traced, shadows); glsl: the viewport's renderer "
        "(no shadows); both light with the same virtual lights",
    )
    add_device_argument(p)
    p.add_argument(
        "--resolution",
        default=None,
        metavar="WxH",
        help="override the scene's resolution, e.g. 800x600",
    )
    p.add_argument(
        "--lighting",
        default="virtual:256",
        metavar="virtual:N|envmap",
        help="virtual:N — N importance-sampled virtual lights (deterministic, default 256); "
        "envmap — the World sampled continuously with MIS, --samples per pixel (opencl only)",
    )
    p.add_argument(
        "--samples",
        type=int,
        default=None,
        help="envmap lighting: samples per pixel (default 64); glsl engine: lights per "
        "accumulation pass (default: all)",
    )
    p.add_argument(
        "--bounces", type=int, default=4, help="envmap lighting: indirect reflections (default 4)"
    )
    p.set_defaults(func=cmd_render)


def _parse_resolution(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise BTFError(f"--resolution must look like 800x600, got {text!r}") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise BTFError(f"--resolution {w}x{h} is outside 1…16384")
    return w, h


def _parse_lighting(text: str) -> int | None:
    """N for virtual:N, None for envmap (continuous sampling)."""
    if text == "envmap":
        return None
    kind, _, count = text.partition(":")
    if kind != "virtual" or not count.isdigit() or int(count) < 1:
        raise BTFError(f"--lighting must be virtual:N with N ≥ 1 or envmap, got {text!r}")
    return int(count)


def cmd_render(args) -> int:
    suffix = args.output.suffix.lower()
    if suffix not in (".png", ".exr"):
        raise BTFError(f"{args.output}: output must end in .png or .exr")
    resolution = _parse_resolution(args.resolution)
    n_lights = _parse_lighting(args.lighting)
    if args.blend is not None and not args.blend.is_file():
        raise BTFError(f"{args.blend}: no such .blend file")
    t0 = time.perf_counter()
    try:
        import bpy
    except ImportError:
        raise BTFError("rendering needs Blender's bpy module (pip install bpy==5.0.1)") from None
    from .. import blender
    from ..blender.demo import build_demo_scene
    from ..blender.export import export_scene

    registered = hasattr(bpy.types.Material, "btf")
    if not registered:  # no installed copy enabled in this Blender: register this one
        blender.register()
    try:
        if args.demo:
            scene = build_demo_scene(args.output.parent / "demo_data")
        else:
            bpy.ops.wm.open_mainfile(filepath=str(args.blend.resolve()))
            scene = bpy.context.scene
        if resolution:
            scene.render.resolution_x, scene.render.resolution_y = resolution
            scene.render.resolution_percentage = 100
        pct = scene.render.resolution_percentage / 100
        width = max(1, int(scene.render.resolution_x * pct))
        height = max(1, int(scene.render.resolution_y * pct))
        depsgraph = bpy.context.evaluated_depsgraph_get()
        render_scene = export_scene(depsgraph, width, height)
    finally:
        if not registered:
            blender.unregister()
    for message in render_scene.messages:
        print(f"warning: {message}", file=sys.stderr)
    t_export = time.perf_counter()
    if n_lights is None and args.engine == "glsl":
        raise BTFError(
            "--lighting envmap needs the opencl engine (the viewport uses virtual lights)"
        )
    lights = render_scene.environment.virtual_lights(n_lights or 1)
    image = _render(args, render_scene, width, height, lights)
    t_render = time.perf_counter()
    if suffix == ".exr":
        write_exr(args.output, image)
    else:
        write_png(args.output, srgb8_from_linear(image))
    print(
        f"rendered {width}x{height} with {_lighting_label(args, n_lights)}: scene export "
        f"{t_export - t0:.2f} s, {args.engine} render {t_render - t_export:.2f} s -> {args.output}"
    )
    if not np.all(np.isfinite(image)):
        raise BTFError("the render produced non-finite pixels")
    return 0


def _render(args, scene, width: int, height: int, lights) -> np.ndarray:
    if args.engine == "glsl":
        from ..gl.renderer import GLSLRenderer

        try:
            renderer = GLSLRenderer(scene, width, height)
        except RuntimeError as exc:
            raise BTFError(f"the GLSL renderer is unavailable: {exc}") from None
        return renderer.render(lights, per_pass=args.samples)
    from ..cl.context import OpenCLUnavailableError, create_context
    from ..cl.renderer import CLRenderer

    try:
        renderer = CLRenderer(scene, width, height, create_context(args.device))
    except (OpenCLUnavailableError, RuntimeError) as exc:
        raise BTFError(f"OpenCL final render unavailable ({exc}); try --engine glsl") from None
    if args.lighting == "envmap":
        return renderer.render_sampled(args.samples or 64, seed=0, max_bounces=args.bounces)[
            ..., :3
        ]
    return renderer.render_direct(lights).combined[..., :3]


def _lighting_label(args, n_lights: int | None) -> str:
    if n_lights is None:
        return f"the environment sampled, {args.samples or 64} samples per pixel"
    return f"{n_lights} virtual lights"
