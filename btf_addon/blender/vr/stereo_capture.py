"""Stereo Capture: the thesis's "VR screenshot" of the current scene, without a headset.

The operator ``btf.stereo_capture`` exports the evaluated scene (the shared export), draws
both eyes of a headset profile from the scene camera (gl/stereo_capture.py: the one
progressive drawer, all N lights of the scene's BTF render settings) and writes the pair and
its JSON beside the .blend or to a chosen path. ``capture_scene`` is the one path the CLI's
``render --stereo`` runs too.

Device: inside Blender's UI an operator runs with Blender's GPU context current, so the eyes
are drawn through Blender's ``gpu`` module (blender/gpu_draw.BlenderGPUDevice), on the GPU
Blender itself uses. Background Blender (``blender -b``, the bpy module, the CLI) has no GPU
context outside a render, so there the eyes are drawn on a headless moderngl (EGL) context,
exactly as ``python -m btf_addon render --stereo`` does.

PNG files go through the scene's colour management (view transform, look, exposure, dither),
as ``render`` saves PNGs through F12 + Save; EXR files hold the linear values (core/imageio).

The operator changes no Blender data (a temporary image used to save a PNG is removed, the
scene's output settings are put back), so it adds no undo step and is safe under undo.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import bpy
import numpy as np
from bpy.props import EnumProperty, IntProperty, StringProperty
from bpy.types import Operator

from ...core.errors import BTFError, BTFMaterialsError
from ...core.fileio import atomic_write_path
from ...gl.drawer import MAX_SIZE
from ...gl.stereo_capture import (
    LAYOUTS,
    StereoCapture,
    capture_profile,
    describe,
    output_paths,
    render_stereo,
    write_stereo,
)
from ...render.headsets import PROFILES, profile
from ...render.settings import RenderSettings
from ..export import export_scene
from ..sync import render_settings

#: Blender's image settings for an 8-bit RGB PNG (what ``render`` sets for a .png, less alpha:
#: a capture has none).
PNG_SETTINGS = {"file_format": "PNG", "color_mode": "RGB", "color_depth": "8"}


@contextmanager
def _image_settings(scene, values: dict):
    """``scene.render.image_settings`` set to ``values`` (and a still image), then restored."""
    settings = scene.render.image_settings
    names = ["media_type", *values] if hasattr(settings, "media_type") else list(values)
    saved = {name: getattr(settings, name) for name in names}
    try:
        if "media_type" in saved:  # Blender 5: a multilayer EXR or video first
            settings.media_type = "IMAGE"
        for name, value in values.items():
            setattr(settings, name, value)
        yield
    finally:
        for name in names:  # media_type first: it decides which formats are allowed
            setattr(settings, name, saved[name])


def scene_png_writer(scene):
    """A PNG writer (gl/stereo_capture.PngWriter) through ``scene``'s colour management:
    the image is saved as a render of ``scene`` would be (Image.save_render)."""

    def write(path: Path, rgb: np.ndarray) -> None:
        h, w = rgb.shape[:2]
        image = bpy.data.images.new("BTF stereo capture", w, h, alpha=False, float_buffer=True)
        try:
            rgba = np.ones((h, w, 4), dtype=np.float32)
            rgba[..., :3] = rgb[::-1]  # Blender's rows start at the bottom
            image.pixels.foreach_set(rgba.ravel())
            with _image_settings(scene, PNG_SETTINGS):
                atomic_write_path(path, lambda tmp: image.save_render(str(tmp), scene=scene))
        finally:
            bpy.data.images.remove(image)

    return write


def capture_scene(
    depsgraph,
    output: Path,
    profile_name: str,
    layout: str,
    eye_width: int | None,
    settings: RenderSettings | None = None,
    device=None,
) -> tuple[StereoCapture, list[Path]]:
    """Export ``depsgraph``'s scene and write its stereo capture to ``output`` (.exr/.png).
    ``settings``: None → the scene's BTF render settings; ``device``: a drawer device, None →
    headless moderngl. Sizes, names and the camera are checked before anything is drawn.
    Returns the capture (the export's warnings in ``capture.messages``) and the paths
    written (images, then the JSON)."""
    scene = depsgraph.scene
    sized = capture_profile(profile(profile_name), eye_width)  # ValueError: unknown name
    output_paths(output, layout)  # layout and suffix refused before the work
    if scene.camera is None:
        raise BTFError(f"the scene {scene.name!r} has no camera to capture from")
    if settings is None:
        settings = render_settings(scene)  # with the film filter, as F12
    exported = export_scene(depsgraph, sized.eye_width, sized.eye_height)
    capture = render_stereo(exported, settings, sized, device)
    capture.messages = list(exported.messages)
    written = write_stereo(capture, output, layout, scene_png_writer(scene))
    return capture, written


def _profile_items():
    return [(p.name, p.label, p.source, i) for i, p in enumerate(PROFILES.values())]


class BTF_OT_stereo_capture(Operator):
    """Render a stereo pair of what a headset would show from the scene camera (the headset
    profile's IPD, per-eye field of view and resolution) and save it with a JSON of the eyes"""

    bl_idname = "btf.stereo_capture"
    bl_label = "Stereo Capture"
    # No UNDO: nothing in the file changes (see the module docstring).
    bl_options = {"REGISTER"}

    profile: EnumProperty(name="Headset", items=_profile_items(), default="xtal-8k")
    layout: EnumProperty(
        name="Layout",
        items=[  # identifiers as gl/stereo_capture.LAYOUTS, the CLI's --layout
            (LAYOUTS[0], "Side by Side", "One image: left eye | right eye", 0),
            (LAYOUTS[1], "Per Eye", "NAME_left and NAME_right, one image per eye", 1),
        ],
        default="side-by-side",
    )
    file_format: EnumProperty(
        name="Format",
        items=[
            ("EXR", "OpenEXR", "Linear float values", 0),
            ("PNG", "PNG", "8-bit, through the scene's colour management", 1),
        ],
        default="EXR",
        description="Used when no file path is given",
    )
    eye_width: IntProperty(
        name="Eye Width",
        description="Pixels per eye, the headset's aspect kept (0: the headset's own size)",
        default=0,
        min=0,
        max=MAX_SIZE,
    )
    filepath: StringProperty(
        name="File Path",
        description="Where to write (.exr or .png); empty: beside the .blend, "
        "as BLENDNAME_stereo_HEADSET",
        subtype="FILE_PATH",
        default="",
    )

    def _output(self) -> Path:
        if self.filepath:
            return Path(bpy.path.abspath(self.filepath))
        if not bpy.data.filepath:
            raise BTFError("save the .blend first, or choose a file path for the capture")
        blend = Path(bpy.data.filepath)
        suffix = ".exr" if self.file_format == "EXR" else ".png"
        return blend.with_name(f"{blend.stem}_stereo_{self.profile}{suffix}")

    def invoke(self, context, event):
        # From the menu or F3: choose the headset and size first (the default is the
        # headset's full resolution).
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        device = None
        if not bpy.app.background:  # the UI's GPU context is current in an operator
            from ..gpu_draw import BlenderGPUDevice

            device = BlenderGPUDevice()
        try:
            output = self._output()
            capture, written = capture_scene(
                context.evaluated_depsgraph_get(),
                output,
                self.profile,
                self.layout,
                self.eye_width or None,
                device=device,
            )
        except (BTFMaterialsError, ValueError) as exc:
            self.report({"ERROR"}, f"Stereo Capture: {exc}")
            return {"CANCELLED"}
        except Exception as exc:  # no headless OpenGL; Blender's GPUOffScreen raises a bare
            # Exception when the GPU refuses a buffer: reported, never passed as a capture
            self.report(
                {"ERROR"}, f"Stereo Capture: could not draw the eyes ({type(exc).__name__}: {exc})"
            )
            return {"CANCELLED"}
        for message in capture.messages:
            self.report({"WARNING"}, message)
        names = ", ".join(str(p) for p in written)
        self.report(
            {"INFO"},
            f"Stereo Capture ({describe(capture)}, {capture.lights} lights): wrote {names}",
        )
        return {"FINISHED"}


classes = (BTF_OT_stereo_capture,)
register, unregister = bpy.utils.register_classes_factory(classes)
