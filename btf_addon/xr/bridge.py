"""The XTAL bridge: our renderer driving a headset straight through OpenXR, with its own frame
loop. The API the Blender operator (blender/vr/xtal_bridge.py) and the CLI (``bridge``) use.

Threads: ``start``, ``run_frame`` and ``close`` run on ONE thread, the one that owns the EGL
context (OpenGL contexts are current per thread). ``set_scene``, ``request_stop``, ``status``
and ``pop_edits`` may be called from any other thread (Blender's main thread): they only
touch values under a lock, taken by the frame loop at its next frame.

Per eye a ``gl/eye.HeadsetEye``, the same object Blender's VR session callback keeps (one
``ViewAccumulation`` over the one ``ProgressiveDrawer``): the lights of
``render/lighting.frame_lights``, K of them per frame fixed or from the eyes' one
``SharedBudget`` (one decision per frame, the same K for both eyes)
(budget: the runtime's predicted display period unless set, the profile's refresh before the
runtime says), a restart when the eye's matrices moved (``view_moved``), the resolve drawn into
the acquired swapchain image (sizes equal: the resolve fetches at the fragment's own
coordinates) with GL_FRAMEBUFFER_SRGB on for an sRGB swapchain (our output is linear), and the
HUD quad fixed to the head.

Where the scene is (``BridgeSettings.placement``):
- ``"space"`` (default): the runtime's reference space (STAGE, else LOCAL) IS the scene's world:
  a located pose is used as the eye's world pose as it is, so the images are exactly "the scene
  seen from the poses the runtime reported" (what an independent render of a capture takes).
  OpenXR spaces are +y up and Blender's world +z up: a real headset then sees the scene lying
  on its side, unless its poses are expressed for that (a test runtime's scripted head).
- ``"camera"``: as Blender's VR session places a headset by default (base pose "Scene Camera",
  no absolute tracking): the viewer's first located head position (the mid-point of the eyes)
  goes to the scene camera's location, the space's −z (forward) to the camera's heading about
  the world's +Z, its +y to the world's +Z; the camera's pitch and roll are not used (a tilted
  world makes people sick). For wearing a headset.
Captures record ``world_from_space`` and each eye's matrices either way.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..core.interrupts import deferred
from ..gl.drawer import ProgressiveDrawer
from ..gl.eye import HeadsetEye, HeadsetSettings, SharedBudget
from ..render.headsets import profile as headset_profile
from ..render.headsets import projection_from_fov
from ..render.settings import RenderSettings
from ..scene.scene import Scene
from .controls import ControlMap
from .errors import (
    BridgeError,
    NoHeadsetError,
    NoRuntimeError,
    SessionLostError,
    UnsupportedRuntimeError,
)
from .views import GL_FRAMEBUFFER_SRGB

__all__ = [
    "BridgeError",
    "BridgeSettings",
    "BridgeStatus",
    "ControlMap",
    "NoHeadsetError",
    "NoRuntimeError",
    "SessionLostError",
    "UnsupportedRuntimeError",
    "XRBridge",
    "run_bridge",
    "world_from_space",
]

log = logging.getLogger(__name__)

EYES = ("left", "right")
IDLE_WAIT_S = 0.005  # between polls while the session is not running yet
PLACEMENTS = ("space", "camera")
WARMUP_FRAMES = 3  # the first frames' times are always explained (status, log, CLI)
SLOW_WORK_S = 0.1  # a later frame with this much compiling/uploading is explained too
START_TIMEOUT_S = 30.0  # run_bridge: no frame by then → the session never started
STOP_TIMEOUT_S = 10.0  # run_bridge: the runtime never ended the session after the request
# OpenXR's spaces are +y up, Blender's world +z up: (x, y, z) → (x, −z, y).
ZUP_FROM_YUP = np.array(
    [[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]], dtype=np.float64
)


@dataclass(frozen=True)
class BridgeSettings(HeadsetSettings):
    """The eyes' settings of Blender's VR session too (``HeadsetSettings``: lights, frame
    budget, exposure, HUD), and the bridge's own: ``resolution_scale``: times the runtime's
    recommended eye size (clamped to its maximum); ``profile``: the headset profile
    (render/headsets.py) used for what the runtime does not report; ``capture_dir``: write
    each submitted eye image (xr/capture.py); ``converge``: hold the first located pose
    (submitted as drawn) for the whole run, so the lights accumulate until all are in and the
    image then stays converged; ``placement``: where the runtime's space lies in the scene
    (module docstring: "space", the default, or "camera")."""

    resolution_scale: float = 1.0
    profile: str = "generic-2016x2240"
    capture_dir: Path | None = None
    converge: bool = False
    placement: str = "space"  # "space" or "camera" (module docstring)


@dataclass(frozen=True)
class BridgeStatus:
    """A snapshot for the operator's header and the CLI: ``runtime`` name; ``state`` (the
    session's, or "not started"/"ended"); ``fps`` (submitted frames per second, smoothed);
    per eye ``lights_per_frame`` (K) and ``lights_done``; ``eye_size`` (w, h); ``values_from``:
    "runtime" or "profile <name>" (then ``message`` says which values); ``message``;
    ``warmup``: why the start and the first frames took long, one line each ("start: 0.56 s
    (OpenXR session and GL context 0.47 s, shader compile 0.08 s)", "frame 1: 0.18 s (first
    draws 0.10 s)": parts of 5 ms or more, xr/bridge_device.py), and any later frame slowed by
    compiling or uploading (a new scene); the latest also leads ``message`` while the run
    warms up (before the first line: "warming up: opening the OpenXR session", "warming up:
    compiling shaders, uploading the scene"). ``bake``: the light bake's status line
    (render/bake_playback.py: which objects show baked light, which are stale); empty without
    a bake."""

    runtime: str = ""
    state: str = "not started"
    fps: float | None = None
    lights_per_frame: dict[str, int] = field(default_factory=dict)
    lights_done: dict[str, int] = field(default_factory=dict)
    eye_size: tuple[int, int] = (0, 0)
    values_from: str = "runtime"
    message: str = ""
    frames: int = 0
    warmup: tuple[str, ...] = ()
    bake: str = ""


def world_from_space(world_from_camera: np.ndarray, head_in_space: np.ndarray) -> np.ndarray:
    """(4, 4) float64: the reference space placed in the scene (module docstring): the head
    position ``head_in_space`` ((3,), the space's coordinates) lands on the camera's location,
    the space's forward (−z) on the camera's heading about world +Z."""
    cam = np.asarray(world_from_camera, dtype=np.float64)
    forward = -cam[:3, 2]
    if math.hypot(forward[0], forward[1]) < 1e-6:  # looking straight down/up: use its up
        forward = cam[:3, 1] * np.sign(-forward[2] or 1.0)
    heading = math.atan2(-forward[0], forward[1])  # 0: looking along +Y (Blender's default)
    c, s = math.cos(heading), math.sin(heading)
    base = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=np.float64)
    base[:3, 3] = cam[:3, 3]
    recentre = np.eye(4)
    recentre[:3, 3] = -np.asarray(head_in_space, dtype=np.float64)
    return base @ ZUP_FROM_YUP @ recentre


class XRBridge:
    """The bridge over one scene (module docstring). ``controls``: the controller vocabulary
    (xr/controls.py ``ControlMap``; None: no controller input); ``clock``: seconds,
    injectable."""

    def __init__(
        self,
        scene: Scene,
        render_settings: RenderSettings,
        settings: BridgeSettings,
        controls: ControlMap | None = None,
        clock=time.perf_counter,
    ):
        self.profile = headset_profile(settings.profile)  # ValueError for an unknown name
        if settings.lights_total < 1:
            raise ValueError(f"lights_total must be >= 1, got {settings.lights_total}")
        if settings.lights_per_frame is not None and settings.lights_per_frame < 1:
            raise ValueError(f"lights_per_frame must be >= 1, got {settings.lights_per_frame}")
        if settings.placement not in PLACEMENTS:
            raise ValueError(f"placement must be one of {PLACEMENTS}, got {settings.placement!r}")
        self.settings = settings
        self.render_settings = replace(
            render_settings, lights_total=settings.lights_total, progressive=True
        )
        self.clock = clock
        self._scene = scene
        self._lock = threading.Lock()
        self._pending_scene: Scene | None = None
        self._stop = False
        self._edits: list = []  # controllers.actions.Edit (made by the ControlMap)
        self.control_map = controls
        self._status = BridgeStatus(values_from="runtime")
        self.gl = self.session = self.device = self.drawer = self.controls = None
        self.eyes: list[HeadsetEye] = []
        self.budget: SharedBudget | None = None
        self.held: list = []  # per eye, the LocatedView held while converging
        self.world_from_space: np.ndarray | None = None
        self.frames = 0  # submitted frames
        self.ended = False
        self._fps: float | None = None
        self._last_frame_t: float | None = None
        self._message = ""
        self.warmup: list[str] = []  # BridgeStatus.warmup
        self._warming: str | None = None  # what leads the status message while warming up

    # --- thread-safe API ----------------------------------------------------------------------
    @property
    def status(self) -> BridgeStatus:
        with self._lock:
            return self._status

    def set_scene(self, scene: Scene) -> None:
        """Draw ``scene`` from the next frame on (uploads of unchanged parts are kept)."""
        with self._lock:
            self._pending_scene = scene

    def request_stop(self) -> None:
        """End the session: xrRequestExitSession at the next frame; ``run_frame`` then
        returns False once the runtime has ended it."""
        with self._lock:
            self._stop = True

    def pop_edits(self) -> list:
        """The controller edits since the last call (oldest first): ``controllers.actions.
        Edit``s as the ControlMap makes them."""
        with self._lock:
            edits, self._edits = self._edits, []
        return edits

    # --- the frame-loop thread ----------------------------------------------------------------
    def start(self) -> None:
        """Context, OpenXR session, drawer. Raises BridgeError subclasses (and releases what
        was made)."""
        from .bridge_device import BridgeDevice
        from .session import XRSession

        try:
            started = self.clock()
            self._warming = "warming up: opening the OpenXR session"
            self._publish()
            size = (self.profile.eye_width, self.profile.eye_height)
            self.session = XRSession(self.settings.resolution_scale, size)
            self.session.open()
            opened = self.clock()
            self.gl = self.session.gl
            self.device = BridgeDevice(self.gl.ctx, self.clock)
            self._warming = "warming up: compiling shaders, uploading the scene"
            self._publish()
            self.drawer = ProgressiveDrawer(self.device, self._scene)
            self._explain(
                "start", self.clock() - started, {"OpenXR session and GL context": opened - started}
            )
            budget = self.settings.budget_s or self.profile.frame_budget_s
            # One budget decision per frame, the same K for both eyes (gl/eye.py SharedBudget).
            self.budget = SharedBudget(budget, self.clock)
            self.eyes = [HeadsetEye(self.device, budget, self.clock, self.budget) for _ in EYES]
            self.held = [None] * len(EYES)
            self._start_controls()
        except BaseException:
            self.close()
            raise
        self._publish()

    def _start_controls(self) -> None:
        from .controls import Controls

        if self.control_map is None:
            return
        try:
            s = self.session
            self.controls = Controls(s.xr, s.instance, s.session, self.control_map)
        except Exception as exc:  # controllers are optional: say so, draw anyway
            self.controls = None
            self._message = f"no controller input ({exc})"
            log.warning("controller actions unavailable: %s", exc)

    def run_frame(self) -> bool:
        """Poll the runtime's events and, while the session runs, render and submit one
        frame. False once the session has ended (then ``close``)."""
        if self.ended:
            return False
        session = self.session
        with self._lock:
            stop = self._stop
        if stop:
            session.request_exit()
        try:
            session.poll_events()
        except SessionLostError:
            self._set_state("LOSS_PENDING")
            raise
        if session.exiting:
            self.ended = True
            self._warming = None
            self._set_state("ended")
            return False
        if not session.running:
            self._publish()
            time.sleep(IDLE_WAIT_S)
            return True
        with self._lock:  # taken only now: a scene set before the session runs is kept
            scene, self._pending_scene = self._pending_scene, None
        if scene is not None:
            self.drawer = ProgressiveDrawer(self.device, scene, previous=self.drawer)
            self._scene = scene
        frame_started = self.clock()
        info = session.frame(self._draw_eye)
        if info.submitted:
            self._explain_frame(self.frames + 1, self.clock() - frame_started)
            if self.settings.capture_dir is not None:
                self._capture(info)
            self.frames += 1
            now = self.clock()
            if self._last_frame_t is not None and now > self._last_frame_t:
                fps = 1.0 / (now - self._last_frame_t)
                self._fps = fps if self._fps is None else 0.8 * self._fps + 0.2 * fps
            self._last_frame_t = now
        if self.controls is not None:
            try:
                edits = self.controls.poll(self.clock(), info.period_s)
            except Exception as exc:
                log.warning("controller actions failed, ignored from now on: %s", exc)
                self.controls, self._message = None, f"controller input stopped ({exc})"
                edits = []
            if edits:
                with self._lock:
                    self._edits.extend(edits)
        self._publish()
        return True

    # --- warm-up (issue 30 item 7) ------------------------------------------------------------
    def _explain(self, what: str, seconds: float, before: dict[str, float] | None = None) -> None:
        """One line of ``warmup``: ``what`` took ``seconds``, of which the device's compiling,
        uploading and first draws (xr/bridge_device.py) and ``before``'s parts; logged and
        leading the status message while the run warms up."""
        parts = {**(before or {}), **self.device.take_spent()}
        detail = ", ".join(f"{kind} {t:.2f} s" for kind, t in parts.items() if t >= 0.005)
        line = f"{what}: {seconds:.2f} s" + (f" ({detail})" if detail else "")
        self.warmup.append(line)
        self._warming = f"warming up: {line}"
        log.info("%s", line)

    def _explain_frame(self, number: int, seconds: float) -> None:
        """The first frames always; a later one when compiling or uploading slowed it."""
        slowed = sum(self.device.spent.values()) >= SLOW_WORK_S
        if number <= WARMUP_FRAMES or slowed:
            self._explain(f"frame {number}", seconds)
        else:
            self.device.take_spent()
        if number >= WARMUP_FRAMES and not slowed:  # warmed up: the status message moves on
            self._warming = None

    # --- one eye ------------------------------------------------------------------------------
    def _draw_eye(self, index: int, located, chain, framebuffer):
        eye = self.eyes[index]
        settings = self.settings
        if self.world_from_space is None:
            self._place_space()
        if settings.converge:
            # The first located pose for the whole run: the lights accumulate until all N are
            # in, and every later frame is that converged image (what a check compares).
            if self.held[index] is None:
                self.held[index] = located
            view_used = self.held[index]
        else:
            view_used = located
        k = eye.lights_this_frame(
            settings.lights_per_frame, settings.budget_s or self.session.period_s
        )

        view_from_world, clip_from_view = self.matrices(view_used)
        eye.advance(
            self.drawer,
            (chain.width, chain.height),
            self.render_settings,
            clip_from_view,
            view_from_world,
            k,
        )
        view = eye.view

        framebuffer.use()  # the acquired swapchain image (viewport: the whole image)
        self._resolve_into(eye, index, view, clip_from_view)
        return view_used

    def _resolve_into(self, eye: HeadsetEye, index: int, view, clip_from_view) -> None:
        ctx = self.gl.ctx
        srgb = self.session.srgb
        if srgb:  # our output is linear: the hardware encodes into the sRGB image
            ctx.enable_direct(GL_FRAMEBUFFER_SRGB)
        try:
            self.drawer.draw_resolved(view, self.settings.exposure)
            if self.settings.show_hud:
                offset, material = self._eye_offset(index), self._material_name()
                eye.draw_hud(clip_from_view, offset, material, self._bake_line())
        finally:
            if srgb:
                ctx.disable_direct(GL_FRAMEBUFFER_SRGB)

    def _bake_line(self) -> tuple[str, ...]:
        """The light bake's status for the HUD and the status (none without a bake)."""
        status = self.drawer.bake_status if self.drawer is not None else None
        return (status.line(),) if status is not None else ()

    def _eye_offset(self, index: int) -> float:
        """∓IPD/2: the eyes' distance as located (the profile's IPD before two are known)."""
        views = self.session.located
        ipd = self.profile.ipd_m
        if views and len(views) == 2:
            ipd = float(np.linalg.norm(np.subtract(views[0].position, views[1].position)))
        return (-0.5 if index == 0 else 0.5) * ipd

    def _material_name(self) -> str:
        names = {m.name for m in self.drawer.scene.materials if getattr(m, "name", "")}
        return next(iter(names)) if len(names) == 1 else "XTAL bridge"

    # --- geometry -----------------------------------------------------------------------------
    def near_far(self) -> tuple[float, float]:
        cam = self._scene.camera
        near, far = float(cam.clip_start), float(cam.clip_end)
        return (near, far) if 0 < near < far else (0.05, 100.0)

    def _place_space(self) -> None:
        """``world_from_space``: identity ("space"), or from the first located pair of views
        ("camera"; the session locates both before it draws either)."""
        if self.settings.placement == "space":
            self.world_from_space = np.eye(4)
            return
        views = self.session.located
        head = np.mean([v.position for v in views], axis=0)
        self.world_from_space = world_from_space(self._scene.camera.world_from_camera, head)

    def matrices(self, located) -> tuple[np.ndarray, np.ndarray]:
        """(view_from_world, clip_from_view) (4, 4) float64 for a located view."""
        world_from_eye = self.world_from_space @ located.space_from_eye()
        near, far = self.near_far()
        return np.linalg.inv(world_from_eye), projection_from_fov(located.fov, near, far)

    # --- status, captures, shutdown -----------------------------------------------------------
    def _set_state(self, state: str) -> None:
        self._publish(state)

    def _publish(self, state: str | None = None) -> None:
        session = self.session
        eyes = {
            name: eye
            for name, eye in zip(EYES, self.eyes, strict=False)
            if eye.view is not None and eye.view.state is not None
        }
        from_profile = list(session.from_profile) if session is not None else []
        if self.settings.budget_s is None and session is not None and not session.period_s:
            from_profile.append(f"frame budget {self.profile.refresh_hz:g} Hz")
        message = self._message
        if from_profile:
            used = ", ".join(from_profile)
            message = f"{used} from profile {self.profile.name}" + (
                f"; {message}" if message else ""
            )
        if self._warming:  # first: what the user waits for
            message = self._warming + (f"; {message}" if message else "")
        status = BridgeStatus(
            runtime=session.runtime_name if session is not None else "",
            state=state or (session.state if session is not None else "not started"),
            fps=self._fps,
            lights_per_frame={n: int(e.view.state.per_pass) for n, e in eyes.items()},
            lights_done={n: int(e.view.state.done) for n, e in eyes.items()},
            eye_size=(
                (session.swapchains[0].width, session.swapchains[0].height)
                if session is not None and session.swapchains
                else (0, 0)
            ),
            values_from=f"profile {self.profile.name}" if from_profile else "runtime",
            message=message,
            frames=self.frames,
            warmup=tuple(self.warmup),
            bake="".join(self._bake_line()),
        )
        with self._lock:
            self._status = status

    def _capture(self, info) -> None:
        from .capture import write_frame

        session = self.session
        near, far = self.near_far()
        eyes = []
        for index, (name, located) in enumerate(zip(EYES, info.views, strict=True)):
            eye = self.eyes[index]
            view = eye.view
            view_from_world, clip_from_view = self.matrices(located)
            with self.device.bound(view.output):  # the same draws, into a float target
                self.drawer.draw_resolved(view, self.settings.exposure)
                if self.settings.show_hud and eye.hud_image is not None:
                    eye.draw_hud_image(clip_from_view, self._eye_offset(index))
            meta = {
                "display_time_ns": info.display_time,
                "runtime": session.runtime_name,
                "pose": [*located.position, *located.orientation],
                "fov": [
                    located.fov.angle_left,
                    located.fov.angle_right,
                    located.fov.angle_up,
                    located.fov.angle_down,
                ],
                "reference_space": session.space_type,
                "world_from_space": self.world_from_space,
                "view_from_world": view_from_world,
                "clip_from_view": clip_from_view,
                "near": near,
                "far": far,
                "lights_done": view.state.done,
                "lights_total": view.state.total,
                "lights_this_frame": eye.drawn,
                "exposure": self.settings.exposure,
                "eye_size": [view.width, view.height],
                "format": session.format,
                "values_from": self.status.values_from,
            }
            eyes.append((name, view.read(), meta))
        write_frame(Path(self.settings.capture_dir), self.frames, eyes)

    def close(self) -> None:
        """Release everything in reverse order (idempotent; safe after a failed start, and
        after an interrupt at any point of a frame): the controllers, the open frame and the
        session ended (xr/session.py ``stop``), GL finished, our GL objects, then the OpenXR
        chain and the context. Ctrl-C and SIGTERM are held back meanwhile and delivered when
        all is released (core/interrupts.py)."""
        with deferred():
            self._close()
            if not self.ended:
                self._publish("closed")

    def _close(self) -> None:
        if self.controls is not None:
            _quietly(self.controls.close)
            self.controls = None
        session = self.session
        if session is not None:
            session.stop()
            session.finish_gl()
        elif self.gl is not None and self.gl.context is not None:
            _quietly(self.gl.make_current)
        for eye in self.eyes:
            _quietly(eye.release)
        if self.drawer is not None:
            _quietly(self.drawer.release)
            self.drawer = None
        if self.device is not None:
            _quietly(self.device.close)
            self.device = None
        if session is not None:
            session.close()  # glFinish, swapchains, session, instance; the GL context last
        self.gl = None


def _quietly(fn, *args) -> None:
    try:
        fn(*args)
    except Exception as exc:  # shutdown goes on whatever one step says
        log.warning("%s during shutdown: %s", getattr(fn, "__qualname__", fn), exc)


def run_bridge(
    scene: Scene,
    render_settings: RenderSettings,
    settings: BridgeSettings,
    frames: int | None = None,
    controls: ControlMap | None = None,
    stop_check: Callable[[], None] | None = None,
) -> BridgeStatus:
    """Start, run ``frames`` submitted frames (None: until the runtime ends the session),
    ask the runtime to end the session, let it end cleanly, close. Controller edits
    (``controls``) are logged at INFO. ``stop_check``: called after every frame, raises to
    stop (the CLI's re-raises a Ctrl-C or SIGTERM that a callback in the runtime or the driver
    swallowed); the bridge closes either way. Returns the last status; raises BridgeError
    subclasses."""
    bridge = XRBridge(scene, render_settings, settings, controls)
    bridge.start()
    started, stop_asked = time.monotonic(), None
    try:
        while bridge.run_frame():
            if stop_check is not None:
                stop_check()
            for edit in bridge.pop_edits():  # nothing applies them here: logged (CLI -v)
                log.info("controller: %s", edit)
            if frames is not None and bridge.frames >= frames and stop_asked is None:
                bridge.request_stop()
                stop_asked = time.monotonic()
            now = time.monotonic()
            if bridge.frames == 0 and now - started > START_TIMEOUT_S:
                raise SessionLostError(
                    f"the runtime {bridge.status.runtime!r} did not start the session within "
                    f"{START_TIMEOUT_S:g} s (state {bridge.session.state}): is the headset "
                    "awake and its display on?"
                )
            if stop_asked is not None and now - stop_asked > STOP_TIMEOUT_S:
                log.warning(
                    "the runtime did not end the session within %g s of the request; "
                    "closing it anyway",
                    STOP_TIMEOUT_S,
                )
                break
    finally:
        bridge.close()
    if stop_check is not None:
        stop_check()
    return bridge.status
