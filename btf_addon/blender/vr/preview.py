"""BTF materials in Blender's own VR session: an 'XR' POST_VIEW draw callback, per eye.

Blender's VR session never calls an engine's ``view_draw``: it draws each eye through
Workbench/EEVEE offscreen, then (with ``xr_session_settings.show_custom_overlays``) runs the
draw callbacks of region type 'XR', 'POST_VIEW', once per eye, with that eye's framebuffer bound
and its matrices loaded in ``gpu.matrix`` (depth test off), and without a context: ``bpy.context``
is unusable there, so everything is reached through ``bpy.data`` (the session's window, scene,
view layer and ``window_manager.xr_session_state``) or given to ``XRPreview`` by the caller.
The session's window is the one it was started from (remembered at ``xr_session_start_pre``
by its ``as_pointer()``; the first window once it is closed), as Blender's own
``wm_xr_session_root_window_or_fallback_get`` finds it.

Who is drawing: the two eyes, and a desktop "Mirror VR Session" view, which runs the callback a
third time per frame at its window's size from the viewer pose itself. ``viewer_pose_location``
reads exactly (0, 0, 0) until Blender has drawn the first eye: that is taken as unknown. A
mirror draw (the pose rule's "mono", or a symmetric frustum while the pose is unknown) gets a
view of its own (``MIRROR``) with one light per frame, and its time is kept out of the eyes'
clock, so the eyes' frame budget measures their own frames.

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
  lights in, frame time or over-budget warning, and the Wiimote's help when it is shown. Its
  place is in view-space metres: Blender's view matrix divides by base scale × navigation
  scale (``wm_xr_draw_matrices_create``), so view space is the headset's metres whatever the
  scales, and the eye's offset from the head is the viewer's location in that eye's view
  space. The gaze is ray-cast once for both eyes, again when the head moved > 1 cm or turned
  > 0.5° or the scene was re-exported.

Live costs (``live.py``): the drawer's uniforms converted once per value, not per mesh draw;
``depsgraph_update_post`` re-exports only for updates of drawn data (objects other than
cameras, their data, materials, images, the World), never for the Scene's own properties.

Colour (``display.py``): Blender merges the callback's image, from its 8-bit sRGB overlay
buffer, over its own eye image after the latter's view transform; the live callback therefore
draws through the scene's view transform (a LUT baked by Blender, outside drawing), written for
that merge, so the eyes show the desktop's colours.

Tests (tests/blender/test_xr_draw.py, test_xr_live_session.py) drive ``draw_callback``
exactly as Blender does: an eye's ``GPUOffScreen`` bound, its matrices loaded, the callback
called, for two eyes of a headset profile; the pixels are compared with the standalone
renderer for the same matrices.
"""

from __future__ import annotations

import math
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, replace

import bpy
import gpu
import numpy as np

from ...core.errors import BTFMaterialsError
from ...core.mat4 import inverse
from ...gl.device import DEFAULT_STATE, DrawState
from ...gl.drawer import ProgressiveDrawer
from ...gl.eye import HeadsetEye, HeadsetSettings, SharedBudget
from ...render.frame_budget import DEFAULT_BUDGET_S
from ...render.stereo import SKEW_TOLERANCE, EyeId, EyeIdentifier
from ..export import ExportCache, changed_ids, export_scene
from ..export.light_bake import remember_status
from ..sync import render_settings, vr_settings
from ..wiimote import overlay as wiimote_overlay
from .display import DisplayTransform
from .live import CachedUniformsDevice, drawn_data_changed

# Into the eye's framebuffer: no depth written (Blender's depth there is its own), opaque or
# premultiplied "over" Blender's image when the World is left out.
EYE_OPAQUE = DrawState(depth_write=False)
EYE_OVER = DrawState(depth_write=False, blend="OVER")


@dataclass(frozen=True)
class VRSettings(HeadsetSettings):
    """What the VR panel sets (``scene.btf_vr``; blender/sync.py ``vr_settings``), as plain
    values: the headset's, as the XTAL bridge's, and ``show_world``."""

    show_world: bool = True


MIRROR = "mirror"  # the key of a desktop "Mirror VR Session" view's draws
MIRROR_LIGHTS_PER_FRAME = 1  # the mirror is a window-sized extra: the fewest lights a frame
GAZE_MOVE_M = 0.01  # the head moves this far (headset metres) before the gaze is cast again
GAZE_TURN_RAD = math.radians(0.5)  # or turns this far


@dataclass(frozen=True)
class Gaze:
    """The last gaze ray cast: from ``origin`` (world) along ``forward`` (unit) on the drawer of
    ``serial``, it found ``material`` ("" for none)."""

    origin: np.ndarray
    forward: np.ndarray
    serial: int
    material: str


@dataclass(frozen=True)
class SceneSource:
    """Where the callback finds the scene: the depsgraph to export, the render settings, the
    VR settings and (None without a running session) the session state for the viewer pose."""

    depsgraph: Callable[[], object]
    session_state: Callable[[], object | None] = lambda: None


def head_offset_m(view_from_world: np.ndarray, viewer: np.ndarray | None) -> float:
    """This eye's offset from the head's centre along its view-space +x, in metres: the HUD's
    ``eye_offset``. Blender's view matrix divides by base scale × navigation scale
    (wm_xr_draw.cc ``wm_xr_draw_matrices_create``), so view space is the headset's metres
    whatever those scales: the viewer's location taken into this eye's view space gives it
    directly (−x of the head centre seen from the eye). 0 while the viewer is unknown."""
    if viewer is None:
        return 0.0
    head_in_view = np.asarray(view_from_world, dtype=np.float64) @ np.array([*viewer[:3], 1.0])
    return float(-head_in_view[0] / head_in_view[3])


class XRPreview:
    """Everything the callback keeps between frames: one drawer for the scene, one state per
    eye. ``clock`` is injectable for the frame-budget tests."""

    def __init__(
        self,
        source: SceneSource,
        clock: Callable[[], float] = time.perf_counter,
        display: DisplayTransform | None = None,
    ):
        """``display``: the scene's view transform applied for Blender's overlay merge (the
        live session's callback); None draws scene-linear values (tests against the standalone
        renderer)."""
        self.source, self.clock, self.display = source, clock, display
        self._display_requested = False
        self.device = CachedUniformsDevice()
        self.drawer: ProgressiveDrawer | None = None
        self.cache = ExportCache()
        self.scene_dirty = True
        self.eyes: dict[str, HeadsetEye] = {}
        self.shared: SharedBudget | None = None  # the eyes' one budget (not the mirror's)
        self.gaze: Gaze | None = None  # the BTF material straight ahead, and from where
        self.ray_casts = 0  # gaze ray casts made (tests, the benchmark)
        self.mirror_s = 0.0  # seconds spent in mirror draws: kept out of the eyes' clock
        self.identifier = EyeIdentifier()
        self.error = ""  # why nothing is drawn (the panel shows it)
        self.messages: list[str] = []  # the export's warnings (a missing BTF drawn plain, …)
        self.last_eye: EyeId | None = None

    # --- scene changes ----------------------------------------------------------------------
    def invalidate(self, objects=(), materials=(), world: bool = False) -> None:
        """The depsgraph changed: the next draw re-exports (uploading only what changed)."""
        self.cache.invalidate(objects, materials, world)
        self.scene_dirty = True

    def depsgraph_updated(self, depsgraph) -> None:
        """``depsgraph_update_post``: re-export (and so restart the eyes) only when what is
        drawn changed (``live.drawn_data_changed``), not for the Scene's own properties (our
        exposure, read every frame) or a camera."""
        if drawn_data_changed(depsgraph.updates):
            self.invalidate(*changed_ids(depsgraph))

    def release(self) -> None:
        for eye in self.eyes.values():
            eye.release()
        self.eyes.clear()
        self.shared = None
        self.gaze = None
        if self.display is not None:
            self.display.release()
        if self.drawer is not None:
            self.drawer.release()
        self.drawer = None
        self.scene_dirty = True

    # --- one eye ------------------------------------------------------------------------------
    def draw_eye(self, clip_from_view, view_from_world, size: tuple[int, int]) -> None:
        """Draw the scene for one eye into the bound framebuffer (``size``: its pixels). A
        desktop mirror's draw (``_identify``) is drawn too, as a view of its own with
        ``MIRROR_LIGHTS_PER_FRAME``, and its time is kept out of the eyes' clock: the eyes'
        frame budget measures the intervals between their own frames without it. With a
        ``display`` whose LUT matches the scene's view settings, the eye is resolved into its
        view's float target and drawn through the view transform (``display.py``)."""
        start = self.clock()
        mirror = False
        try:
            mirror = self._draw(clip_from_view, view_from_world, size)
        finally:
            if mirror:
                self.mirror_s += self.clock() - start

    def eye_clock(self) -> float:
        """The eyes' clock: ``clock`` less the time spent in mirror draws."""
        return self.clock() - self.mirror_s

    def _draw(self, clip_from_view, view_from_world, size) -> bool:
        """``draw_eye``'s work; True when the draw was a mirror's (set before anything can
        fail, so that a failing mirror draw is kept out of the eyes' clock as well)."""
        depsgraph = self.source.depsgraph()
        scene = depsgraph.scene
        vr = vr_settings(scene)
        settings = replace(render_settings(scene), progressive=True)
        settings = replace(settings, lights_total=vr.lights_total)
        clip_from_view = np.asarray(clip_from_view, dtype=np.float64)
        view_from_world = np.asarray(view_from_world, dtype=np.float64)
        state = self.source.session_state()
        viewer = self._viewer(state)
        mirror, eye_id = self._identify(state, viewer, clip_from_view, view_from_world)
        self.last_eye = eye_id
        key = MIRROR if mirror else eye_id.key
        budget_s = vr.budget_s or DEFAULT_BUDGET_S  # Blender never says the display period
        eye = self.eyes.get(key)
        if eye is None:
            clock = self.clock if mirror else self.eye_clock
            shared = None
            if not mirror:  # both eyes: one budget decision per frame (gl/eye.py SharedBudget)
                if self.shared is None:
                    self.shared = SharedBudget(budget_s, clock)
                shared = self.shared
            eye = self.eyes[key] = HeadsetEye(self.device, budget_s, clock, shared=shared)
        k = eye.lights_this_frame(
            MIRROR_LIGHTS_PER_FRAME if mirror else vr.lights_per_frame, budget_s
        )

        framebuffer, viewport = gpu.state.active_framebuffer_get(), gpu.state.viewport_get()
        drawer = self._drawer(depsgraph, size)
        if drawer is None:
            return mirror
        _, restarted = eye.advance(
            drawer, size, settings, clip_from_view, view_from_world, k, not vr.show_world
        )
        if restarted and vr.show_hud:
            self._update_gaze(depsgraph, drawer.serial, inverse(view_from_world), viewer)
        view = eye.view

        # Making GPU objects (the first frame's offscreens, textures) may leave another
        # framebuffer bound and the viewport changed: draw into the eye's explicitly.
        with framebuffer.bind():
            gpu.state.viewport_set(*viewport)
            draw_state = EYE_OPAQUE if vr.show_world else EYE_OVER
            display = self.display
            if display is not None and display.matches(scene):
                # Resolved into the view's own float target, then through the view transform.
                with self.device.bound(view.output):
                    drawer.draw_resolved(view, vr.exposure, not vr.show_world, DEFAULT_STATE)
                gpu.state.viewport_set(*viewport)
                self.device.set_state(draw_state)
                display.draw(self.device.target_texture(view.output))
                self.device.set_state(DEFAULT_STATE)
            else:
                if display is not None:
                    self._request_display_update(scene)
                drawer.draw_resolved(view, vr.exposure, not vr.show_world, draw_state)
            if vr.show_hud:
                help_rows = wiimote_overlay.current_help() or ()
                bake = [drawer.bake_status.line()] if drawer.bake_status is not None else []
                eye.draw_hud(
                    clip_from_view,
                    head_offset_m(view_from_world, viewer),
                    self.gaze.material if self.gaze is not None else "",
                    [*bake, *(f"{a}: {b}" for a, b in help_rows)],
                    1.0,  # view space is metres whatever the base and navigation scales
                )
            gpu.state.blend_set("NONE")
            gpu.state.depth_test_set("NONE")
            gpu.state.depth_mask_set(True)
        self.error = ""  # drawn: whatever went wrong before is over
        return mirror

    def _request_display_update(self, scene) -> None:
        """The view settings changed (or were never baked): bake the LUT from a timer, outside
        drawing; until then the eyes are drawn untransformed."""
        if self._display_requested:
            return
        self._display_requested = True
        original = getattr(scene, "original", scene)
        name = original.name

        def bake():
            self._display_requested = False
            target = bpy.data.scenes.get(name)
            if target is not None and self.display is not None:
                try:
                    self.display.update(target)
                except Exception as exc:  # a failed bake leaves the eyes untransformed
                    self.error = f"BTF VR preview: the view transform failed: {exc}"
            return None

        bpy.app.timers.register(bake, first_interval=0.0)

    def _identify(self, state, viewer, clip_from_view, view_from_world) -> tuple[bool, EyeId]:
        """(whether this is a desktop mirror's draw, the eye). A mirror view (Blender's
        "Mirror VR Session") draws from the viewer pose itself: "mono" by the pose rule; before
        the pose is known (a session whose first eye was not drawn yet) a symmetric frustum
        is taken for the mirror, without touching the position rule's memory."""
        skew = float(clip_from_view[0, 2])
        if state is not None and viewer is None and abs(skew) <= SKEW_TOLERANCE:
            return True, EyeId(MIRROR, 0.0, "symmetric frustum, viewer pose unknown")
        eye_id = self.identifier.identify(view_from_world, clip_from_view, viewer)
        return eye_id.key == "mono" and state is not None, eye_id

    def _viewer(self, state) -> np.ndarray | None:
        """The viewer pose's location (world), None while unknown: no session, or the exact
        zero Blender's session state holds until its first eye was drawn (a mirror view drawn
        before that would otherwise be filed as an eye by its offset from the origin)."""
        if state is None:
            return None
        location = np.array(state.viewer_pose_location, dtype=np.float64)
        if not np.any(location):
            return None
        return location

    def _drawer(self, depsgraph, size) -> ProgressiveDrawer | None:
        if not self.scene_dirty and self.drawer is not None:
            return self.drawer
        try:
            scene = export_scene(depsgraph, *size, cache=self.cache, viewport=True)
            self.drawer = ProgressiveDrawer(self.device, scene, previous=self.drawer)
            remember_status(depsgraph.scene, self.drawer)  # for the Light Bake panel
            self.error, self.messages = "", list(scene.messages)
        except BTFMaterialsError as exc:  # bad input or a shader that does not compile
            if self.drawer is not None:
                self.drawer.release()
            self.drawer, self.error = None, str(exc)
            return None
        self.scene_dirty = False
        return self.drawer

    def _update_gaze(self, depsgraph, serial: int, world_from_view, viewer) -> None:
        """The HUD's material under the gaze, ray-cast again only when the head moved more
        than ``GAZE_MOVE_M`` or turned more than ``GAZE_TURN_RAD`` since the last cast, or the
        scene was re-exported: both eyes (and a mirror) share one cast from the head."""
        metre = float(np.linalg.norm(world_from_view[:3, 0]))  # world units per view metre
        origin = np.asarray(viewer if viewer is not None else world_from_view[:3, 3], float)
        forward = -world_from_view[:3, 2] / max(metre, 1e-12)
        gaze = self.gaze
        if (
            gaze is not None
            and gaze.serial == serial
            and np.linalg.norm(origin - gaze.origin) <= GAZE_MOVE_M * metre
            and float(np.dot(forward, gaze.forward)) >= math.cos(GAZE_TURN_RAD)
        ):
            return
        self.gaze = Gaze(origin, forward, serial, self._gaze_material(depsgraph, origin, forward))

    def _gaze_material(self, depsgraph, origin, forward) -> str:
        """The BTF material of the object straight ahead of ``origin`` along ``forward``."""
        self.ray_casts += 1
        hit, *_, obj, _ = depsgraph.scene.ray_cast(depsgraph, origin.tolist(), forward.tolist())
        if not hit or obj is None:
            return ""
        for slot in getattr(obj, "material_slots", ()):
            material = slot.material
            if material is not None and material.btf.enabled:
                return material.name
        return ""

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
_display = DisplayTransform()  # the scene's view transform, baked outside drawing


#: ``as_pointer()`` of the window the session was started from (None: not known).
_session_window_id: int | None = None


def remember_session_window(context) -> None:
    """At session start: the window it is started from. Blender draws the session from that
    window's scene and view layer (``wm_xr_session_root_window_or_fallback_get``, the
    ``session_root_win`` set by ``wm.xr_session_toggle``), not from the first window."""
    global _session_window_id
    window = getattr(context, "window", None)
    _session_window_id = window.as_pointer() if window is not None else None


def session_window(wm):
    """The session's window in ``wm`` as Blender finds it: the remembered one while it is still
    open, else the first window (Blender's fallback); None without windows (background)."""
    windows = list(wm.windows)
    for window in windows:
        if _session_window_id is not None and window.as_pointer() == _session_window_id:
            return window
    return windows[0] if windows else None


def session_source(window_manager: Callable[[], object] | None = None) -> SceneSource:
    """The live session's ``SceneSource``; ``window_manager`` (tests) returns the window manager
    (by default ``bpy.data.window_managers[0]``, the only one)."""
    get_wm = window_manager or (lambda: bpy.data.window_managers[0])

    def depsgraph():
        window = session_window(get_wm())
        if window is not None:
            return window.view_layer.depsgraph
        # Background Blender has no window (a script or test driving the callback itself):
        # there the context is a real one.
        return bpy.context.evaluated_depsgraph_get()

    def session_state():
        return get_wm().xr_session_state

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
            _preview = XRPreview(session_source(), display=_display)
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
        _preview.depsgraph_updated(depsgraph)
        _update_display(scene)


def _update_display(scene) -> None:
    """The view transform's LUT for ``scene`` (a no-op while its view settings are unchanged);
    a failure is printed once and leaves the eyes untransformed."""
    try:
        _display.update(scene)
    except Exception:
        traceback.print_exc()


@bpy.app.handlers.persistent
def _on_session_start(*_args) -> None:
    """A new session: fresh per-eye state, the scene exported again on the first frame."""
    global _preview
    if _preview is not None:
        _preview.release()
    _preview = None
    remember_session_window(bpy.context)
    _draw_before_controllers()
    if getattr(bpy.context, "scene", None) is not None:
        _update_display(bpy.context.scene)
    if not bpy.app.timers.is_registered(_release_when_stopped):
        bpy.app.timers.register(_release_when_stopped, first_interval=1.0)


def _draw_before_controllers() -> None:
    """Put our draw callback at the end of the 'XR' region's list now, before the session
    starts: Blender appends its controller stand-ins' and aim rays' callback when the session
    sets up its controller data (``wm_xr_session_controller_data_populate``, after this
    handler), so they draw over our opaque image. Registered once at add-on start, ours would
    already come first; enabled during a running session it would come last and hide them."""
    global _handler
    if _handler is None:
        return
    bpy.types.SpaceView3D.draw_handler_remove(_handler, "XR")
    _handler = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), "XR", "POST_VIEW")


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
