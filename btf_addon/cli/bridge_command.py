"""``bridge``: the XTAL bridge headless — a .blend's scene drawn straight into whatever OpenXR
runtime the loader finds (``XR_RUNTIME_JSON``), for N frames, optionally captured.

The .blend is opened in Blender (the bpy module) with the add-on registered, as ``render
--blend`` does, and its scene exported by the shared export (blender/export) once; the bridge
(xr/bridge.py) then runs bpy-free.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..core.errors import BTFError
from ..render.headsets import PROFILES
from .blend_file import check_blend, import_bpy, open_blend

DESCRIPTION = """\
Run the XTAL bridge on a .blend's active scene against the OpenXR runtime the loader finds
(set XR_RUNTIME_JSON to choose one): per eye, the progressive BTF drawer with K lights per
frame within the runtime's frame period, submitted to the headset. --place says where the
runtime's space lies in the scene: "space" (default) uses the reported poses as scene
coordinates; "camera" puts the head at the scene camera, facing its heading, +y up turned to
the scene's +z (what a worn headset needs).

The output ends with what the run used and did: the runtime, eye size, frames and FPS, the
warm-up (how long the start and the first frames took, and on what: the OpenXR session and
GL context, shader compiles, uploads, the driver's first draws), and per eye the lights per
frame (one decision per frame for both eyes) and the lights accumulated.

--capture DIR writes, per submitted frame and eye, the linear image (EXR) and a JSON with the
eye's pose and FOV as submitted, the matrices drawn with, lights so far, exposure, eye size
and the runtime's name (docs/user-guide.md, "XTAL bridge and headless captures").

Exit codes: 0 ok, 2 usage or scene errors, 3 no OpenXR runtime, 4 no headset, 5 session
lost, 6 the runtime lacks what the bridge needs (two views, an OpenGL/EGL binding, a usable
swapchain format), 130 interrupted (Ctrl-C).
"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "bridge",
        help="drive an OpenXR headset with the BTF renderer (the XTAL bridge), headless",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--blend", type=Path, required=True, help="the .blend (its active scene)")
    p.add_argument(
        "--frames", type=_positive_int, metavar="N", help="submit N frames, then end (default: "
        "until the runtime ends the session)"
    )  # fmt: skip
    p.add_argument("--capture", type=Path, metavar="DIR", help="write each eye image + JSON")
    p.add_argument(
        "--converge",
        action="store_true",
        help="hold the first located pose for the whole run: the lights accumulate until all "
        "are in and later frames stay converged (captures then equal an independent render "
        "of that pose)",
    )
    p.add_argument(
        "--scale", type=_positive_float, default=1.0, metavar="S",
        help="eye resolution × S of the runtime's recommended size (clamped to its maximum)",
    )  # fmt: skip
    p.add_argument(
        "--lights", type=_positive_int, metavar="N", help="virtual lights per eye (default: "
        "the scene's Lights setting)"
    )  # fmt: skip
    p.add_argument("--exposure", type=float, default=0.0, metavar="STOPS", help="exposure")
    p.add_argument(
        "--profile",
        choices=sorted(PROFILES),
        default="generic-2016x2240",
        help="headset profile for what the runtime does not report",
    )
    p.add_argument(
        "--place",
        choices=("space", "camera"),
        default="space",
        help="space (default): the runtime's reference space is the scene's world, poses used "
        "as reported; camera: the head starts at the scene camera, facing its heading, +y up "
        "turned to +z up (as Blender's VR session; for wearing a headset)",
    )
    p.add_argument(
        "--hud",
        action="store_true",
        help="show the status panel in the eyes (off by default: the images, and captures, "
        "then hold the scene alone, as an independent render of the same views does)",
    )
    p.set_defaults(func=cmd_bridge)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {value}")
    return value


def cmd_bridge(args) -> int:
    from ..xr.bridge import BridgeSettings, run_bridge
    from ..xr.controls import vr_controls

    check_blend(args.blend)  # before Blender starts
    scene, render_settings = export_blend(args.blend)
    settings = BridgeSettings(
        lights_total=args.lights or render_settings.lights_total,
        exposure=args.exposure,
        resolution_scale=args.scale,
        profile=args.profile,
        show_hud=args.hud,
        capture_dir=args.capture.resolve() if args.capture else None,
        converge=args.converge,
        placement=args.place,
    )
    for message in scene.messages:
        print(f"note: {message}", file=sys.stderr)
    # BridgeError (its exit codes) and Ctrl-C (130) end at the CLI's one boundary (cli/main.py);
    # a Ctrl-C at any point of a frame ends it, the session and the GL work first (xr/session.py);
    # the session and the context are released on the way out.
    from .main import raise_if_interrupted

    status = run_bridge(
        scene, render_settings, settings, args.frames, vr_controls(), raise_if_interrupted
    )
    fps = f"{status.fps:.1f}" if status.fps is not None else "n/a"
    w, h = status.eye_size
    print(f"runtime: {status.runtime}")
    print(f"values from: {status.values_from}" + (f" ({status.message})" if status.message else ""))
    print(f"eye size: {w}x{h}; frames: {status.frames}; FPS: {fps}")
    if status.bake:
        print(status.bake)
    for line in status.warmup:  # why the start and the first frames took long
        print(f"warm-up: {line}")
    for eye in sorted(status.lights_per_frame):
        print(
            f"{eye} eye: {status.lights_per_frame[eye]} lights per frame, "
            f"{status.lights_done.get(eye, 0)}/{settings.lights_total} accumulated"
        )
    if settings.capture_dir is not None:
        print(f"captures in {settings.capture_dir}")
    return 0


def export_blend(path: Path) -> tuple:
    """Open ``path`` in Blender and export its active scene (plain arrays) and render
    settings, with the add-on registered as ``render --blend`` registers it."""
    bpy = import_bpy("opening a .blend")
    from .render_command import _engine_registered

    with _engine_registered(bpy):
        open_blend(bpy, path)
        from ..blender.export import export_scene
        from ..blender.sync import frame_size, render_settings

        blender_scene = bpy.context.scene
        if blender_scene.camera is None:
            raise BTFError(f"the scene {blender_scene.name!r} has no camera: the bridge "
                           "places the viewer at the scene camera")  # fmt: skip
        # With the scene's film filter, as F12 and Blender's VR session (blender/sync.py).
        settings = render_settings(blender_scene)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        scene = export_scene(depsgraph, *frame_size(blender_scene.render))
    return scene, settings
