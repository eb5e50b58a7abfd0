"""BTF materials in Blender's own VR session: an 'XR' POST_VIEW draw callback, per eye.

Blender's VR session never calls an engine's ``view_draw``: it draws each eye through
Workbench/EEVEE offscreen, then (with ``xr_session_settings.show_custom_overlays``) runs the
draw callbacks of region type 'XR', 'POST_VIEW', once per eye, with that eye's framebuffer bound
and its matrices loaded in ``gpu.matrix`` (depth test off), and without a context: ``bpy.context``
is unusable there, so everything is reached through ``bpy.data`` (the session's window, scene,
view layer and ``window_manager.xr_session_state``) or given to ``XRPreview`` by the caller.

Per eye (``render/stereo.py`` says which eye from the matrices and the viewer pose) a
``gl/eye.HeadsetEye``, the same object the XTAL bridge keeps per eye:
- an accumulation of its own (``gl/drawer.ViewAccumulation``) over the one scene drawer;
- K lights per frame, K from a frame-time budget (``render/frame_budget.FrameBudget``: the
  interval between successive callbacks of the same eye) or fixed; restarted when the eye's
  matrices move beyond a small threshold, accumulating towards N while the head is still;
- composited by drawing the WHOLE scene ourselves: BTF objects and the other objects in their
  analytic look (the exporter's plain materials) share one depth buffer, so occlusion is right
  both ways; the World is ours too, or (``show_world`` off) left transparent so Blender's own
  eye image (its background, controllers, floor) shows around our objects;
- a HUD quad fixed to the head (``render/hud.py``, ``gl/hud.py``): material under the gaze,
  lights in, frame time or over-budget warning, and the Wiimote's help when it is shown.

Tests (tests/blender/test_xr_draw.py) drive ``draw_callback`` exactly as Blender does: an eye's
``GPUOffScreen`` bound, its matrices loaded, the callback called, for two eyes of a headset
profile; the pixels are compared with the standalone renderer for the same matrices.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, replace

import bpy
import gpu
import numpy as np

from ...core.errors import BTFMaterialsError
from ...gl.device import DrawState
from ...gl.drawer import ProgressiveDrawer
from ...gl.eye import HeadsetEye, HeadsetSettings
from ...render.frame_budget import DEFAULT_BUDGET_S
from ...render.stereo import EyeId, EyeIdentifier
from ..export import ExportCache, changed_ids, export_scene
from ..gpu_draw import BlenderGPUDevice
from ..sync import render_settings, vr_settings
from ..wiimote import overlay as wiimote_overlay

# Into the eye's framebuffer: no depth written (Blender's depth there is its own), opaque or
# premultiplied "over" Blender's image when the World is left out.
EYE_OPAQUE = DrawState(depth_write=False)
EYE_OVER = DrawState(depth_write=False, blend="OVER")


@dataclass(frozen=True)
class VRSettings(HeadsetSettings):
    """What the VR panel sets (``scene.btf_vr``; blender/sync.py ``vr_settings``), as plain
    values: the headset's, as the XTAL bridge's, and ``show_world``."""

    show_world: bool = True


@dataclass(frozen=True)
class SceneSource:
    """Where the callback finds the scene: the depsgraph to export, the render settings, the
    VR settings and (None without a running session) the session state for the viewer pose."""

    depsgraph: Callable[[], object]
    session_state: Callable[[], object | None] = lambda: None


class XRPreview:
    """Everything the callback keeps between frames: one drawer for the scene, one state per
    eye. ``clock`` is injectable for the frame-budget tests."""

    def __init__(self, source: SceneSource, clock: Callable[[], float] = time.perf_counter):
        self.source, self.clock = source, clock
        self.device = BlenderGPUDevice()
        self.drawer: ProgressiveDrawer | None = None
        self.cache = ExportCache()
        self.scene_dirty = True
        self.eyes: dict[str, HeadsetEye] = {}
        self.gaze_materials: dict[str, str] = {}  # per eye: the BTF material straight ahead
        self.identifier = EyeIdentifier()
        self.error = ""  # why nothing is drawn (the panel shows it)
        self.messages: list[str] = []  # the export's warnings (a missing BTF drawn plain, …)
        self.last_eye: EyeId | None = None

    # --- scene changes ----------------------------------------------------------------------
    def invalidate(self, objects=(), materials=(), world: bool = False) -> None:
        """The depsgraph changed: the next draw re-exports (uploading only what changed)."""
        self.cache.invalidate(objects, materials, world)
        self.scene_dirty = True

    def release(self) -> None:
        for eye in self.eyes.values():
            eye.release()
        self.eyes.clear()
        self.gaze_materials.clear()
        if self.drawer is not None:
            self.drawer.release()
        self.drawer = None
        self.scene_dirty = True

    # --- one eye ------------------------------------------------------------------------------
    def draw_eye(self, clip_from_view, view_from_world, size: tuple[int, int]) -> None:
        """Draw the scene for one eye into the bound framebuffer (``size``: its pixels)."""
        depsgraph = self.source.depsgraph()
        scene = depsgraph.scene
        vr = vr_settings(scene)
        settings = replace(render_settings(scene), progressive=True)
        settings = replace(settings, lights_total=vr.lights_total)
        clip_from_view = np.asarray(clip_from_view, dtype=np.float64)
        view_from_world = np.asarray(view_from_world, dtype=np.float64)
        eye_id = self.identifier.identify(view_from_world, clip_from_view, self._viewer())
        self.last_eye = eye_id
        budget_s = vr.budget_s or DEFAULT_BUDGET_S  # Blender never says the display period
        eye = self.eyes.get(eye_id.key)
        if eye is None:
            eye = self.eyes[eye_id.key] = HeadsetEye(self.device, budget_s, self.clock)
        k = eye.lights_this_frame(vr.lights_per_frame, budget_s)

        framebuffer, viewport = gpu.state.active_framebuffer_get(), gpu.state.viewport_get()
        drawer = self._drawer(depsgraph, size)
        if drawer is None:
            return
        _, restarted = eye.advance(
            drawer, size, settings, clip_from_view, view_from_world, k, not vr.show_world
        )
        if restarted:
            gaze = self._gaze_material(depsgraph, np.linalg.inv(view_from_world))
            self.gaze_materials[eye_id.key] = gaze
        view = eye.view

        # Making GPU objects (the first frame's offscreens, textures) may leave another
        # framebuffer bound and the viewport changed: draw into the eye's explicitly.
        with framebuffer.bind():
            gpu.state.viewport_set(*viewport)
            state = EYE_OPAQUE if vr.show_world else EYE_OVER
            drawer.draw_resolved(view, vr.exposure, not vr.show_world, state)
            if vr.show_hud:
                help_rows = wiimote_overlay.current_help() or ()
                eye.draw_hud(
                    clip_from_view,
                    eye_id.offset,
                    self.gaze_materials.get(eye_id.key, ""),
                    [f"{a}: {b}" for a, b in help_rows],
                    self._navigation_scale(),
                )
            gpu.state.blend_set("NONE")
            gpu.state.depth_test_set("NONE")
            gpu.state.depth_mask_set(True)
        self.error = ""  # drawn: whatever went wrong before is over

    def _viewer(self) -> np.ndarray | None:
        state = self.source.session_state()
        if state is None:
            return None
        return np.array(state.viewer_pose_location, dtype=np.float64)

    def _drawer(self, depsgraph, size) -> ProgressiveDrawer | None:
        if not self.scene_dirty and self.drawer is not None:
            return self.drawer
        try:
            scene = export_scene(depsgraph, *size, cache=self.cache, viewport=True)
            self.drawer = ProgressiveDrawer(self.device, scene, previous=self.drawer)
            self.error, self.messages = "", list(scene.messages)
        except BTFMaterialsError as exc:  # bad input or a shader that does not compile
            if self.drawer is not None:
                self.drawer.release()
            self.drawer, self.error = None, str(exc)
            return None
        self.scene_dirty = False
        return self.drawer

    def _gaze_material(self, depsgraph, world_from_view) -> str:
        """The BTF material of the object straight ahead of the eye, for the HUD."""
        origin, forward = world_from_view[:3, 3], -world_from_view[:3, 2]
        hit, *_, obj, _ = depsgraph.scene.ray_cast(depsgraph, origin.tolist(), forward.tolist())
        if not hit or obj is None:
            return ""
        for slot in getattr(obj, "material_slots", ()):
            material = slot.material
            if material is not None and material.btf.enabled:
                return material.name
        return ""

    def _navigation_scale(self) -> float:
        state = self.source.session_state()
        return float(getattr(state, "navigation_scale", 1.0) or 1.0) if state else 1.0

    # --- for the panel ----------------------------------------------------------------------
    def summary(self) -> str:
        if self.error:
            return self.error
        parts = []
        for key, eye in sorted(self.eyes.items()):
            if eye.view is not None and eye.view.state is not None:
                parts.append(f"{key}: {eye.view.state.done}/{eye.view.state.total}")
        return ", ".join(parts) or "waiting for the first frame"


# --- the live session -------------------------------------------------------------------------
_preview: XRPreview | None = None
_handler = None


def _session_window():
    """The window the session draws from (Blender uses its root window's scene/view layer)."""
    wm = bpy.data.window_managers[0]
    return wm, (wm.windows[0] if len(wm.windows) else None)


def session_source() -> SceneSource:
    def depsgraph():
        _, window = _session_window()
        if window is not None:
            return window.view_layer.depsgraph
        # Background Blender has no window (a script or test driving the callback itself):
        # there the context is a real one.
        return bpy.context.evaluated_depsgraph_get()

    def session_state():
        wm, _ = _session_window()
        return wm.xr_session_state

    return SceneSource(depsgraph, session_state)


def preview() -> XRPreview | None:
    return _preview


def draw_callback(target: XRPreview | None = None) -> None:
    """The 'XR' POST_VIEW callback: one eye, its framebuffer bound and matrices loaded.

    ``target``: the preview to draw (tests pass their own); by default the live session's,
    created on first use. Never raises: a draw callback that raised would print a traceback
    twice a frame; the error is kept for the VR panel and printed once."""
    global _preview
    if target is None:
        if _preview is None:
            _preview = XRPreview(session_source())
        target = _preview
    *_, width, height = gpu.state.viewport_get()
    if width < 1 or height < 1:
        return
    clip_from_view = np.array(gpu.matrix.get_projection_matrix(), dtype=np.float64)
    view_from_world = np.array(gpu.matrix.get_model_view_matrix(), dtype=np.float64)
    try:
        target.draw_eye(clip_from_view, view_from_world, (width, height))
    except Exception as exc:
        message = f"BTF VR preview: {exc}"
        if message != target.error:
            traceback.print_exc()
        target.error = message
        # Whatever state the failed draw left: Blender's next draws expect its defaults.
        gpu.state.blend_set("NONE")
        gpu.state.depth_test_set("NONE")
        gpu.state.depth_mask_set(True)


@bpy.app.handlers.persistent
def _on_depsgraph_update(scene, depsgraph) -> None:
    if _preview is not None:
        _preview.invalidate(*changed_ids(depsgraph))


@bpy.app.handlers.persistent
def _on_session_start(*_args) -> None:
    """A new session: fresh per-eye state, the scene exported again on the first frame."""
    global _preview
    if _preview is not None:
        _preview.release()
    _preview = None
    if not bpy.app.timers.is_registered(_release_when_stopped):
        bpy.app.timers.register(_release_when_stopped, first_interval=1.0)


def _release_when_stopped() -> float | None:
    """Free the GPU memory once the session has ended (Blender has no end-of-session handler)."""
    global _preview
    if bpy.types.XrSessionState.is_running(bpy.context):
        return 1.0
    if _preview is not None:
        _preview.release()
    _preview = None
    return None


def has_openxr() -> bool:
    return bool(getattr(bpy.app.build_options, "xr_openxr", False))


def register(xr_available: bool | None = None) -> None:
    """With XR: the settings, panel, operator, draw callback, handlers and VR actions. Without
    (``bpy.app.build_options.xr_openxr`` false): only a panel that says why."""
    from . import panel as xr_panel

    available = has_openxr() if xr_available is None else xr_available
    xr_panel.register(available)
    if not available:
        return
    from . import actions as xr_actions

    global _handler
    _handler = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), "XR", "POST_VIEW")
    bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph_update)
    bpy.app.handlers.xr_session_start_pre.append(_on_session_start)
    xr_actions.register()


def unregister() -> None:
    from . import panel as xr_panel

    global _handler, _preview
    if _handler is not None:
        from . import actions as xr_actions

        xr_actions.unregister()
        bpy.types.SpaceView3D.draw_handler_remove(_handler, "XR")
        _handler = None
        for handlers, fn in (
            (bpy.app.handlers.depsgraph_update_post, _on_depsgraph_update),
            (bpy.app.handlers.xr_session_start_pre, _on_session_start),
        ):
            if fn in handlers:
                handlers.remove(fn)
        if bpy.app.timers.is_registered(_release_when_stopped):
            bpy.app.timers.unregister(_release_when_stopped)
    if _preview is not None:
        _preview.release()
        _preview = None
    xr_panel.unregister()
