"""Leave the host's OpenGL context current, as we found it.

Blender draws through EGL in background mode and keeps its GPU context current on the main
thread; at exit it frees its GPU resources without making the context current again, and
libepoxy aborts the process (``Couldn't find current GLX or EGL context``, exit status 134)
when none is. Our own contexts (moderngl's standalone EGL context, the bridge's surfaceless
one) become current when made and used, and releasing them leaves *no* context current — so a
process that drew through both, in either order, aborted at exit.

So a context of ours that is released gives back what was current before it (``kept``), and
before one of ours is made current, a foreign context then current (Blender's) is remembered
(``before_ours``): at interpreter exit, before Blender's own teardown runs (``atexit`` runs
handlers last-registered first, and ours is registered only once Blender's context exists),
it is made current again. Where no EGL library exists (Windows, macOS: no epoxy-over-EGL
teardown there) or nothing was current, these do nothing.
"""

from __future__ import annotations

import atexit
import ctypes
import sys
from contextlib import contextmanager
from typing import NamedTuple

EGL_DRAW = 0x3059
EGL_READ = 0x305A

_lib: ctypes.CDLL | bool | None = False  # False: not looked up yet


class Current(NamedTuple):
    """The calling thread's current EGL binding."""

    display: int
    draw: int
    read: int
    context: int


def _egl():
    global _lib
    if _lib is False:
        _lib = None
        if sys.platform.startswith("linux"):
            try:
                lib = ctypes.CDLL("libEGL.so.1")
            except OSError:
                return None
            vp = ctypes.c_void_p
            for name in ("eglGetCurrentDisplay", "eglGetCurrentContext"):
                getattr(lib, name).restype = vp
                getattr(lib, name).argtypes = []
            lib.eglGetCurrentSurface.restype = vp
            lib.eglGetCurrentSurface.argtypes = [ctypes.c_int32]
            lib.eglMakeCurrent.restype = ctypes.c_uint
            lib.eglMakeCurrent.argtypes = [vp, vp, vp, vp]
            _lib = lib
    return _lib


def current() -> Current | None:
    """The EGL context current on this thread (with its display and surfaces), or None."""
    lib = _egl()
    if lib is None:
        return None
    context = lib.eglGetCurrentContext()
    if not context:
        return None
    return Current(
        lib.eglGetCurrentDisplay() or 0,
        lib.eglGetCurrentSurface(EGL_DRAW) or 0,
        lib.eglGetCurrentSurface(EGL_READ) or 0,
        context,
    )


def restore(saved: Current | None) -> None:
    """Make ``saved`` current again (nothing when None). A context destroyed meanwhile fails
    quietly: there is nothing left to give back."""
    lib = _egl()
    if saved is None or lib is None:
        return
    lib.eglMakeCurrent(saved.display, saved.draw, saved.read, saved.context)


@contextmanager
def kept():
    """Whatever our code makes current inside, the host's context is current again after."""
    saved = current()
    try:
        yield
    finally:
        restore(saved)


#: EGL contexts of ours (handles), so a context of ours is never taken for the host's.
_ours: set[int] = set()
#: The foreign context last displaced by one of ours: made current again at exit.
_host: Current | None = None


def before_ours() -> None:
    """Call before making a context of ours current: remembers a foreign current context."""
    global _host
    found = current()
    if found is not None and found.context not in _ours:
        if _host is None:
            atexit.register(_give_back_host)
        _host = found


def mark_ours() -> None:
    """Call after making a context of ours current (or creating one that is now current)."""
    found = current()
    if found is not None:
        _ours.add(found.context)


def _give_back_host() -> None:
    if _host is not None:
        restore(_host)
