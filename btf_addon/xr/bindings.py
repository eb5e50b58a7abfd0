"""OpenXR OpenGL graphics bindings from a context's handles (XR_KHR_opengl_enable /
XR_MNDX_egl_enable), as ctypes structures laid out as in openxr_platform.h.

- EGL (``XrGraphicsBindingEGLMNDX``): what the bridge uses (xr/egl.py makes the context);
  tested against the test runtime.
- WGL (``XrGraphicsBindingOpenGLWin32KHR``) and GLX (``XrGraphicsBindingOpenGLXlibKHR``):
  from the context current on the calling thread (a window's context: Windows runtimes such
  as SteamVR, and Linux desktop runtimes, accept only these). **Written per the specification
  but untested** — no Windows machine or X display here — and not yet wired to a window by
  the bridge, which refuses such runtimes with a message saying so.

pyopenxr has its own binding structs, but types their handles with PyOpenGL's platform
pointers; plain ``c_void_p`` handles keep this module independent of PyOpenGL's platform.
"""

from __future__ import annotations

import ctypes
import sys

XR_TYPE_GRAPHICS_BINDING_OPENGL_WIN32_KHR = 1000023000
XR_TYPE_GRAPHICS_BINDING_OPENGL_XLIB_KHR = 1000023001
XR_TYPE_GRAPHICS_BINDING_EGL_MNDX = 1000048004
GLX_FBCONFIG_ID = 0x8013


class GraphicsBindingEGLMNDX(ctypes.Structure):
    """XrGraphicsBindingEGLMNDX."""

    _fields_ = [
        ("type", ctypes.c_int32),
        ("next", ctypes.c_void_p),
        ("get_proc_address", ctypes.c_void_p),  # PFN_xrEglGetProcAddressMNDX
        ("display", ctypes.c_void_p),  # EGLDisplay
        ("config", ctypes.c_void_p),  # EGLConfig
        ("context", ctypes.c_void_p),  # EGLContext
    ]


class GraphicsBindingOpenGLWin32KHR(ctypes.Structure):
    """XrGraphicsBindingOpenGLWin32KHR (untested)."""

    _fields_ = [
        ("type", ctypes.c_int32),
        ("next", ctypes.c_void_p),
        ("h_dc", ctypes.c_void_p),  # HDC
        ("h_glrc", ctypes.c_void_p),  # HGLRC
    ]


class GraphicsBindingOpenGLXlibKHR(ctypes.Structure):
    """XrGraphicsBindingOpenGLXlibKHR (untested)."""

    _fields_ = [
        ("type", ctypes.c_int32),
        ("next", ctypes.c_void_p),
        ("x_display", ctypes.c_void_p),  # Display*
        ("visualid", ctypes.c_uint32),
        ("glx_fbconfig", ctypes.c_void_p),  # GLXFBConfig
        ("glx_drawable", ctypes.c_ulong),  # GLXDrawable (an XID)
        ("glx_context", ctypes.c_void_p),  # GLXContext
    ]


def egl_binding(egl) -> GraphicsBindingEGLMNDX:
    """From an ``xr.egl.EGLContext``."""
    return GraphicsBindingEGLMNDX(
        XR_TYPE_GRAPHICS_BINDING_EGL_MNDX,
        None,
        egl.get_proc_address,
        egl.display,
        egl.config,
        egl.context,
    )


def wgl_binding_from_current() -> GraphicsBindingOpenGLWin32KHR:
    """The WGL context current on this thread (untested). RuntimeError when none is."""
    if sys.platform != "win32":
        raise RuntimeError("the WGL binding exists on Windows only")
    gl = ctypes.WinDLL("opengl32.dll")
    gl.wglGetCurrentDC.restype = ctypes.c_void_p
    gl.wglGetCurrentContext.restype = ctypes.c_void_p
    dc, context = gl.wglGetCurrentDC(), gl.wglGetCurrentContext()
    if not dc or not context:
        raise RuntimeError("no WGL context is current on this thread")
    return GraphicsBindingOpenGLWin32KHR(
        XR_TYPE_GRAPHICS_BINDING_OPENGL_WIN32_KHR, None, dc, context
    )


class _XVisualInfo(ctypes.Structure):
    _fields_ = [
        ("visual", ctypes.c_void_p),
        ("visualid", ctypes.c_ulong),
        ("screen", ctypes.c_int),
        ("depth", ctypes.c_int),
    ]  # the leading members only: read through a pointer, never allocated here


def glx_binding_from_current() -> GraphicsBindingOpenGLXlibKHR:
    """The GLX context current on this thread (untested): its display, drawable, context,
    the FB config it was made with (glXQueryContext's GLX_FBCONFIG_ID) and that config's
    visual. RuntimeError when none is current."""
    gl = ctypes.CDLL("libGL.so.1")
    vp = ctypes.c_void_p
    gl.glXGetCurrentDisplay.restype = vp
    gl.glXGetCurrentContext.restype = vp
    gl.glXGetCurrentDrawable.restype = ctypes.c_ulong
    gl.glXQueryContext.argtypes = [vp, vp, ctypes.c_int, ctypes.POINTER(ctypes.c_int)]
    gl.glXChooseFBConfig.restype = ctypes.POINTER(vp)
    gl.glXChooseFBConfig.argtypes = [vp, ctypes.c_int, ctypes.POINTER(ctypes.c_int), vp]
    gl.glXGetVisualFromFBConfig.restype = ctypes.POINTER(_XVisualInfo)
    gl.glXGetVisualFromFBConfig.argtypes = [vp, vp]
    display, context = gl.glXGetCurrentDisplay(), gl.glXGetCurrentContext()
    if not display or not context:
        raise RuntimeError("no GLX context is current on this thread")
    config_id = ctypes.c_int()
    gl.glXQueryContext(display, context, GLX_FBCONFIG_ID, ctypes.byref(config_id))
    screen = ctypes.CDLL("libX11.so.6").XDefaultScreen
    screen.argtypes = [vp]
    wanted = (ctypes.c_int * 3)(GLX_FBCONFIG_ID, config_id.value, 0)
    count = ctypes.c_int()
    configs = gl.glXChooseFBConfig(display, screen(display), wanted, ctypes.byref(count))
    if not configs or count.value < 1:
        raise RuntimeError("the current GLX context's FB config was not found")
    config = configs[0]
    visual = gl.glXGetVisualFromFBConfig(display, config)
    visualid = visual.contents.visualid if visual else 0
    return GraphicsBindingOpenGLXlibKHR(
        XR_TYPE_GRAPHICS_BINDING_OPENGL_XLIB_KHR,
        None,
        display,
        visualid,
        config,
        gl.glXGetCurrentDrawable(),
        context,
    )
