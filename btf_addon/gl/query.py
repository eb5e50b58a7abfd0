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
from .interface import BAKE_QUERY_SHADER, QUERY_SHADER, ShaderCompileError

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
        self.vao, self.vbo = _quad(self.ctx, self.program)
        for slot, _type, name in QUERY_SHADER.samplers:
            if name in self.program:
                self.program[name].value = slot

    def __call__(self, q: Queries) -> np.ndarray:
        make_current(self.ctx)
        a, b, size = query_textures(q)
        return _draw_queries(self.ctx, self.vao, (self.int_tex, self.float_tex), a, b, size)[
            : len(q.uv)
        ]


def _quad(ctx, program):
    quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype=np.float32)
    vbo = ctx.buffer(quad.tobytes())
    return ctx.vertex_array(program, [(vbo, "2f", "pos")]), vbo


def _draw_queries(ctx, vao, tables, a: np.ndarray, b: np.ndarray, size) -> np.ndarray:
    """One full-screen draw of ``vao`` with ``tables`` on texture units 0, 1 and the query
    images ``a``, ``b`` on 2, 3 → (h·w, 3) float64 values, a texel per query."""
    w, h = size
    tex_a = ctx.texture((w, h), 4, a.tobytes(), dtype="f4")
    tex_b = ctx.texture((w, h), 4, b.tobytes(), dtype="f4")
    target = ctx.texture((w, h), 4, dtype="f4")
    fbo = ctx.framebuffer(color_attachments=[target])
    try:
        for tex in (tex_a, tex_b):
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
        for unit, tex in enumerate((*tables, tex_a, tex_b)):
            tex.use(unit)
        fbo.use()
        ctx.viewport = (0, 0, w, h)
        vao.render()
        out = np.frombuffer(fbo.read(components=4, dtype="f4"), dtype=np.float32)
    finally:
        for obj in (fbo, target, tex_a, tex_b):
            obj.release()
    return out.reshape(h * w, 4)[:, :3].astype(np.float64)


def glsl_bake_lookup(bake, tri, bary, wo, ctx=None, direction: bool = False) -> np.ndarray:
    """(N, 3) float64: the light bake's lookup (shaders/bake_lib.glsl) at bake triangles
    ``tri`` (N,), barycentrics ``bary`` (N, 2) and views ``wo`` (N, 3, the surface's frame):
    its value, or with ``direction`` its light direction; ``bake``: a render/light_bake.py
    LightBake."""
    from ..render.bake_playback import bake_textures

    ctx = ctx or create_gl_context()
    make_current(ctx)
    program = compile_program(ctx, BAKE_QUERY_SHADER)
    for slot, _type, name in BAKE_QUERY_SHADER.samplers:
        if name in program:
            program[name].value = slot
    tables = []
    for array in bake_textures(bake):
        h, w = array.shape[:2]
        channels = 1 if array.ndim == 2 else array.shape[2]
        tex = ctx.texture((w, h), channels, np.ascontiguousarray(array).tobytes(), dtype="f4")
        tex.filter = (ctx.NEAREST, ctx.NEAREST)
        tables.append(tex)
    n = len(tri)
    w = min(max(n, 1), QUERY_TILE)
    h = -(-n // w) if n else 1
    a = np.zeros((h * w, 4), dtype=np.float32)
    b = np.zeros((h * w, 4), dtype=np.float32)
    a[:n] = np.column_stack([tri, bary, np.ones(n)])
    b[:n, :3] = wo
    b[:n, 3] = float(direction)
    vao, vbo = _quad(ctx, program)
    try:
        out = _draw_queries(ctx, vao, tables, a.reshape(h, w, 4), b.reshape(h, w, 4), (w, h))
    finally:
        for obj in (vao, vbo, program, *tables):
            obj.release()
    return out[:n]


def glsl_btf(btf: BTF, ctx=None) -> DelegatingBTF:
    """``btf`` evaluated by the GLSL shaders (moderngl, headless EGL unless ``ctx`` is given)."""
    return DelegatingBTF(btf, GLSLEvaluator(btf, ctx))
