"""The graphics-binding structs of btf_addon/xr/bindings.py against openxr_platform.h: sizes,
field offsets and structure-type values as the C compiler lays them out (the WGL and GLX
bindings are otherwise untested: no Windows machine or X display here)."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys

import pytest

from btf_addon.xr import bindings

C_PROGRAM = r"""
#include <stddef.h>
#include <stdio.h>
#include <X11/Xlib.h>
#include <GL/glx.h>
#include <EGL/egl.h>
#define XR_USE_PLATFORM_XLIB
#define XR_USE_PLATFORM_EGL
#define XR_USE_GRAPHICS_API_OPENGL
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>
#define F(s, f) printf(#s " " #f " %zu\n", offsetof(s, f))
int main(void) {
    printf("XrGraphicsBindingEGLMNDX size %zu\n", sizeof(XrGraphicsBindingEGLMNDX));
    F(XrGraphicsBindingEGLMNDX, next); F(XrGraphicsBindingEGLMNDX, getProcAddress);
    F(XrGraphicsBindingEGLMNDX, display); F(XrGraphicsBindingEGLMNDX, config);
    F(XrGraphicsBindingEGLMNDX, context);
    printf("XrGraphicsBindingOpenGLXlibKHR size %zu\n", sizeof(XrGraphicsBindingOpenGLXlibKHR));
    F(XrGraphicsBindingOpenGLXlibKHR, next); F(XrGraphicsBindingOpenGLXlibKHR, xDisplay);
    F(XrGraphicsBindingOpenGLXlibKHR, visualid); F(XrGraphicsBindingOpenGLXlibKHR, glxFBConfig);
    F(XrGraphicsBindingOpenGLXlibKHR, glxDrawable);
    F(XrGraphicsBindingOpenGLXlibKHR, glxContext);
    printf("types %d %d %d\n", XR_TYPE_GRAPHICS_BINDING_EGL_MNDX,
           XR_TYPE_GRAPHICS_BINDING_OPENGL_XLIB_KHR, XR_TYPE_GRAPHICS_BINDING_OPENGL_WIN32_KHR);
    return 0;
}
"""


def c_layout(tmp_path) -> dict[str, int]:
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (apt install gcc)")
    source, program = tmp_path / "layout.c", tmp_path / "layout"
    source.write_text(C_PROGRAM)
    build = subprocess.run(
        [cc, "-o", str(program), str(source)], capture_output=True, text=True, check=False
    )
    if build.returncode != 0:
        pytest.skip(f"the OpenXR/EGL/GLX headers do not compile here: {build.stderr[:300]}")
    out = subprocess.run([str(program)], capture_output=True, text=True, check=True).stdout
    layout = {}
    for line in out.splitlines():
        if line.startswith("types"):
            layout["egl"], layout["xlib"], layout["win32"] = map(int, line.split()[1:])
        else:
            struct, field, value = line.split()
            layout[f"{struct}.{field}"] = int(value)
    return layout


def test_binding_structs_match_the_headers(tmp_path):
    layout = c_layout(tmp_path)
    egl, xlib = bindings.GraphicsBindingEGLMNDX, bindings.GraphicsBindingOpenGLXlibKHR
    assert ctypes.sizeof(egl) == layout["XrGraphicsBindingEGLMNDX.size"]
    for ours, theirs in [
        ("next", "next"),
        ("get_proc_address", "getProcAddress"),
        ("display", "display"),
        ("config", "config"),
        ("context", "context"),
    ]:
        assert getattr(egl, ours).offset == layout[f"XrGraphicsBindingEGLMNDX.{theirs}"]
    assert ctypes.sizeof(xlib) == layout["XrGraphicsBindingOpenGLXlibKHR.size"]
    for ours, theirs in [
        ("next", "next"),
        ("x_display", "xDisplay"),
        ("visualid", "visualid"),
        ("glx_fbconfig", "glxFBConfig"),
        ("glx_drawable", "glxDrawable"),
        ("glx_context", "glxContext"),
    ]:
        assert getattr(xlib, ours).offset == layout[f"XrGraphicsBindingOpenGLXlibKHR.{theirs}"]
    assert bindings.XR_TYPE_GRAPHICS_BINDING_EGL_MNDX == layout["egl"]
    assert bindings.XR_TYPE_GRAPHICS_BINDING_OPENGL_XLIB_KHR == layout["xlib"]
    assert bindings.XR_TYPE_GRAPHICS_BINDING_OPENGL_WIN32_KHR == layout["win32"]


def test_win32_binding_layout():
    """windows.h is not here: XrGraphicsBindingOpenGLWin32KHR is {XrStructureType type;
    const void* next; HDC hDC; HGLRC hGLRC;} — two handles after the common header."""
    win32 = bindings.GraphicsBindingOpenGLWin32KHR
    pointer = ctypes.sizeof(ctypes.c_void_p)
    assert win32.next.offset == pointer  # the 4-byte type padded to pointer alignment
    assert (win32.h_dc.offset, win32.h_glrc.offset) == (2 * pointer, 3 * pointer)
    assert ctypes.sizeof(win32) == 4 * pointer


def test_egl_binding_carries_the_contexts_handles():
    from btf_addon.xr.egl import EGLContext, EGLError

    try:
        egl = EGLContext()
    except EGLError as exc:
        pytest.skip(f"no EGL here: {exc}")
    try:
        b = bindings.egl_binding(egl)
        assert b.type == bindings.XR_TYPE_GRAPHICS_BINDING_EGL_MNDX
        assert (b.display, b.config, b.context) == (egl.display, egl.config, egl.context)
        assert b.get_proc_address == egl.get_proc_address != 0
    finally:
        egl.close()


def test_the_egl_context_offers_its_binding(monkeypatch):
    """The session's context factory (xr/desktop_gl.py): EGL's context carries the binding
    for its own handles; without a display no desktop binding is offered on Linux."""
    from btf_addon.xr.desktop_gl import desktop_kind, make_context
    from btf_addon.xr.egl import EGLError

    try:
        context = make_context("egl")
    except EGLError as exc:
        pytest.skip(f"no EGL here: {exc}")
    try:
        b = context.binding()
        assert b.type == bindings.XR_TYPE_GRAPHICS_BINDING_EGL_MNDX
        assert b.context == context.context and context.ctx.version_code >= 330
    finally:
        context.close()
    assert context.context is None
    monkeypatch.delenv("DISPLAY", raising=False)
    if sys.platform.startswith("linux"):
        assert desktop_kind() is None
