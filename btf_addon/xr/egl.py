"""A surfaceless EGL OpenGL 3.3 core context made with ctypes (libEGL.so.1), for the bridge.

OpenXR's ``XR_MNDX_egl_enable`` binds a session to an EGL context by its handles (display,
config, context) and ``eglGetProcAddress``; this module makes such a context without any
window (Mesa's surfaceless platform where offered, else the default display), makes it
current with no surface (``EGL_KHR_surfaceless_context``), and attaches moderngl to it, so
the drawer (gl/moderngl_device.py) draws in the very context the runtime's swapchain images
belong to. Linux only (libEGL); runtimes without the EGL binding get a desktop context
(xr/desktop_gl.py).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import threading

from ..core.errors import DeviceError
from ..gl import host_context

EGL_DEFAULT_DISPLAY = 0
EGL_NO_CONTEXT = 0
EGL_NO_SURFACE = 0
EGL_NONE = 0x3038
EGL_RENDERABLE_TYPE = 0x3040
EGL_SURFACE_TYPE = 0x3033
EGL_OPENGL_BIT = 0x0008
EGL_OPENGL_API = 0x30A2
EGL_CONTEXT_MAJOR_VERSION = 0x3098
EGL_CONTEXT_MINOR_VERSION = 0x30FB
EGL_CONTEXT_OPENGL_PROFILE_MASK = 0x30FD
EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT = 0x1
EGL_PLATFORM_SURFACELESS_MESA = 0x31DD
EGL_EXTENSIONS = 0x3055
EGL_VENDOR = 0x3053


class EGLError(DeviceError):
    """An EGL call failed; the message names the call and EGL's error code."""


def _load() -> ctypes.CDLL:
    name = ctypes.util.find_library("EGL") or "libEGL.so.1"
    try:
        lib = ctypes.CDLL(name)
    except OSError:
        try:
            lib = ctypes.CDLL("libEGL.so.1")
        except OSError as exc:
            raise EGLError(
                f"libEGL.so.1 is not installed ({exc}); on Debian/Ubuntu: apt install libegl1"
            ) from None
    vp, i32 = ctypes.c_void_p, ctypes.c_int32
    lib.eglGetProcAddress.restype = vp
    lib.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    lib.eglGetDisplay.restype = vp
    lib.eglGetDisplay.argtypes = [vp]
    lib.eglInitialize.argtypes = [vp, ctypes.POINTER(i32), ctypes.POINTER(i32)]
    lib.eglInitialize.restype = ctypes.c_uint
    lib.eglTerminate.argtypes = [vp]
    lib.eglBindAPI.argtypes = [ctypes.c_uint]
    lib.eglBindAPI.restype = ctypes.c_uint
    lib.eglChooseConfig.argtypes = [
        vp,
        ctypes.POINTER(i32),
        ctypes.POINTER(vp),
        i32,
        ctypes.POINTER(i32),
    ]
    lib.eglChooseConfig.restype = ctypes.c_uint
    lib.eglCreateContext.argtypes = [vp, vp, vp, ctypes.POINTER(i32)]
    lib.eglCreateContext.restype = vp
    lib.eglMakeCurrent.argtypes = [vp, vp, vp, vp]
    lib.eglMakeCurrent.restype = ctypes.c_uint
    lib.eglDestroyContext.argtypes = [vp, vp]
    lib.eglGetError.restype = i32
    lib.eglQueryString.argtypes = [vp, i32]
    lib.eglQueryString.restype = ctypes.c_char_p
    lib.eglGetCurrentContext.restype = vp
    return lib


def _attribs(*values: int):
    return (ctypes.c_int32 * (len(values) + 1))(*values, EGL_NONE)


class EGLContext:
    """A surfaceless OpenGL ``major.minor`` core-profile context, current on the creating
    thread. ``display``, ``config``, ``context``: the EGL handles (ints) an
    ``XrGraphicsBindingEGLMNDX`` carries; ``get_proc_address``: the address of
    ``eglGetProcAddress``; ``ctx``: the moderngl context attached to it (made on first use).
    Use it from one thread: OpenGL contexts are current per thread."""

    def __init__(self, major: int = 3, minor: int = 3):
        self._lib = lib = _load()
        self.thread = threading.get_ident()
        self.display = self._display()
        major_out, minor_out = ctypes.c_int32(), ctypes.c_int32()
        if not lib.eglInitialize(self.display, ctypes.byref(major_out), ctypes.byref(minor_out)):
            self._fail("eglInitialize")
        if not lib.eglBindAPI(EGL_OPENGL_API):
            self._fail("eglBindAPI(EGL_OPENGL_API)")
        config, count = ctypes.c_void_p(), ctypes.c_int32()
        # No colour sizes asked: nothing is drawn to a surface (Mesa's surfaceless configs
        # are pbuffer-only); the swapchain images are textures with their own formats.
        # EGL_SURFACE_TYPE 0: any (its default, EGL_WINDOW_BIT, excludes surfaceless configs).
        wanted = _attribs(EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0)
        if not lib.eglChooseConfig(
            self.display, wanted, ctypes.byref(config), 1, ctypes.byref(count)
        ):
            self._fail("eglChooseConfig")
        if count.value < 1:
            raise EGLError("eglChooseConfig: no EGL config renders with desktop OpenGL")
        self.config = config.value
        context_attribs = _attribs(
            EGL_CONTEXT_MAJOR_VERSION, major, EGL_CONTEXT_MINOR_VERSION, minor,
            EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
        )  # fmt: skip
        context = lib.eglCreateContext(self.display, self.config, EGL_NO_CONTEXT, context_attribs)
        if not context:
            self._fail(f"eglCreateContext (OpenGL {major}.{minor} core)")
        self.context = context
        # libEGL's exported eglGetProcAddress itself (the address, for the runtime to call).
        self.get_proc_address = ctypes.cast(lib.eglGetProcAddress, ctypes.c_void_p).value
        self._ctx = None
        # Blender's context where one is current on this thread: given back on release.
        self._host = host_context.current()
        self.make_current()

    def _display(self) -> int:
        lib = self._lib
        client = lib.eglQueryString(None, EGL_EXTENSIONS) or b""
        get_platform_display = lib.eglGetProcAddress(b"eglGetPlatformDisplayEXT")
        if b"EGL_MESA_platform_surfaceless" in client and get_platform_display:
            fn = ctypes.CFUNCTYPE(
                ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int32)
            )(get_platform_display)
            display = fn(EGL_PLATFORM_SURFACELESS_MESA, None, None)
            if display:
                return display
        display = lib.eglGetDisplay(EGL_DEFAULT_DISPLAY)
        if not display:
            self._fail("eglGetDisplay(EGL_DEFAULT_DISPLAY)")
        return display

    def _fail(self, call: str):
        raise EGLError(f"{call} failed (EGL error 0x{self._lib.eglGetError() & 0xFFFF:04X})")

    @property
    def vendor(self) -> str:
        return (self._lib.eglQueryString(self.display, EGL_VENDOR) or b"").decode()

    def make_current(self) -> None:
        """Current on the calling thread, with no surface (drawing goes to framebuffers)."""
        host_context.before_ours()
        if not self._lib.eglMakeCurrent(self.display, EGL_NO_SURFACE, EGL_NO_SURFACE, self.context):
            self._fail("eglMakeCurrent (surfaceless)")
        host_context.mark_ours()

    def release(self) -> None:
        """Not current any more: the host's context (Blender's, where one was current when
        this one was made on this thread) is current again, else none (gl/host_context.py)."""
        self._lib.eglMakeCurrent(self.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT)
        if self._host is not None and threading.get_ident() == self.thread:
            host_context.restore(self._host)

    @property
    def ctx(self):
        """The moderngl context attached to this EGL context. moderngl's own "detect" mode
        goes through glcontext, whose EGL backend only makes standalone contexts; moderngl
        also accepts a loader object (``load_opengl_function`` + ``__enter__``/``__exit__``/
        ``release``), which is how it attaches here (as ``moderngl.init_context`` does, but
        without making it the process-wide default context)."""
        if self._ctx is None:
            from collections import deque

            import moderngl

            self.make_current()
            ctx = moderngl.Context.__new__(moderngl.Context)
            ctx.mglo, ctx.version_code = moderngl.mgl.create_context(context=_Loader(self))
            ctx._info = ctx._extensions = ctx.extra = ctx._gc_mode = None
            ctx._objects = deque()
            ctx._screen = ctx.detect_framebuffer(0)
            ctx.fbo = ctx.detect_framebuffer()
            ctx.mglo.fbo = ctx.fbo.mglo
            if ctx.version_code < 330:
                raise EGLError(f"OpenGL {ctx.version_code} is below the 3.3 the drawer needs")
            self._ctx = ctx
        return self._ctx

    def close(self) -> None:
        """Release moderngl's wrapper, the EGL context and the display (idempotent)."""
        if self.context is None:
            return
        self.release()
        self._lib.eglDestroyContext(self.display, self.context)
        self.context = None
        self._ctx = None


class _Loader:
    """moderngl's context protocol over an ``EGLContext``: GL entry points through
    ``eglGetProcAddress`` (EGL 1.5 returns core functions too), current on ``__enter__``.
    ``__exit__`` keeps the context current: the bridge's thread owns it for its lifetime."""

    def __init__(self, egl: EGLContext):
        self.egl = egl
        self._proc = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_char_p)(egl.get_proc_address)

    def load_opengl_function(self, name: str) -> int:
        return self._proc(name.encode()) or 0

    def __enter__(self):
        self.egl.make_current()

    def __exit__(self, *_exc):
        return None

    def release(self) -> None:
        return None
