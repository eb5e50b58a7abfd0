"""A minimal OpenXR OpenGL app over pyopenxr and a surfaceless EGL context, to drive the test
runtime in tests/xr/test_test_runtime.py exactly as a headset app drives a runtime."""

from __future__ import annotations

import ctypes

import numpy as np
import xr

from .egl import ModernGLLoader, create_egl_context

GL_SRGB8_ALPHA8, GL_RGBA8, GL_RGBA16F, GL_RGBA32F = 0x8C43, 0x8058, 0x881A, 0x8814
GL_FRAMEBUFFER_SRGB = 0x8DB9
EXTENSIONS = ["XR_KHR_opengl_enable", "XR_MNDX_egl_enable"]
STEREO = xr.ViewConfigurationType.PRIMARY_STEREO


class App:
    """Instance + system; ``start()`` makes the EGL context and the session."""

    def __init__(self, extensions=EXTENSIONS, api_version=None):
        info = xr.ApplicationInfo(application_name="btf runtime test")
        if api_version is not None:
            info.api_version = api_version
        self.instance = xr.create_instance(
            xr.InstanceCreateInfo(application_info=info, enabled_extension_names=extensions)
        )
        self.system = None
        self.session = None
        self.egl = None
        self.gl = None
        self.spaces, self.swapchains, self.states = [], [], []

    def get_system(self):
        self.system = xr.get_system(
            self.instance, xr.SystemGetInfo(form_factor=xr.FormFactor.HEAD_MOUNTED_DISPLAY)
        )
        return self.system

    def graphics_requirements(self):
        pfn = ctypes.cast(
            xr.get_instance_proc_addr(self.instance, "xrGetOpenGLGraphicsRequirementsKHR"),
            xr.PFN_xrGetOpenGLGraphicsRequirementsKHR,
        )
        req = xr.GraphicsRequirementsOpenGLKHR()
        result = xr.check_result(xr.Result(pfn(self.instance, self.system, ctypes.byref(req))))
        if result.is_exception():
            raise result
        return req

    def start(self, requirements=True):
        """EGL context, then the session (binding chained in next)."""
        if self.system is None:
            self.get_system()
        if requirements:
            self.graphics_requirements()
        if self.egl is None:
            self.egl = create_egl_context()  # EGLError when there is no EGL OpenGL
            import moderngl

            self.gl = moderngl.create_context(require=330, context=ModernGLLoader(self.egl))
        self._binding = self.egl.binding()  # kept alive: the runtime reads it in xrCreateSession
        info = xr.SessionCreateInfo(
            system_id=self.system,
            next=ctypes.cast(ctypes.pointer(self._binding), ctypes.c_void_p),
        )
        self.session = xr.create_session(self.instance, info)
        return self.session

    def poll(self) -> list:
        """Drain the event queue; session states are appended to self.states."""
        events = []
        while True:
            try:
                buf = xr.poll_event(self.instance)
            except xr.EventUnavailable:
                return events
            if xr.StructureType(buf.type) == xr.StructureType.EVENT_DATA_SESSION_STATE_CHANGED:
                ev = ctypes.cast(
                    ctypes.byref(buf), ctypes.POINTER(xr.EventDataSessionStateChanged)
                ).contents
                self.states.append(xr.SessionState(ev.state))
            events.append(buf.type)

    def space(self, kind=xr.ReferenceSpaceType.LOCAL):
        sp = xr.create_reference_space(
            self.session, xr.ReferenceSpaceCreateInfo(reference_space_type=kind)
        )
        self.spaces.append(sp)
        return sp

    def swapchain(self, fmt, width, height):
        sc = xr.create_swapchain(
            self.session,
            xr.SwapchainCreateInfo(
                usage_flags=xr.SwapchainUsageFlags.COLOR_ATTACHMENT_BIT,
                format=fmt,
                sample_count=1,
                width=width,
                height=height,
                face_count=1,
                array_size=1,
                mip_count=1,
            ),
        )
        images = xr.enumerate_swapchain_images(sc, xr.SwapchainImageOpenGLKHR)
        self.swapchains.append(sc)
        return sc, [img.image for img in images]

    def clear_image(self, texture, size, colour, corner_colour):
        """Clear a swapchain texture to ``colour`` (linear), its bottom-left quarter to
        ``corner_colour``; sRGB textures encode on write (GL_FRAMEBUFFER_SRGB)."""
        tex = self.gl.external_texture(texture, size, 4, 0, "f1")
        fbo = self.gl.framebuffer(color_attachments=[tex])
        self.gl.enable_direct(GL_FRAMEBUFFER_SRGB)
        fbo.clear(*colour)
        fbo.clear(*corner_colour, viewport=(0, 0, size[0] // 2, size[1] // 2))
        self.gl.finish()
        fbo.release()

    def begin(self):
        xr.begin_session(self.session, xr.SessionBeginInfo(primary_view_configuration_type=STEREO))

    def close(self):
        for sc in self.swapchains:
            try:
                xr.destroy_swapchain(sc)
            except xr.HandleInvalidError:
                pass
        for sp in self.spaces:
            try:
                xr.destroy_space(sp)
            except xr.HandleInvalidError:
                pass
        if self.session is not None:
            xr.destroy_session(self.session)
        if self.gl is not None:
            self.gl.release()
        if self.egl is not None:
            self.egl.destroy()
        xr.destroy_instance(self.instance)


def submit_frame(app, space, chains, colours, rects=None):
    """One full frame: wait, begin, locate, render each view (clear), end. Returns
    (frame_state, located views)."""
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    xr.begin_frame(app.session, xr.FrameBeginInfo())
    _, views = xr.locate_views(
        app.session,
        xr.ViewLocateInfo(
            view_configuration_type=STEREO,
            display_time=state.predicted_display_time,
            space=space,
        ),
    )
    proj = []
    for i, view in enumerate(views):
        sc, images, size = chains[i]
        index = xr.acquire_swapchain_image(sc, xr.SwapchainImageAcquireInfo())
        xr.wait_swapchain_image(sc, xr.SwapchainImageWaitInfo(timeout=xr.INFINITE_DURATION))
        app.clear_image(images[index], size, *colours[i])
        xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
        x, y, w, h = rects[i] if rects else (0, 0, *size)
        proj.append(
            xr.CompositionLayerProjectionView(
                pose=view.pose,
                fov=view.fov,
                sub_image=xr.SwapchainSubImage(
                    swapchain=sc,
                    image_rect=xr.Rect2Di(offset=xr.Offset2Di(x, y), extent=xr.Extent2Di(w, h)),
                ),
            )
        )
    layer = xr.CompositionLayerProjection(space=space, views=proj)
    xr.end_frame(
        app.session,
        xr.FrameEndInfo(
            display_time=state.predicted_display_time,
            environment_blend_mode=xr.EnvironmentBlendMode.OPAQUE,
            layers=[ctypes.byref(layer)],
        ),
    )
    return state, views


def quat_rotate(q, v):
    """Rotate v by the unit quaternion q = (x, y, z, w)."""
    x, y, z, w = q
    u = np.array([x, y, z])
    v = np.asarray(v, dtype=float)
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def start_running(app, size=(96, 72), formats=(GL_SRGB8_ALPHA8, GL_SRGB8_ALPHA8)):
    """Session begun, LOCAL space, one swapchain per eye."""
    app.start()
    app.poll()
    app.begin()
    space = app.space()
    chains = []
    for fmt in formats:
        sc, images = app.swapchain(fmt, *size)
        chains.append((sc, images, size))
    return space, chains
