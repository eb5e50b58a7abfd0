"""A surfaceless EGL OpenGL 3.3 core context made with ctypes, for driving the test runtime.

The OpenXR EGL binding (``XR_MNDX_egl_enable``) needs the EGLDisplay, EGLConfig and EGLContext
of the app's context; moderngl's standalone contexts hide them, so the test app makes its own
and ``moderngl.create_context()`` then attaches to it (it is current on this thread).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

EGL_DEFAULT_DISPLAY = None
EGL_NO_CONTEXT = None
EGL_NO_SURFACE = None
EGL_NONE = 0x3038
EGL_SURFACE_TYPE = 0x3033
EGL_PBUFFER_BIT = 0x0001
EGL_RENDERABLE_TYPE = 0x3040
EGL_OPENGL_BIT = 0x0008
EGL_RED_SIZE, EGL_GREEN_SIZE, EGL_BLUE_SIZE, EGL_ALPHA_SIZE = 0x3024, 0x3023, 0x3022, 0x3021
EGL_OPENGL_API = 0x30A2
EGL_CONTEXT_MAJOR_VERSION = 0x3098
EGL_CONTEXT_MINOR_VERSION = 0x30FB
EGL_CONTEXT_OPENGL_PROFILE_MASK = 0x30FD
EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT = 0x0001
EGL_PLATFORM_SURFACELESS_MESA = 0x31DD


class EGLError(RuntimeError):
    """No surfaceless EGL OpenGL context here (no libEGL, no Mesa, no GL 3.3 core)."""


class XrGraphicsBindingEGLMNDX(ctypes.Structure):
    """openxr_platform.h's XrGraphicsBindingEGLMNDX (XR_MNDX_egl_enable); chained into
    XrSessionCreateInfo.next as a pointer."""

    _fields_ = [
        ("type", ctypes.c_int),  # XR_TYPE_GRAPHICS_BINDING_EGL_MNDX = 1000048004
        ("next", ctypes.c_void_p),
        ("getProcAddress", ctypes.c_void_p),  # PFNEGLGETPROCADDRESSPROC
        ("display", ctypes.c_void_p),
        ("config", ctypes.c_void_p),
        ("context", ctypes.c_void_p),
    ]


XR_TYPE_GRAPHICS_BINDING_EGL_MNDX = 1000048004


@dataclass
class EGLContext:
    lib: ctypes.CDLL
    display: int
    config: int
    context: int
    # What was current on this thread before (display, draw, read, context), e.g. Blender's
    # context in a bpy process: given back on release, as a guest app should, since Blender's
    # exit frees its GPU resources assuming its context is current (libepoxy aborts otherwise).
    previous: tuple | None = None

    def binding(self) -> XrGraphicsBindingEGLMNDX:
        get_proc = ctypes.cast(self.lib.eglGetProcAddress, ctypes.c_void_p).value
        return XrGraphicsBindingEGLMNDX(
            XR_TYPE_GRAPHICS_BINDING_EGL_MNDX,
            None,
            get_proc,
            self.display,
            self.config,
            self.context,
        )

    def make_current(self) -> None:
        if not self.lib.eglMakeCurrent(self.display, EGL_NO_SURFACE, EGL_NO_SURFACE, self.context):
            raise EGLError(f"eglMakeCurrent failed (0x{self.lib.eglGetError():x})")

    def release_current(self) -> None:
        self.lib.eglMakeCurrent(self.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT)
        if self.previous is not None:
            self.lib.eglMakeCurrent(*self.previous)

    def destroy(self) -> None:
        self.release_current()
        self.lib.eglDestroyContext(self.display, self.context)


def _attribs(*pairs: int):
    values = [*pairs, EGL_NONE]
    return (ctypes.c_int32 * len(values))(*values)


def create_egl_context() -> EGLContext:
    """A surfaceless OpenGL 3.3 core EGL context, current on the calling thread."""
    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError as exc:
        raise EGLError(f"no libEGL.so.1 ({exc}); apt install libegl1 libgl1-mesa-dri") from None
    vp = ctypes.c_void_p
    egl.eglGetProcAddress.restype = vp
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    egl.eglGetDisplay.restype = vp
    egl.eglGetDisplay.argtypes = [vp]
    egl.eglInitialize.argtypes = [
        vp,
        ctypes.POINTER(ctypes.c_int32),
        ctypes.POINTER(ctypes.c_int32),
    ]
    egl.eglChooseConfig.argtypes = [
        vp,
        vp,
        ctypes.POINTER(vp),
        ctypes.c_int32,
        ctypes.POINTER(ctypes.c_int32),
    ]
    egl.eglBindAPI.argtypes = [ctypes.c_uint32]
    egl.eglCreateContext.restype = vp
    egl.eglCreateContext.argtypes = [vp, vp, vp, vp]
    egl.eglMakeCurrent.argtypes = [vp, vp, vp, vp]
    egl.eglDestroyContext.argtypes = [vp, vp]
    egl.eglGetError.restype = ctypes.c_int32
    egl.eglGetCurrentContext.restype = vp
    egl.eglGetCurrentDisplay.restype = vp
    egl.eglGetCurrentSurface.restype = vp
    egl.eglGetCurrentSurface.argtypes = [ctypes.c_int32]
    previous = None
    if egl.eglGetCurrentContext():
        previous = (
            egl.eglGetCurrentDisplay(),
            egl.eglGetCurrentSurface(0x3059),  # EGL_DRAW
            egl.eglGetCurrentSurface(0x305A),  # EGL_READ
            egl.eglGetCurrentContext(),
        )

    display = None
    get_platform_display = egl.eglGetProcAddress(b"eglGetPlatformDisplayEXT")
    if get_platform_display:  # Mesa's surfaceless platform needs no window system at all
        fn = ctypes.CFUNCTYPE(vp, ctypes.c_uint32, vp, vp)(get_platform_display)
        display = fn(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, None)
    if not display:
        display = egl.eglGetDisplay(EGL_DEFAULT_DISPLAY)
    major, minor = ctypes.c_int32(), ctypes.c_int32()
    if not display or not egl.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)):
        raise EGLError(f"eglInitialize failed (0x{egl.eglGetError():x})")
    if not egl.eglBindAPI(EGL_OPENGL_API):
        raise EGLError("eglBindAPI(EGL_OPENGL_API) failed")
    config, count = vp(), ctypes.c_int32()
    attribs = _attribs(
        EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT,
        EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8, EGL_ALPHA_SIZE, 8,
    )  # fmt: skip
    if not egl.eglChooseConfig(display, attribs, ctypes.byref(config), 1, ctypes.byref(count)):
        raise EGLError(f"eglChooseConfig failed (0x{egl.eglGetError():x})")
    if count.value < 1:
        raise EGLError("no EGL config renders OpenGL")
    context = egl.eglCreateContext(
        display,
        config,
        EGL_NO_CONTEXT,
        _attribs(
            EGL_CONTEXT_MAJOR_VERSION,
            3,
            EGL_CONTEXT_MINOR_VERSION,
            3,
            EGL_CONTEXT_OPENGL_PROFILE_MASK,
            EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
        ),
    )
    if not context:
        raise EGLError(f"eglCreateContext(3.3 core) failed (0x{egl.eglGetError():x})")
    ctx = EGLContext(egl, display, config.value, context, previous)
    ctx.make_current()
    return ctx


class ModernGLLoader:
    """moderngl's context-loader interface over this EGL context, so
    ``moderngl.create_context(context=ModernGLLoader(egl))`` draws into it."""

    def __init__(self, egl: EGLContext):
        self.egl = egl

    def load_opengl_function(self, name: str) -> int:
        return self.egl.lib.eglGetProcAddress(name.encode()) or 0

    def __enter__(self):
        self.egl.make_current()

    def __exit__(self, *args):
        pass

    def release(self):
        pass
