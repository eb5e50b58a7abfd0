"""Stereo captures without a headset (the thesis's "VR screenshot"), bpy-free.

The scene camera is the head: a headset profile (render/headsets.py) gives the two eyes (IPD,
per-eye OpenXR field of view, per-eye resolution) and each eye is drawn by the one progressive
drawer (gl/drawer.py): one ``ProgressiveDrawer`` for the scene, one ``ViewAccumulation`` per
eye, all N virtual lights of the render settings (render/lighting.py), as the VR preview and
the XTAL bridge draw their eyes. Any device adapter works (gl/device.py): the CLI and
background Blender draw on moderngl, Blender's UI on its own ``gpu`` module.

Files: side-by-side (left | right in one image) or one file per eye (``NAME_left.EXT``,
``NAME_right.EXT``); ``.exr`` holds linear values, ``.png`` goes through a PNG writer the caller
chooses (default: core/imageio's sRGB curve, clipped; in Blender the scene's colour management,
as ``render`` saves PNGs); a JSON beside them (``NAME.json``) records the profile, IPD, per-eye
FOV, eye poses, sizes and lights. Every file is written atomically (core/fileio).
"""

from __future__ import annotations

import ctypes
import json
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..core.errors import BTFError
from ..core.fileio import atomic_write
from ..core.formats.imageio import srgb8_from_linear, write_exr, write_png
from ..render.headsets import Eye, HeadsetProfile, stereo_eyes
from ..render.lighting import frame_lights
from ..render.settings import RenderSettings
from ..scene.scene import Scene
from .converge import converge, rgb_top_first
from .drawer import MAX_SIZE, ProgressiveDrawer, ViewAccumulation

LAYOUTS = ("side-by-side", "per-eye")
SUFFIXES = (".exr", ".png")
#: Lights per batch without anti-aliasing: a capture is drawn to convergence, the split only
#: bounds one draw call.
BATCH = 16


def batch_size(settings: RenderSettings, lights: int) -> int:
    """Lights per batch. Anti-aliased (the film's filter), the lights are split over the
    settings' ``aa_samples`` subpixel offsets, one per batch, as F12's Virtual Lights mode splits
    them (gl/drawer.py): the capture is the same filtered image."""
    if settings.film() is None:
        return BATCH
    return max(1, -(-lights // settings.aa_samples))


#: (path, (H, W, 3) float32 linear image) → writes a PNG at ``path``.
PngWriter = Callable[[Path, np.ndarray], None]


def write_png_srgb(path: Path, rgb: np.ndarray) -> None:
    """The plain sRGB curve clipped at 1 (core/imageio), what ``render`` gives a scene on the
    "Standard" view without dither (the demo scene)."""
    write_png(path, srgb8_from_linear(rgb))


def capture_profile(profile: HeadsetProfile, eye_width: int | None = None) -> HeadsetProfile:
    """``profile`` at ``eye_width`` pixels per eye, its aspect kept (None: its own size).
    BTFError when the size is outside 1…MAX_SIZE per side, before anything is drawn."""
    if eye_width is not None:
        if eye_width < 1:
            raise BTFError(f"eye width must be at least 1 pixel, got {eye_width}")
        height = max(1, round(profile.eye_height * eye_width / profile.eye_width))
        profile = replace(profile, eye_width=eye_width, eye_height=height)
    w, h = profile.eye_width, profile.eye_height
    if max(w, h) > MAX_SIZE:
        raise BTFError(
            f"{profile.name}: {w}×{h} per eye is larger than the drawer's {MAX_SIZE} pixels "
            "per side; choose a smaller eye width"
        )
    return profile


def _film_metadata(settings: RenderSettings, lights: int) -> dict | None:
    """The pixel filter the eyes were anti-aliased with and over how many subpixel offsets
    (one per batch); None: pixel centres only."""
    film = settings.film()
    if film is None:
        return None
    subpixels = -(-lights // batch_size(settings, lights))
    return {"filter": film.type, "width_px": film.width, "subpixels": subpixels}


def head_from_camera(world_from_camera: np.ndarray) -> np.ndarray:
    """(4, 4) float64 world_from_head: the camera's position and orientation with its scale
    removed (an object scale on the camera must not scale the IPD). Blender's camera space and
    OpenXR's view space share axes (+x right, +y up, −z forward), so no axis change."""
    m = np.array(world_from_camera, dtype=np.float64)
    for i in range(3):
        m[:3, i] /= np.linalg.norm(m[:3, i])
    return m


@dataclass(eq=False)
class StereoCapture:
    """Both eyes of a capture. ``images``: {"left", "right"} → (H, W, 3) float32 linear, row 0
    at the top; ``eyes``: [left, right] (render/headsets.Eye); ``lights``: how many virtual
    lights each eye accumulated; ``settings``: the render settings they came from; ``files``:
    the images written; ``messages``: the scene export's warnings, for the caller to show;
    ``bake``: the light bake's status line (render/bake_playback.py; "" without a bake)."""

    profile: HeadsetProfile
    eyes: list[Eye]
    images: dict[str, np.ndarray]
    lights: int
    settings: RenderSettings
    near: float
    far: float
    files: list[Path] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    bake: str = ""

    def side_by_side(self) -> np.ndarray:
        """(H, 2W, 3) float32: [left | right]."""
        return np.concatenate([self.images["left"], self.images["right"]], axis=1)

    def metadata(self, layout: str) -> dict:
        """What the JSON beside the images holds (angles in radians, lengths in metres,
        matrices row-major (4, 4) lists)."""
        p = self.profile
        fovs = {"left": p.fov_left_eye, "right": p.fov_right_eye}
        return {
            "profile": {"name": p.name, "label": p.label, "source": p.source},
            "ipd_m": p.ipd_m,
            "layout": layout,
            "eye_size": [p.eye_width, p.eye_height],
            "image_size": ([2 * p.eye_width, p.eye_height] if layout == "side-by-side" else None),
            "near_m": self.near,
            "far_m": self.far,
            "eyes": {
                eye.name: {
                    "fov_rad": asdict(fovs[eye.name]),
                    "world_from_eye": np.linalg.inv(eye.view_from_world).tolist(),
                    "clip_from_view": eye.clip_from_view.tolist(),
                }
                for eye in self.eyes
            },
            "lights": {
                "count": self.lights,
                "lighting": self.settings.lighting.name.lower(),
                "seed": self.settings.seed,
            },
            "film": _film_metadata(self.settings, self.lights),
            "light_bake": self.bake or None,
            "files": [f.name for f in self.files],
        }


def render_stereo(
    scene: Scene,
    settings: RenderSettings,
    profile: HeadsetProfile,
    device=None,
) -> StereoCapture:
    """Draw both eyes of ``profile`` (already sized: ``capture_profile``) with the scene
    camera as the head, to convergence. ``device``: a drawer device (gl/device.py); None: a
    new headless moderngl one, closed afterwards. The near and far planes are the camera's."""
    capture_profile(profile)  # sizes refused before a context is made
    cam = scene.camera
    near, far = cam.clip_start, cam.clip_end
    eyes = stereo_eyes(profile, head_from_camera(cam.world_from_camera), near, far)
    # The eyes are parallel: both see the headlight from the head's +z, as in the VR preview.
    lights = frame_lights(settings, scene, head_from_camera(cam.world_from_camera)[:3, 2])
    if device is not None:  # the caller's device, in the caller's context
        return _draw_eyes(scene, settings, profile, eyes, lights, device, near, far)
    with _current_context_kept():
        return _draw_eyes(scene, settings, profile, eyes, lights, None, near, far)


@contextmanager
def _current_context_kept() -> Iterator[None]:
    """Leave the thread's current EGL context as it was found. Our own moderngl context,
    once released, leaves none current, and Blender (epoxy) aborts the process on its next GL
    call when it finds none: background Blender after a render, or at exit."""
    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError:  # no EGL: moderngl cannot have used it either
        yield
        return
    for name in ("eglGetCurrentDisplay", "eglGetCurrentContext", "eglGetCurrentSurface"):
        getattr(egl, name).restype = ctypes.c_void_p
    egl.eglGetCurrentSurface.argtypes = [ctypes.c_int]
    egl.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
    draw, read = 0x3059, 0x305A  # EGL_DRAW, EGL_READ
    context = egl.eglGetCurrentContext()
    current = (
        egl.eglGetCurrentDisplay(),
        egl.eglGetCurrentSurface(draw),
        egl.eglGetCurrentSurface(read),
        context,
    )
    try:
        yield
    finally:
        if context:
            egl.eglMakeCurrent(*current)


def _draw_eyes(scene, settings, profile, eyes, lights, device, near, far) -> StereoCapture:
    own_device = device is None
    if own_device:
        from .moderngl_device import ModernGLDevice

        device = ModernGLDevice()
    drawer = view = None
    try:
        drawer = ProgressiveDrawer(device, scene)
        bake = drawer.bake_status.line() if drawer.bake_status is not None else ""
        images = {}
        film = settings.film()
        for eye in eyes:  # one eye's targets at a time: 3 RGBA32F images of the eye's size
            view = ViewAccumulation(device, eye.width, eye.height)
            view.set_lights(lights, batch_size(settings, len(lights.pdf)))
            drawn = converge(drawer, view, eye.clip_from_world, [*eye.position, 1.0], film=film)
            images[eye.name] = rgb_top_first(drawn.image)  # files start at the top
            view.release()
            view = None
    finally:
        if view is not None:
            view.release()
        if drawer is not None:
            drawer.release()
        if own_device:
            device.close()
    return StereoCapture(profile, eyes, images, len(lights.pdf), settings, near, far, bake=bake)


def output_paths(output: Path, layout: str) -> dict[str, Path]:
    """{"image"} (side-by-side) or {"left", "right"} (per-eye), and "json": where a capture
    to ``output`` goes. BTFError for an unknown layout or suffix."""
    output = Path(output)
    if layout not in LAYOUTS:
        raise BTFError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    suffix = output.suffix.lower()
    if suffix not in SUFFIXES:
        raise BTFError(f"{output}: a stereo capture must end in .exr or .png")
    json_path = output.with_suffix(".json")
    if layout == "side-by-side":
        return {"image": output, "json": json_path}
    stem = output.with_suffix("")
    return {
        "left": stem.with_name(f"{stem.name}_left{output.suffix}"),
        "right": stem.with_name(f"{stem.name}_right{output.suffix}"),
        "json": json_path,
    }


def write_stereo(
    capture: StereoCapture, output: Path, layout: str, png_writer: PngWriter | None = None
) -> list[Path]:
    """Write ``capture`` as ``layout`` to ``output`` (its suffix chooses EXR or PNG) and the
    JSON beside it; returns the paths written, images first."""
    paths = output_paths(output, layout)
    images = {"image": capture.side_by_side()} if layout == "side-by-side" else dict(capture.images)
    write_image = write_exr if Path(output).suffix.lower() == ".exr" else png_writer
    if write_image is None:
        write_image = write_png_srgb
    written = []
    for key, image in images.items():
        if not np.isfinite(image).all():  # a broken image must not pass as a capture
            raise BTFError(f"the {key} image has non-finite pixels; nothing was written")
    for key, image in images.items():
        write_image(paths[key], image)
        written.append(paths[key])
    capture.files = list(written)
    text = json.dumps(capture.metadata(layout), indent=2, allow_nan=False)
    written.append(atomic_write(paths["json"], lambda fh: fh.write(text.encode())))
    return written


def describe(capture: StereoCapture) -> str:
    """One line for reports: profile, sizes, IPD, FOV."""
    p = capture.profile
    fov = p.fov_left_eye
    h_deg = math.degrees(fov.angle_right - fov.angle_left)
    return (
        f"{p.name}: 2 × {p.eye_width}×{p.eye_height}, IPD {p.ipd_m * 1000:.0f} mm, "
        f"{h_deg:.0f}° per eye horizontally"
    )
