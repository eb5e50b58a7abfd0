"""The OpenXR resources of the bridge as a chain, released in reverse: instance → system →
session (OpenGL through EGL) → reference space → one swapchain per eye; the session's state
machine in one place (``poll_events``) and the frame loop (``frame``: wait → begin → locate
views → per eye acquire/wait, draw, release → end with a projection layer).

pyopenxr is imported as ``xr`` with an absolute import: inside this package (``btf_addon.xr``)
``import xr`` still names the top-level pyopenxr (imports are absolute), and the module is
bound as ``openxr`` here so that the two cannot be confused when reading.

Every OpenXR call's failure becomes a ``BridgeError`` subclass (xr/errors.py) whose message
names the call; results that are successes with a qualifier (``XR_FRAME_DISCARDED``,
``XR_SESSION_LOSS_PENDING``, ``XR_EVENT_UNAVAILABLE``: pyopenxr raises them) are handled where
they occur.

Interrupts (issue 30 item 1): every change of the protocol's state — ``open``, the events,
one ``frame`` from xrWaitFrame to xrEndFrame, ``close`` — runs with Ctrl-C and SIGTERM held
back (core/interrupts.py), so the flags below always say what the runtime holds; only
``draw_eye`` takes a Ctrl-C at once, and ``frame`` then releases the image and ends the frame
with no layers before the interrupt leaves it. ``close`` brings any state to the end the spec
allows, in order: release an acquired image, end a begun frame (no layers), request exit and
end the session once the runtime says STOPPING (the frame loop kept going with empty frames,
at most ``STOP_TIMEOUT_S``), glFinish, then release our framebuffers of the swapchain images and
destroy swapchains, space, session, instance, and last the GL context.
"""

from __future__ import annotations

import ctypes
import json
import logging
import os
import sys
import time
from collections.abc import Callable

from ..core.interrupts import allowed, deferred
from .desktop_gl import desktop_kind, make_context
from .errors import (
    BridgeError,
    NoHeadsetError,
    NoRuntimeError,
    SessionLostError,
    UnsupportedRuntimeError,
)
from .views import (
    FORMATS,
    EyeSwapchain,
    FrameInfo,
    LocatedView,
    located_view,
    set_pose,
    swapchain_size,
)

log = logging.getLogger(__name__)

STOP_TIMEOUT_S = 2.0  # close(): how long the runtime may take to end a session we asked to end
APP_NAME = "BTF Materials XTAL bridge"
KHR_OPENGL = "XR_KHR_opengl_enable"
MNDX_EGL = "XR_MNDX_egl_enable"


def _openxr():
    try:
        import xr as openxr  # pyopenxr, the top-level package (see the module docstring)
    except ImportError as exc:
        raise NoRuntimeError(
            f"the OpenXR loader is missing: pyopenxr does not import ({exc}); "
            "pip install pyopenxr (it bundles the loader)"
        ) from None
    return openxr


def manifest_state(manifest: str) -> str:
    """What is wrong with a runtime manifest, or that it looks usable: the file, its JSON, and
    the runtime library it names (``runtime.library_path``; the OpenXR loader resolves a
    relative path against the manifest's folder, and leaves a bare file name to the system's
    library search)."""
    if not os.path.isfile(manifest):
        return "does not exist"
    try:
        with open(manifest, encoding="utf-8") as f:
            library = json.load(f)["runtime"]["library_path"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return f"exists, but is not a runtime manifest with runtime.library_path: {exc}"
    if not isinstance(library, str) or not library:
        return "exists, but its runtime.library_path is empty"
    if os.sep not in library and "/" not in library:
        return f"exists; its runtime library {library} is left to the system's library search"
    path = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(manifest)), library))
    if not os.path.isfile(path):
        return f"exists, but the runtime library it names, {path}, does not exist"
    return f"exists; runtime library {path}"


def _runtime_hint() -> str:
    manifest = os.environ.get("XR_RUNTIME_JSON")
    if manifest:
        return f"XR_RUNTIME_JSON={manifest} ({manifest_state(manifest)})"
    return (
        "XR_RUNTIME_JSON is not set and no active runtime is registered "
        "(Linux: ~/.config/openxr/1/active_runtime.json or /etc/xdg/openxr/1/; Windows: the "
        "ActiveRuntime registry value); start your headset's runtime (SteamVR, Monado, the "
        "vendor's) and make it the active OpenXR runtime"
    )


class XRSession:
    """instance → GL context (xr/desktop_gl.py: EGL where the runtime offers
    XR_MNDX_egl_enable) → system → session → space → swapchains.

    ``open()`` makes them all (BridgeError subclasses when something is missing); ``frame``
    runs one frame; ``close()`` releases in reverse. One thread: the one the context is current
    on (OpenGL binding rule: the runtime uses the app's context during the graphics calls)."""

    def __init__(
        self,
        resolution_scale: float = 1.0,
        fallback_size: tuple[int, int] = (2016, 2240),
        app_name: str = APP_NAME,
    ):
        """``fallback_size``: per-eye pixels used where the runtime recommends none (0×0),
        from the bridge's headset profile; ``from_profile`` then lists it. ``gl``: the
        OpenGL context, made by ``open`` once the runtime's bindings are known."""
        if not resolution_scale > 0:
            raise ValueError(f"resolution scale must be positive, got {resolution_scale}")
        self.xr = _openxr()
        self.gl = None
        self.binding_kind = ""
        self.resolution_scale = float(resolution_scale)
        self.app_name = app_name
        self.fallback_size = fallback_size
        self.from_profile: list[str] = []  # what came from the profile, not the runtime
        self.instance = self.system_id = self.session = self.space = None
        self.runtime_name = ""
        self.system_name = ""
        self.recommended: list[tuple[int, int]] = []
        self.swapchains: list[EyeSwapchain] = []
        self.format = 0
        self.srgb = False
        self.space_type = ""
        self.blend_mode = None
        self.state = "IDLE"
        self.running = False  # between xrBeginSession and xrEndSession
        self.exiting = False  # EXITING seen: the loop is over
        self.exit_requested = False
        self.lost = False  # the runtime lost the session: nothing more to end, only destroy
        self.frame_begun = False  # xrBeginFrame succeeded, xrEndFrame not yet
        self._display_time = 0  # the last xrWaitFrame's predicted display time
        self.period_s: float | None = None
        self.located: tuple[LocatedView, ...] = ()
        self._binding = None  # kept alive while the session exists
        self._layer_keepalive: list = []

    # --- creation ---------------------------------------------------------------------------
    def open(self) -> None:
        """Make the chain, with interrupts held back: a Ctrl-C meanwhile lands after the
        chain is whole (or released, on an error)."""
        with deferred():
            try:
                self._create_instance()
                self._get_system()
                self._check_views()
                self._create_session()
                self._create_space()
                self._create_swapchains()
            except BaseException:
                self.close()
                raise

    def _call(self, name: str, fn: Callable, *args, error=UnsupportedRuntimeError, hint=""):
        """Run an OpenXR call; a failure → ``error`` naming the call (and the lost-session
        results → SessionLostError)."""
        openxr = self.xr
        try:
            return fn(*args)
        except (openxr.SessionLostError, openxr.InstanceLostError) as exc:
            self.lost = True
            raise SessionLostError(
                f"{name}: the runtime lost the session ({type(exc).__name__}); restart the "
                "runtime/headset and the bridge"
            ) from None
        except openxr.XrException as exc:
            if isinstance(exc, BridgeError):
                raise
            detail = f"{name} failed: {type(exc).__name__} ({exc})"
            raise error(f"{detail}{'; ' + hint if hint else ''}") from None

    def _create_instance(self) -> None:
        openxr = self.xr
        offered = self._call(
            "xrEnumerateInstanceExtensionProperties",
            openxr.enumerate_instance_extension_properties,
            error=NoRuntimeError,
            hint=f"no OpenXR runtime found: {_runtime_hint()}",
        )
        names = {p.extension_name.decode() if isinstance(p.extension_name, bytes)
                 else str(p.extension_name) for p in offered}  # fmt: skip
        if KHR_OPENGL not in names:
            raise UnsupportedRuntimeError(
                f"the OpenXR runtime offers no OpenGL graphics binding ({KHR_OPENGL}); the "
                f"bridge draws with OpenGL. Offered: {', '.join(sorted(names)) or 'none'}"
            )
        if MNDX_EGL in names:
            self.binding_kind = "egl"
        else:
            self.binding_kind = desktop_kind() or ""
            if not self.binding_kind:
                raise UnsupportedRuntimeError(
                    f"the OpenXR runtime offers {KHR_OPENGL} but not {MNDX_EGL}, and there is "
                    "no desktop here for its WGL/GLX binding: the bridge draws headless only "
                    f"through {MNDX_EGL} (Monado offers it)"
                )
            log.warning(
                "the runtime offers no %s: using a hidden window's %s context (untested)",
                MNDX_EGL,
                self.binding_kind.upper(),
            )
        enabled = [KHR_OPENGL] + ([MNDX_EGL] if self.binding_kind == "egl" else [])
        info = openxr.InstanceCreateInfo(
            application_info=openxr.ApplicationInfo(
                application_name=self.app_name,
                application_version=1,
                engine_name="btf_materials",
                engine_version=1,
            ),
            enabled_extension_names=enabled,
        )
        self.instance = self._call(
            "xrCreateInstance",
            openxr.create_instance,
            info,
            error=NoRuntimeError,
            hint=_runtime_hint(),
        )
        props = self._call("xrGetInstanceProperties", openxr.get_instance_properties, self.instance)
        name = props.runtime_name
        self.runtime_name = name.decode() if isinstance(name, bytes) else str(name)
        try:
            self.gl = make_context(self.binding_kind)
        except (RuntimeError, OSError, ImportError) as exc:
            raise UnsupportedRuntimeError(
                f"no OpenGL 3.3 context for the {self.binding_kind.upper()} binding: {exc}"
            ) from None

    def _get_system(self) -> None:
        openxr = self.xr
        try:
            self.system_id = openxr.get_system(
                self.instance,
                openxr.SystemGetInfo(form_factor=openxr.FormFactor.HEAD_MOUNTED_DISPLAY),
            )
        except (openxr.FormFactorUnavailableError, openxr.FormFactorUnsupportedError) as exc:
            raise NoHeadsetError(
                f"the OpenXR runtime {self.runtime_name!r} has no head-mounted display "
                f"({type(exc).__name__}): connect and switch on the headset (and start its "
                "tracking software), then try again"
            ) from None
        except openxr.XrException as exc:
            raise NoHeadsetError(f"xrGetSystem failed: {type(exc).__name__} ({exc})") from None
        props = self._call(
            "xrGetSystemProperties", openxr.get_system_properties, self.instance, self.system_id
        )
        name = props.system_name
        self.system_name = name.decode() if isinstance(name, bytes) else str(name)

    def _check_views(self) -> None:
        openxr = self.xr
        stereo = openxr.ViewConfigurationType.PRIMARY_STEREO
        types = self._call(
            "xrEnumerateViewConfigurations",
            openxr.enumerate_view_configurations,
            self.instance,
            self.system_id,
        )
        if stereo.value not in [int(t) for t in types]:
            raise UnsupportedRuntimeError(
                f"the runtime {self.runtime_name!r} offers no PRIMARY_STEREO view "
                "configuration (two views, one per eye)"
            )
        views = self._call(
            "xrEnumerateViewConfigurationViews",
            openxr.enumerate_view_configuration_views,
            self.instance,
            self.system_id,
            stereo,
        )
        if len(views) != 2:
            raise UnsupportedRuntimeError(
                f"the runtime {self.runtime_name!r} reports {len(views)} views for "
                "PRIMARY_STEREO; the bridge draws exactly two (one per eye)"
            )
        self.recommended = [
            (v.recommended_image_rect_width, v.recommended_image_rect_height) for v in views
        ]
        if any(w < 1 or h < 1 for w, h in self.recommended):
            self.recommended = [self.fallback_size] * 2
            self.from_profile.append("eye size")
        self._max = [(v.max_image_rect_width, v.max_image_rect_height) for v in views]
        modes = self._call(
            "xrEnumerateEnvironmentBlendModes",
            openxr.enumerate_environment_blend_modes,
            self.instance,
            self.system_id,
            stereo,
        )
        modes = [int(m) for m in modes]
        opaque = openxr.EnvironmentBlendMode.OPAQUE.value
        self.blend_mode = openxr.EnvironmentBlendMode(opaque if opaque in modes else modes[0])

    def _create_session(self) -> None:
        openxr = self.xr
        # Required before xrCreateSession (XR_ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING).
        req = self._call(
            "xrGetOpenGLGraphicsRequirementsKHR",
            openxr.get_opengl_graphics_requirements_khr,
            self.instance,
            self.system_id,
        )
        ours = self.gl.ctx.version_code  # e.g. 450
        low = _gl_version(req.min_api_version_supported)
        if ours < low:
            raise UnsupportedRuntimeError(
                f"the runtime needs OpenGL {low // 100}.{low % 100 // 10} or newer; this "
                f"context has {ours // 100}.{ours % 100 // 10}"
            )
        self._binding = self.gl.binding()
        info = openxr.SessionCreateInfo(
            next=ctypes.cast(ctypes.pointer(self._binding), ctypes.c_void_p),
            system_id=self.system_id,
        )
        self.gl.make_current()
        self.session = self._call("xrCreateSession", openxr.create_session, self.instance, info)

    def _create_space(self) -> None:
        openxr = self.xr
        offered = self._call(
            "xrEnumerateReferenceSpaces", openxr.enumerate_reference_spaces, self.session
        )
        offered = [int(s) for s in offered]
        kind = openxr.ReferenceSpaceType.STAGE
        if kind.value not in offered:
            kind = openxr.ReferenceSpaceType.LOCAL
        self.space = self._call(
            "xrCreateReferenceSpace",
            openxr.create_reference_space,
            self.session,
            openxr.ReferenceSpaceCreateInfo(reference_space_type=kind),
        )
        self.space_type = kind.name

    def _create_swapchains(self) -> None:
        openxr = self.xr
        formats = [int(f) for f in self._call(
            "xrEnumerateSwapchainFormats", openxr.enumerate_swapchain_formats, self.session
        )]  # fmt: skip
        chosen = next((f for f in FORMATS if f in formats), None)
        if chosen is None:
            listed = ", ".join(f"0x{f:04X}" for f in formats) or "none"
            raise UnsupportedRuntimeError(
                f"the runtime {self.runtime_name!r} offers no swapchain format the bridge can "
                f"write (offered: {listed}; usable: "
                f"{', '.join(name for *_, name in FORMATS.values())})"
            )
        self.format, self.srgb = chosen, FORMATS[chosen][1]
        dtype = FORMATS[chosen][0]
        ctx = self.gl.ctx
        for (w, h), (max_w, max_h) in zip(self.recommended, self._max, strict=True):
            width, height = swapchain_size((w, h), (max_w, max_h), self.resolution_scale)
            info = openxr.SwapchainCreateInfo(
                usage_flags=openxr.SwapchainUsageFlags.COLOR_ATTACHMENT_BIT
                | openxr.SwapchainUsageFlags.SAMPLED_BIT,
                format=chosen,
                sample_count=1,  # the drawer resolves per pixel: no multisampling
                width=width,
                height=height,
                face_count=1,
                array_size=1,
                mip_count=1,
            )
            self.gl.make_current()
            handle = self._call("xrCreateSwapchain", openxr.create_swapchain, self.session, info)
            images = self._call(
                "xrEnumerateSwapchainImages",
                openxr.enumerate_swapchain_images,
                handle,
                openxr.SwapchainImageOpenGLKHR,
            )
            chain = EyeSwapchain(handle, width, height, [int(i.image) for i in images])
            self.swapchains.append(chain)
            for name in chain.images:
                texture = ctx.external_texture(name, (width, height), 4, 0, dtype)
                chain.textures.append(texture)
                chain.framebuffers.append(ctx.framebuffer(color_attachments=[texture]))

    # --- the state machine --------------------------------------------------------------------
    def poll_events(self) -> None:
        """Handle every queued event: READY → xrBeginSession; STOPPING → xrEndSession;
        EXITING → over; LOSS_PENDING and instance loss → SessionLostError. Interrupts held
        back (a state change and its flag go together)."""
        with deferred():
            self._poll_events()

    def _poll_events(self) -> None:
        openxr = self.xr
        while True:
            try:
                event = openxr.poll_event(self.instance)
            except openxr.EventUnavailable:
                return
            except openxr.XrException as exc:
                raise SessionLostError(f"xrPollEvent failed: {type(exc).__name__}") from None
            kind = int(
                event._type
            )  # the raw field: an extension's event may be unknown to the enum
            if kind == openxr.StructureType.EVENT_DATA_INSTANCE_LOSS_PENDING.value:
                self.lost = True
                raise SessionLostError(
                    f"the runtime {self.runtime_name!r} is going away (instance loss pending)"
                )
            if kind != openxr.StructureType.EVENT_DATA_SESSION_STATE_CHANGED.value:
                continue
            changed = ctypes.cast(
                ctypes.byref(event), ctypes.POINTER(openxr.EventDataSessionStateChanged)
            ).contents
            self._state_changed(openxr.SessionState(changed.state))

    def _state_changed(self, state) -> None:
        openxr = self.xr
        self.state = state.name
        log.info("OpenXR session state: %s", state.name)
        if state == openxr.SessionState.READY:
            self._call(
                "xrBeginSession",
                openxr.begin_session,
                self.session,
                openxr.SessionBeginInfo(openxr.ViewConfigurationType.PRIMARY_STEREO),
            )
            self.running = True
        elif state == openxr.SessionState.STOPPING:
            self.running = False
            self._call("xrEndSession", openxr.end_session, self.session)
        elif state == openxr.SessionState.EXITING:
            self.exiting = True
        elif state == openxr.SessionState.LOSS_PENDING:
            self.running = False
            self.lost = True
            raise SessionLostError(
                f"the runtime {self.runtime_name!r} lost the session (LOSS_PENDING): the "
                "headset was disconnected or the runtime stopped"
            )

    def request_exit(self) -> None:
        """Ask the runtime to end the session (it goes STOPPING → IDLE → EXITING)."""
        with deferred():
            if self.session is None or self.exit_requested:
                return
            self.exit_requested = True
            if not self.running:  # never began: nothing to stop, the loop simply ends
                self.exiting = True
                return
            self._call("xrRequestExitSession", self.xr.request_exit_session, self.session)

    # --- one frame ----------------------------------------------------------------------------
    def frame(
        self, draw_eye: Callable[[int, LocatedView, EyeSwapchain, object], LocatedView | None]
    ) -> FrameInfo:
        """One frame: xrWaitFrame → xrBeginFrame → xrLocateViews (the predicted display
        time) → per eye: acquire, wait, ``draw_eye(index, view, swapchain, framebuffer)``
        (the framebuffer of the acquired image; the context is current; it returns the view it
        drew, or None for the located one), release → xrEndFrame with a projection layer
        carrying the drawn views' poses and FOVs, as the spec asks (no layer when
        the runtime says not to render, the views are not tracked, or an exit was requested:
        the spec wants the frame loop to go on until STOPPING, which may take frames, and
        those frames carry no layer, so a run of N frames submits N images)."""
        with deferred():  # draw_eye alone takes a Ctrl-C at once (module docstring)
            return self._frame(draw_eye)

    def _frame(self, draw_eye) -> FrameInfo:
        openxr = self.xr
        state = self._call("xrWaitFrame", openxr.wait_frame, self.session)
        period_s = state.predicted_display_period / 1e9
        self.period_s = period_s if period_s > 0 else self.period_s
        display_time = self._display_time = state.predicted_display_time
        self._begin_frame()
        views: tuple[LocatedView, ...] = ()
        layers = []
        try:
            if state.should_render and not self.exit_requested:
                views, layer = self._render(display_time, draw_eye)
                if layer is not None:
                    layers.append(ctypes.byref(layer))
        except BaseException:  # an interrupt or error while drawing: end it as the spec asks
            self.abandon_frame()
            raise
        self._end_frame(display_time, layers)
        self._layer_keepalive = []
        return FrameInfo(int(display_time), period_s, views, bool(layers))

    def _begin_frame(self) -> None:
        openxr = self.xr
        try:
            openxr.begin_frame(self.session)
        except openxr.FrameDiscarded:
            pass  # the previous frame was not ended: the runtime dropped it, go on
        except openxr.SessionLossPending:
            pass  # the LOSS_PENDING event follows
        except openxr.XrException:
            self._call("xrBeginFrame", _reraise, sys.exc_info()[1])
        self.frame_begun = True

    def _end_frame(self, display_time, layers) -> None:
        openxr = self.xr
        info = openxr.FrameEndInfo(
            display_time=display_time, environment_blend_mode=self.blend_mode, layers=layers
        )
        try:
            openxr.end_frame(self.session, info)
        except openxr.SessionLossPending:
            pass
        except openxr.XrException:
            self.frame_begun = False  # refused: the runtime holds no frame of ours either way
            self._call("xrEndFrame", _reraise, sys.exc_info()[1])
        self.frame_begun = False

    def abandon_frame(self) -> None:
        """End what a frame left open (idempotent; failures logged): every acquired
        swapchain image released (waited first, as the spec orders), a begun frame ended with
        no layers."""
        with deferred():
            for chain in self.swapchains:
                if chain.acquired:
                    if not chain.waited:
                        _quietly(self._wait_image, chain)
                    _quietly(self._release_image, chain)
                    chain.acquired = chain.waited = False
            if self.frame_begun and self.session is not None and not self.lost:
                _quietly(self._end_frame, self._display_time, [])
            self.frame_begun = False
            self._layer_keepalive = []

    def _acquire_image(self, chain: EyeSwapchain) -> int:
        image = self._call("xrAcquireSwapchainImage", self.xr.acquire_swapchain_image, chain.handle)
        chain.acquired = True
        return image

    def _wait_image(self, chain: EyeSwapchain) -> None:
        openxr = self.xr
        self._call(
            "xrWaitSwapchainImage",
            openxr.wait_swapchain_image,
            chain.handle,
            openxr.SwapchainImageWaitInfo(timeout=openxr.INFINITE_DURATION),
        )
        chain.waited = True

    def _release_image(self, chain: EyeSwapchain) -> None:
        try:
            self._call("xrReleaseSwapchainImage", self.xr.release_swapchain_image, chain.handle)
        finally:
            chain.acquired = chain.waited = False

    def _render(self, display_time, draw_eye):
        openxr = self.xr
        located = self._call(
            "xrLocateViews",
            openxr.locate_views,
            self.session,
            openxr.ViewLocateInfo(
                view_configuration_type=openxr.ViewConfigurationType.PRIMARY_STEREO,
                display_time=display_time,
                space=self.space,
            ),
        )
        view_state, xr_views = located
        flags = int(view_state.view_state_flags)
        needed = int(openxr.VIEW_STATE_POSITION_VALID_BIT) | int(
            openxr.VIEW_STATE_ORIENTATION_VALID_BIT
        )
        if flags & needed != needed or len(xr_views) != len(self.swapchains):
            return (), None  # no valid poses (tracking lost): submit no layer this frame
        views = tuple(located_view(v) for v in xr_views)
        self.located = views  # the pair, for a draw_eye that needs both (the head's centre)
        projection_views = (openxr.CompositionLayerProjectionView * len(views))()
        submitted: list[LocatedView] = []
        for index, chain in enumerate(self.swapchains):
            image = self._acquire_image(chain)
            self._wait_image(chain)
            self.gl.make_current()
            with allowed():  # the long part: a Ctrl-C lands here at once (_frame ends it)
                drawn = draw_eye(index, views[index], chain, chain.framebuffers[image])
            self._release_image(chain)
            pv = projection_views[index]
            pv.type = openxr.StructureType.COMPOSITION_LAYER_PROJECTION_VIEW.value
            submitted.append(drawn or views[index])
            set_pose(pv, submitted[-1])  # the pose and FOV the image was drawn for
            pv.sub_image.swapchain = chain.handle
            pv.sub_image.image_rect.offset.x = pv.sub_image.image_rect.offset.y = 0
            pv.sub_image.image_rect.extent.width = chain.width
            pv.sub_image.image_rect.extent.height = chain.height
            pv.sub_image.image_array_index = 0
        layer = openxr.CompositionLayerProjection(space=self.space, views=projection_views)
        self._layer_keepalive = [layer, projection_views]
        return tuple(submitted), layer

    # --- shutdown -----------------------------------------------------------------------------
    def stop(self, timeout_s: float = STOP_TIMEOUT_S) -> None:
        """End the session the way the spec allows (idempotent; failures logged): the open
        frame ended, xrRequestExitSession, then the frame loop kept going with empty frames
        until the runtime says STOPPING and xrEndSession is called (``poll_events``), for at
        most ``timeout_s``. Nothing to do when the session never ran, has ended or was lost."""
        with deferred():
            self.abandon_frame()
            if self.session is None or self.lost or not self.running:
                return
            if not self.exit_requested:
                self.exit_requested = True
                _quietly(self._call, "xrRequestExitSession", self.xr.request_exit_session,
                         self.session)  # fmt: skip
            deadline = time.monotonic() + timeout_s
            while self.running and not self.lost and time.monotonic() < deadline:
                try:
                    self._poll_events()
                    if self.running and self.state != "STOPPING":
                        self._frame(lambda *_args: None)  # no layers: exit was requested
                except Exception as exc:
                    log.warning("ending the session: %s", exc)
                    self.abandon_frame()
                    break
            if self.running and not self.lost:
                log.warning(
                    "the runtime did not end the session within %g s of the request; "
                    "destroying it running",
                    timeout_s,
                )

    def finish_gl(self) -> None:
        """Wait for every GL command so far (glFinish): nothing may still write into a
        swapchain image when the runtime frees it."""
        gl = self.gl
        # Only a context moderngl was attached to has drawn (``ctx`` would attach one).
        if gl is not None and gl.context is not None and getattr(gl, "_ctx", None) is not None:
            _quietly(gl.make_current)
            _quietly(gl.ctx.finish)

    def close(self) -> None:
        """Release in reverse order (module docstring: the frame and the session ended
        first, GL finished); each step's failure is logged, never raised (a lost session may
        refuse some of them); interrupts held back until all is released."""
        with deferred():
            self._close()

    def _close(self) -> None:
        openxr = self.xr
        self.stop()
        self.finish_gl()
        for chain in self.swapchains:
            for fbo in chain.framebuffers:  # ours; the textures are the runtime's to delete
                _quietly(fbo.release)
            chain.framebuffers, chain.textures = [], []
        self.finish_gl()
        for chain in self.swapchains:
            _quietly(openxr.destroy_swapchain, chain.handle)
        self.swapchains = []
        if self.space is not None:
            _quietly(openxr.destroy_space, self.space)
        if self.session is not None:
            _quietly(openxr.destroy_session, self.session)
        if self.instance is not None:
            _quietly(openxr.destroy_instance, self.instance)
        self.space = self.session = self.instance = None
        self._binding = None
        self.running = False
        if self.gl is not None:  # after the session: the runtime used it until then
            _quietly(self.gl.close)
            self.gl = None


def _reraise(exc):
    raise exc


def _quietly(fn, *args) -> None:
    try:
        fn(*args)
    except Exception as exc:  # shutdown goes on whatever one step says
        log.warning("%s during shutdown: %s", getattr(fn, "__name__", fn), exc)


def _gl_version(version) -> int:
    """An XrVersion (major << 48 | minor << 32 | patch) → 100·major + 10·minor."""
    number = int(version.number() if hasattr(version, "number") else version)
    return 100 * (number >> 48) + 10 * ((number >> 32) & 0xFFFF)
