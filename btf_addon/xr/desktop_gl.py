"""The OpenGL context the session binds to, by binding kind: "egl" (a surfaceless EGL context,
xr/egl.py: headless, tested) or "wgl"/"glx" (a hidden glfw window's context on a desktop:
Windows runtimes such as SteamVR and Linux desktop runtimes offer only these bindings).

**The glfw path is written per the specification but untested** — no Windows machine or X
display here. Every context offers the same few members the session and the bridge use:
``ctx`` (moderngl), ``make_current``, ``release``, ``close``, ``context`` (None once closed)
and ``binding()`` (the XrGraphicsBinding* struct for XrSessionCreateInfo.next).
"""

from __future__ import annotations

import os
import sys

from .bindings import egl_binding, glx_binding_from_current, wgl_binding_from_current


def desktop_kind() -> str | None:
    """The desktop binding this machine could use: "wgl" on Windows, "glx" on Linux with an X
    display, None otherwise."""
    if sys.platform == "win32":
        return "wgl"
    if sys.platform.startswith("linux") and os.environ.get("DISPLAY"):
        return "glx"
    return None


def make_context(kind: str):
    """A current OpenGL 3.3 core context for the binding ``kind``. RuntimeError (EGLError is
    one) when it cannot be made."""
    if kind == "egl":
        from .egl import EGLContext

        context = EGLContext()
        context.binding = lambda: egl_binding(context)
        return context
    return GlfwContext(kind)


class GlfwContext:
    """A hidden 64×64 glfw window's OpenGL 3.3 core context, current on this thread
    (untested: module docstring). moderngl attaches to it in its "detect" mode."""

    def __init__(self, kind: str):
        if kind not in ("wgl", "glx"):
            raise ValueError(f"unknown binding kind {kind!r}")
        try:
            import glfw
        except ImportError:
            raise RuntimeError(
                "a desktop OpenGL binding needs the glfw package (pip install glfw==2.11.0); "
                "the extension does not bundle it"
            ) from None
        self.kind, self._glfw = kind, glfw
        if not glfw.init():
            raise RuntimeError("glfw could not initialise (no desktop session?)")
        glfw.window_hint(glfw.VISIBLE, glfw.FALSE)
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        self.context = glfw.create_window(64, 64, "BTF XTAL bridge", None, None)
        if not self.context:
            glfw.terminate()
            raise RuntimeError("glfw could not make an OpenGL 3.3 core context")
        self.make_current()
        self._ctx = None

    @property
    def ctx(self):
        if self._ctx is None:
            import moderngl

            self.make_current()
            self._ctx = moderngl.create_context(require=330)
        return self._ctx

    def binding(self):
        self.make_current()
        return wgl_binding_from_current() if self.kind == "wgl" else glx_binding_from_current()

    def make_current(self) -> None:
        self._glfw.make_context_current(self.context)

    def release(self) -> None:
        self._glfw.make_context_current(None)

    def close(self) -> None:
        if self.context is None:
            return
        self._glfw.destroy_window(self.context)
        self._glfw.terminate()
        self.context = self._ctx = None
