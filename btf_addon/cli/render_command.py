"""``render``: a .blend or the demo scene, rendered headless by the engine's own F12.

The file is opened in Blender (the bpy module), its scene keeps every setting it was saved with
(``scene.btf_render``: lighting, final mode, lights, samples, bounces, seed; resolution, colour
management, passes), the flags given override them in the UI's words, and
``bpy.ops.render.render(write_still=True)`` renders and saves the image, as F12 + Save and
``blender -b file.blend -f 1`` do. There is no second render path here to drift from F12.
``--stereo`` opens the file the same way but is no F12: it captures what a headset would see,
through the Stereo Capture operator's own code (blender/vr/stereo_capture.py).
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

from ..core import memory
from ..core.errors import BTFError
from ..core.fileio import check_output
from ..gl.stereo_capture import LAYOUTS, capture_profile
from ..render.headsets import PROFILES, profile
from ..render.pixel_filter import FilterType, PixelFilter
from ..render.settings import FinalMode, Lighting, RenderSettings
from .blend_file import check_blend, import_bpy, open_blend, report_text

#: Output suffix → Blender image settings: 8-bit RGBA PNG (through the view transform) or
#: 32-bit float RGBA EXR (scene-linear values).
FORMATS = {
    ".png": {"file_format": "PNG", "color_mode": "RGBA", "color_depth": "8"},
    ".exr": {"file_format": "OPEN_EXR", "color_mode": "RGBA", "color_depth": "32"},
}

DESCRIPTION = """\
Render a .blend (its active scene) or the demo scene through the BTF engine's F12, exactly as
`blender -b file.blend -f 1` renders it: the scene's own render settings (Render Properties >
BTF) apply, and the flags below override them for this render only (nothing is saved).

Colour: an .exr holds the scene-linear render (float RGBA). A .png is saved as Blender saves
renders: through the scene's colour management (view transform, look, exposure, dither), so
a scene left on Blender's default AgX view gets AgX's tone curve. The demo scene uses the
"Standard" view without dither: its PNG is the plain sRGB curve of the render, clipped at 1
(what this command wrote for every PNG before it rendered through F12).

Devices: OpenCL as chosen by --device or the add-on preference; with no OpenCL device at all,
F12 warns and draws with the GLSL viewport path (no shadows). A kernel that fails to compile
fails the render (exit code 2, with the compiler's first lines).

Stereo (--stereo PROFILE): instead of F12, what a headset would show, the "VR screenshot": the
same file or demo scene is opened and exported, the scene camera is the head, and each eye of
the headset profile (its IPD, per-eye field of view and resolution; --eye-width scales the
resolution keeping its aspect) is drawn by the GLSL viewport drawer on a headless OpenGL
context with all N virtual lights (--lighting, --lights, --seed apply; no shadows). Output:
--layout side-by-side (left | right in OUTPUT) or per-eye (NAME_left.EXT, NAME_right.EXT),
and NAME.json beside it with the profile, IPD, per-eye FOV, eye poses and lights. PNG goes
through the scene's colour management as above; EXR holds linear values.
Profiles: {profiles}.
"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "render",
        help="render a .blend or the demo scene headless (the engine's own F12)",
        description=DESCRIPTION.format(profiles=", ".join(PROFILES)),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--blend", type=Path, help="the .blend file to render (its active scene)")
    source.add_argument("--demo", action="store_true", help="the demo scene (no file needed)")
    p.add_argument("-o", "--output", required=True, type=Path, help=".png or .exr")
    p.add_argument("--resolution", type=_resolution, metavar="WxH", help="e.g. 800x600 (at 100 %%)")
    p.add_argument(
        "--final-mode",
        type=_enum_choice(FinalMode),
        metavar="virtual|sampled",
        help="virtual: exactly the N virtual lights (deterministic); sampled: the World "
        "sampled continuously with MIS, path traced (noise that falls with --samples)",
    )
    p.add_argument(
        "--lighting",
        type=_lighting,
        metavar="environment|headlight",
        help="environment: the World; headlight: one light from the camera",
    )
    p.add_argument(
        "--lights",
        type=int,  # its range (1…4096) is the scene property's, checked in _check_ranges
        metavar="N",
        help="N virtual lights standing in for the World (Virtual Lights mode)",
    )
    p.add_argument(
        "--samples",
        type=_at_least(1),
        metavar="N",
        help="samples per pixel of the Sampled final mode",
    )
    p.add_argument(
        "--samples-per-camera-ray",
        type=_at_least(1, 16),
        metavar="N",
        help="Sampled mode with anti-aliasing: N consecutive samples of a pixel share one "
        "camera ray (1: a ray each)",
    )
    p.add_argument(
        "--bounces",
        type=_at_least(0),
        metavar="N",
        help="indirect reflections of the Sampled final mode",
    )
    p.add_argument(
        "--clamp-indirect",
        type=_non_negative,
        metavar="X",
        help="Sampled mode: a sample's indirect light scaled to at most X per channel (removes "
        "fireflies, a little bias; 0: off)",
    )
    p.add_argument(
        "--noise-threshold",
        type=_noise_threshold,
        metavar="T",
        help="Sampled mode: adaptive sampling, pixels whose noise falls below T stop taking "
        "samples (Cycles' Noise Threshold, default 0.01 in new scenes); 0: off",
    )
    p.add_argument(
        "--seed", type=_at_least(0), metavar="N", help="randomisation of lights and samples' points"
    )
    p.add_argument(
        "--fixed-launch-split",
        action="store_const",
        const=True,  # not given: None, the scene's setting
        help="split the render into device launches by a fixed plan: bit-identical frames "
        "between runs on one device (also BTF_FIXED_LAUNCHES=1)",
    )
    p.add_argument(
        "--no-btf-importance",
        dest="btf_importance_sampling",
        action="store_const",
        const=False,  # not given: None, the scene's setting
        help="Sampled mode: cosine sampling only for measured BTFs, without their sampling "
        "tables (less time per sample, more noise on glossy materials)",
    )
    p.add_argument(
        "--filter",
        type=_pixel_filter,
        default=False,  # not given: the scene's film (None is "none": pixel centres)
        metavar="TYPE:WIDTH",
        help="the film's pixel filter (scene.cycles), e.g. blackman_harris:1.5, gaussian:1.5, "
        "box:1; 'none' traces every ray through the pixel centre",
    )
    p.add_argument(
        "--device",
        type=int,
        metavar="N",
        help="OpenCL device index as `doctor` lists them, set as the add-on preference "
        "(Preferences > Add-ons > BTF Materials > OpenCL Device) for this render; default: "
        "that preference (Automatic: best GPU, else CPU)",
    )
    p.add_argument(
        "--stereo",
        choices=sorted(PROFILES),
        metavar="PROFILE",
        help="a stereo capture with this headset profile instead of F12 (see above)",
    )
    p.add_argument(
        "--layout",
        choices=LAYOUTS,
        help="stereo output: side-by-side (default) or per-eye",
    )
    p.add_argument(
        "--eye-width",
        type=int,
        metavar="N",
        help="stereo: N pixels per eye, the profile's aspect kept (default: its own size)",
    )
    p.add_argument("--engine", type=_removed_engine, help=argparse.SUPPRESS)
    p.set_defaults(func=cmd_render)


def _resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must look like 800x600, got {text!r}") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise argparse.ArgumentTypeError(f"{w}x{h} is outside 1…16384")
    return w, h


def _non_negative(text: str) -> float:
    """A finite number ≥ 0, refused by argparse (exit 2) before Blender starts."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not (0.0 <= value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number of at least 0, got {text}")
    return value


def _noise_threshold(text: str) -> float:
    """A number in [0, 1] (the Noise Threshold property's range), refused by argparse (exit 2)
    before Blender starts."""
    value = _non_negative(text)
    if value > 1.0:
        raise argparse.ArgumentTypeError(f"must be at most 1, got {text}")
    return value


def _at_least(low: int, high: int | None = None):
    """An integer flag with a least (and maybe a greatest) value, refused by argparse (exit 2)
    before Blender starts: Blender would clamp it silently (a black image for --samples -1)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high}, got {value}")
        return value

    return parse


def _after_interrupt(output: Path, before: int | None) -> None:
    """Ctrl-C or SIGTERM during F12 raises inside the engine's render callback, which Blender
    reports and then saves what was drawn: remove that image and end as interrupted."""
    from .main import raise_if_interrupted, signals_received

    if signals_received:
        if output.is_file() and output.stat().st_mtime_ns != before:
            output.unlink()
        raise_if_interrupted()


def _check_memory(width: int, height: int, lights: int) -> None:
    """The render's peak (core/memory.py ``render``) against what the process may use."""
    memory.require(memory.render(width, height, lights, f"a {width}x{height} render"))


def _enum_choice(enum_type):
    """Lower-case member names of ``enum_type`` on the command line → the member."""

    def parse(text: str):
        try:
            return enum_type[text.upper()]
        except KeyError:
            names = "|".join(m.name.lower() for m in enum_type)
            raise argparse.ArgumentTypeError(f"must be one of {names}, got {text!r}") from None

    return parse


def _lighting(text: str) -> Lighting:
    if text.startswith("virtual:") or text == "envmap":
        raise argparse.ArgumentTypeError(
            f"{text!r} is the old form: --lighting is now environment|headlight, as in the UI; "
            "use --final-mode virtual --lights N (was virtual:N) or --final-mode sampled "
            "(was envmap)"
        )
    return _enum_choice(Lighting)(text)


def _pixel_filter(text: str) -> PixelFilter | None:
    """``TYPE:WIDTH`` (Cycles' filter identifiers, any case) or ``none``."""
    if text.lower() == "none":
        return None
    kind, _, width = text.partition(":")
    try:
        return PixelFilter(kind.upper(), float(width or 1.5))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected TYPE:WIDTH with TYPE one of "
            f"{', '.join(t.name.lower() for t in FilterType)} and a width ≥ 0 px, or none"
        ) from exc


def _removed_engine(_text: str):
    raise argparse.ArgumentTypeError(
        "--engine is gone: the CLI renders through the engine's F12 (OpenCL, falling back to "
        "the GLSL drawer only where no OpenCL device exists); choose the device with --device N"
    )


def overrides(args) -> dict:
    """The flags given, as ``RenderSettings`` field values (None: keep the scene's)."""
    return {
        "final_mode": args.final_mode,
        "lighting": args.lighting,
        "lights_total": args.lights,
        "samples": args.samples,
        "max_bounces": args.bounces,
        "clamp_indirect": args.clamp_indirect,
        "samples_per_camera_ray": args.samples_per_camera_ray,
        **_adaptive_overrides(args.noise_threshold),
        "seed": args.seed,
        "fixed_launch_split": args.fixed_launch_split,
        "btf_importance_sampling": args.btf_importance_sampling,
    }


def _adaptive_overrides(threshold: float | None) -> dict:
    """``--noise-threshold T`` in the settings' words: T > 0 turns adaptive sampling on at T,
    0 turns it off (the scene's threshold kept for when it is turned on again)."""
    if threshold is None:
        return {"use_adaptive_sampling": None, "adaptive_threshold": None}
    return {"use_adaptive_sampling": threshold > 0, "adaptive_threshold": threshold or None}


def cmd_render(args) -> int:
    suffix = args.output.suffix.lower()
    if suffix not in FORMATS:
        raise BTFError(f"{args.output}: output must end in .png or .exr")
    check_output(args.output)
    if args.blend is not None:
        check_blend(args.blend)
    _check_stereo_flags(args)
    if args.resolution is not None:  # known before Blender starts: refuse a size up front
        _check_memory(*args.resolution, args.lights or 0)
    bpy = import_bpy("rendering")
    from ..blender.sync import frame_size

    with _engine_registered(bpy) as package:
        if args.demo:
            from ..blender.demo import build_demo_scene

            scene = build_demo_scene(args.output.parent / "demo_data")
        else:
            open_blend(bpy, args.blend)
            scene = bpy.context.scene
        if args.stereo:
            return _render_stereo(bpy, scene, args)
        settings = prepare_scene(scene, args)
        _check_memory(*frame_size(scene.render), settings.lights_total)
        output = args.output.resolve()
        before = output.stat().st_mtime_ns if output.is_file() else None
        with _device_preference(bpy, package, args.device):
            t0 = time.perf_counter()
            try:
                bpy.ops.render.render(write_still=True)
            except RuntimeError as exc:  # the engine's ERROR reports, e.g. a compile error
                raise BTFError(report_text(str(exc))) from None
            finally:
                _after_interrupt(output, before)
            seconds = time.perf_counter() - t0
        w, h = frame_size(scene.render)  # as F12 sized it
    if not output.is_file() or output.stat().st_mtime_ns == before:
        raise BTFError(f"the render wrote no image to {output}")
    print(f"rendered {w}x{h} with {describe(settings)} in {seconds:.2f} s -> {args.output}")
    return 0


#: F12-only flags, refused with --stereo (the eyes are drawn by the viewport's drawer).
F12_ONLY = {
    "resolution": "--resolution (use --eye-width)",
    "final_mode": "--final-mode",
    "samples": "--samples",
    "bounces": "--bounces",
    "clamp_indirect": "--clamp-indirect",
    "samples_per_camera_ray": "--samples-per-camera-ray",
    "noise_threshold": "--noise-threshold",
    "device": "--device",
    "btf_importance_sampling": "--no-btf-importance",
}


def _check_stereo_flags(args) -> None:
    """Before Blender starts: flags that do not fit the stereo capture, and its sizes."""
    stereo_only = [
        flag
        for flag, value in (("--layout", args.layout), ("--eye-width", args.eye_width))
        if value is not None
    ]
    if args.stereo is None:
        if stereo_only:
            raise BTFError(f"{', '.join(stereo_only)} needs --stereo PROFILE")
        return
    given = [flag for name, flag in F12_ONLY.items() if getattr(args, name) is not None]
    if given:
        raise BTFError(
            f"{', '.join(given)}: F12 only; a stereo capture is drawn with the viewport's "
            "virtual lights at the profile's (or --eye-width's) size"
        )
    capture_profile(profile(args.stereo), args.eye_width)  # sizes refused up front
    args.layout = args.layout or LAYOUTS[0]


def _render_stereo(bpy, scene, args) -> int:
    """The stereo capture of ``scene`` (blender/vr/stereo_capture.py, the operator's own path)."""
    from ..blender.sync import render_settings
    from ..blender.vr.stereo_capture import capture_scene
    from ..gl.stereo_capture import describe as describe_capture

    if scene.camera is None:
        raise BTFError(f"the scene {scene.name!r} has no camera to capture from")
    given = overrides(args)
    _check_ranges(scene.btf_render, given)
    settings = render_settings(scene).with_overrides(**given)  # the film, as F12
    t0 = time.perf_counter()
    capture, written = capture_scene(
        bpy.context.evaluated_depsgraph_get(),
        args.output.resolve(),
        args.stereo,
        args.layout,
        args.eye_width,
        settings,
    )
    seconds = time.perf_counter() - t0
    for message in capture.messages:
        print(f"warning: {message}", file=sys.stderr)
    print(
        # A capture draws the virtual lights whatever the final mode (gl/stereo_capture.py).
        f"captured {describe_capture(capture)} with "
        f"{describe(replace(settings, final_mode=FinalMode.VIRTUAL))} in {seconds:.2f} s "
        f"-> {', '.join(str(p) for p in written)}"
    )
    return 0


def describe(settings: RenderSettings) -> str:
    if settings.lighting is Lighting.HEADLIGHT:
        return "the headlight"
    if settings.sampled:
        adaptive = settings.noise_threshold
        stops = f", noise threshold {adaptive:g}" if adaptive else ""
        return (
            f"the environment sampled, {settings.samples} samples per pixel, "
            f"{settings.max_bounces} bounces{stops} (seed {settings.seed})"
        )
    return f"{settings.lights_total} virtual lights (seed {settings.seed})"


def prepare_scene(scene, args) -> RenderSettings:
    """The scene as F12 will see it: the BTF engine, the overrides, the output file."""
    from ..blender.addon import ENGINE_ID
    from ..blender.sync import render_settings

    if scene.camera is None:
        raise BTFError(f"the scene {scene.name!r} has no camera to render from")
    if scene.render.engine != ENGINE_ID:
        print(
            f"note: the scene's render engine is {scene.render.engine}; rendering with BTF",
            file=sys.stderr,
        )
        scene.render.engine = ENGINE_ID
    given = overrides(args)
    _check_ranges(scene.btf_render, given)
    settings = render_settings(scene).with_overrides(**given)  # the film, as F12
    settings.to_properties(scene.btf_render)
    if args.filter is not False:
        _apply_filter(scene, args.filter)
    if args.resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = args.resolution
        scene.render.resolution_percentage = 100
    image = scene.render.image_settings
    if hasattr(image, "media_type"):  # Blender 5: a multilayer EXR or video first
        image.media_type = "IMAGE"
    for name, value in FORMATS[args.output.suffix.lower()].items():
        setattr(image, name, value)
    scene.render.filepath = str(args.output.resolve())
    scene.render.use_file_extension = False  # exactly the path given
    return settings


def _apply_filter(scene, pixel_filter) -> None:
    """--filter: the film's filter where F12 reads it (scene.cycles), or anti-aliasing off."""
    if pixel_filter is None:
        scene.btf_render.use_antialiasing = False
        return
    cycles = getattr(scene, "cycles", None)
    if cycles is None or not hasattr(cycles, "pixel_filter_type"):
        raise BTFError("--filter needs the Cycles add-on (the film's filter lives on it)")
    scene.btf_render.use_antialiasing = True
    cycles.pixel_filter_type, cycles.filter_width = pixel_filter.type, pixel_filter.width


#: RenderSettings fields the flags set, by flag (for messages).
FLAGS = {"lights_total": "--lights", "samples": "--samples", "max_bounces": "--bounces"}


def _check_ranges(props, given: dict) -> None:
    """Blender clamps out-of-range values silently; a command line should say so instead."""
    for name, value in given.items():
        if not isinstance(value, int) or isinstance(value, bool):
            continue
        prop = props.bl_rna.properties[name]
        if not prop.hard_min <= value <= prop.hard_max:
            flag = FLAGS.get(name, f"--{name}")
            raise BTFError(f"{flag} {value} is outside {prop.hard_min}…{prop.hard_max}")


@contextmanager
def _engine_registered(bpy):
    """Yields the package of the add-on that will render: an installed copy enabled in this
    Blender, else this checkout, registered for the command's duration."""
    from .. import blender
    from ..blender.addon import ADDON_PACKAGE, ENGINE_ID

    engine = next(
        (
            e
            for e in bpy.types.RenderEngine.__subclasses__()
            if getattr(e, "bl_idname", "") == ENGINE_ID
        ),
        None,
    )
    if engine is not None:  # its copy's blender/addon.py knows the copy's package name
        yield sys.modules[engine.__module__.rpartition(".")[0] + ".addon"].ADDON_PACKAGE
        return
    from .main import signals_held

    with signals_held():  # half-registered classes crash Blender on the way out
        blender.register()
    try:
        yield ADDON_PACKAGE
    finally:
        with signals_held():
            blender.unregister()


@contextmanager
def _device_preference(bpy, package: str, device: int | None):
    """The add-on preference ``opencl_device`` set to ``device`` for the render (the add-on
    entry created as ``addon_utils`` does where this checkout registered itself)."""
    if device is None:
        yield
        return
    from ..blender.preferences import device_identifier

    addons = bpy.context.preferences.addons
    entry, created = addons.get(package), False
    if entry is None:
        entry, created = addons.new(), True
        entry.module = package
    previous = entry.preferences.opencl_device
    try:
        try:
            entry.preferences.opencl_device = device_identifier(device)
        except TypeError:
            raise BTFError(
                f"--device {device}: no such OpenCL device (`python -m btf_addon doctor` "
                "lists them)"
            ) from None
        yield
    finally:
        if created:
            addons.remove(entry)
        elif previous:  # "" when the saved device is no longer listed: nothing to restore
            entry.preferences.opencl_device = previous
