"""Standalone (headless) OpenGL contexts through moderngl over EGL."""

from __future__ import annotations

from . import host_context


def probe_egl() -> dict:
    """Create a tiny EGL context and report what it is. Raises RuntimeError when impossible."""
    try:
        import moderngl
    except ImportError as exc:
        raise RuntimeError(f"moderngl is not installed ({exc})") from None
    with host_context.kept():  # a host's context (Blender's) is current again afterwards
        try:
            ctx = moderngl.create_standalone_context(backend="egl")
        except Exception as exc:  # glcontext raises plain Exceptions for missing EGL/drivers
            raise RuntimeError(f"no EGL OpenGL context ({exc})") from None
        try:
            return {
                "renderer": ctx.info.get("GL_RENDERER", "?"),
                "vendor": ctx.info.get("GL_VENDOR", "?"),
                "version": ctx.info.get("GL_VERSION", "?"),
                "version_code": ctx.version_code,
            }
        finally:
            ctx.release()
