"""Evaluate BTFs at query lists through the GLSL shaders on a standalone moderngl context.

Each query occupies one texel of two RGBA32F query textures; a full-screen draw runs the shared
``btf_evaluate`` GLSL function once per fragment into an RGBA32F target. The same shader bodies run
inside Blender (tests/blender_gpu_query.py); tests compare both with the numpy reference.
"""

from __future__ import annotations

import sys

import numpy as np

from ..core.codecs.packed import pack
from ..core.errors import DeviceError
from ..core.model import BTF, DelegatingBTF, Queries
from . import host_context
from .interface import QUERY_SHADER, ShaderCompileError

#: What to install where no EGL context can be made (a DeviceError: exit 2, fixable).
EGL_ADVICE = (
    "Install Mesa's EGL and DRI drivers (Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 "
    "libgl1-mesa-dri) or a GPU driver"
)

QUERY_TILE = 1024  # queries per row of the query textures / render target


def query_textures(q: Queries) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Valid queries → two (h, w, 4) float32 images and the target size (w, h)."""
    n = len(q.uv)
    w = min(max(n, 1), QUERY_TILE)
    h = -(-n // w) if n else 1
    a = np.zeros((h * w, 4), dtype=np.float32)
    b = np.zeros((h * w, 4), dtype=np.float32)
    a[:n] = np.column_stack([q.uv, q.theta_i, q.phi_i])
    b[:n, :2] = np.column_stack([q.theta_v, q.phi_v])
    b[:n, 2] = 1.0  # valid marker: padding texels stay black
    return a.reshape(h, w, 4), b.reshape(h, w, 4), (w, h)


def create_gl_context():
    """A headless moderngl context: EGL on Linux (no display needed), the platform's own
    elsewhere. It is current afterwards; a host's context it displaced is remembered
    (gl/host_context.py) and given back at exit."""
    import moderngl

    backend = {"backend": "egl"} if sys.platform.startswith("linux") else {}
    host_context.before_ours()
    try:
        ctx = moderngl.create_standalone_context(**backend)
    except Exception as exc:  # glcontext raises plain Exceptions
        raise DeviceError(f"no headless OpenGL context through EGL ({exc}). {EGL_ADVICE}") from None
    host_context.mark_ours()
    return ctx


def make_current(ctx) -> None:
    """Make ``ctx`` the current OpenGL context. moderngl sends every call to whichever context
    is current, so each user of a context makes it current before its work. moderngl's own
    ``with ctx`` is not used: its exit leaves no context current, which Blender's own drawing
    (epoxy) aborts on; a host context displaced here is given back at exit."""
    host_context.before_ours()
    ctx.mglo.__enter__()


def compile_program(ctx, interface=QUERY_SHADER):
    import moderngl

    vs, fs = interface.glsl_330()
    try:
        return ctx.program(vertex_shader=vs, fragment_shader=fs)
    except moderngl.Error as exc:
        raise ShaderCompileError(
            f"GLSL shader {interface.name!r} failed to compile:\n{exc}"
        ) from None


def upload_tables(ctx, btf: BTF):
    """A BTF's packed tables as two R32F moderngl textures (ints, floats), nearest filtering."""
    packed = pack(btf)
    textures = tuple(
        ctx.texture(a.shape[::-1], 1, a.tobytes(), dtype="f4") for a in (packed.ints, packed.floats)
    )
    for tex in textures:
        tex.filter = (ctx.NEAREST, ctx.NEAREST)
    return textures


class GLSLEvaluator:
    """Valid queries → (M, 3) float64 values by the query shader on a moderngl context; the
    BTF's packed tables stay uploaded between calls."""

    def __init__(self, btf: BTF, ctx=None):
        self.ctx = ctx or create_gl_context()
        make_current(self.ctx)
        self.int_tex, self.float_tex = upload_tables(self.ctx, btf)
        self.program = compile_program(self.ctx)
        quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype=np.float32)
        self.vbo = self.ctx.buffer(quad.tobytes())
        self.vao = self.ctx.vertex_array(self.program, [(self.vbo, "2f", "pos")])
        for slot, _type, name in QUERY_SHADER.samplers:
            if name in self.program:
                self.program[name].value = slot

    def __call__(self, q: Queries) -> np.ndarray:
        make_current(self.ctx)
        n = len(q.uv)
        a, b, (w, h) = query_textures(q)
        tex_a = self.ctx.texture((w, h), 4, a.tobytes(), dtype="f4")
        tex_b = self.ctx.texture((w, h), 4, b.tobytes(), dtype="f4")
        target = self.ctx.texture((w, h), 4, dtype="f4")
        fbo = self.ctx.framebuffer(color_attachments=[target])
        try:
            for tex in (tex_a, tex_b):
                tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self.int_tex.use(0)
            self.float_tex.use(1)
            tex_a.use(2)
            tex_b.use(3)
            fbo.use()
            self.ctx.viewport = (0, 0, w, h)
            self.vao.render()
            out = np.frombuffer(fbo.read(components=4, dtype="f4"), dtype=np.float32)
        finally:
            for obj in (fbo, target, tex_a, tex_b):
                obj.release()
        return out.reshape(h * w, 4)[:n, :3].astype(np.float64)


def glsl_btf(btf: BTF, ctx=None) -> DelegatingBTF:
    """``btf`` evaluated by the GLSL shaders (moderngl, headless EGL unless ``ctx`` is given)."""
    return DelegatingBTF(btf, GLSLEvaluator(btf, ctx))
