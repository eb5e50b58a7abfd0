"""The drawer's device adapter (gl/device.py) on moderngl: a standalone EGL context (headless
renders, tests, benchmarks). moderngl is imported by the context's creation only.

moderngl sends every call to whichever OpenGL context is current, not to the one its objects
belong to: with two contexts in a process (two renderers, or moderngl inside Blender) drawing
would land in the wrong one. So the adapter makes its context current before its own work
(creations, a bound target's draws, reads, releases) and leaves it current, as a new context
is: moderngl's ``with ctx`` would not restore the previous one but leave none current, which
a host such as Blender cannot draw (or exit) with.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.errors import DeviceError
from .device import DrawState
from .interface import ShaderInterface
from .query import compile_program, create_gl_context, make_current

_TARGET_DTYPES = {"RGBA32F": ("f4", np.float32), "RGBA16F": ("f2", np.float16)}
_DEPTH_FUNCS = {"LESS": "<", "EQUAL": "=="}


@dataclass
class _Program:
    gl: Any  # moderngl.Program
    interface: ShaderInterface

    def release(self) -> None:
        self.gl.release()


@dataclass
class _Vertices:
    vao: Any
    buffer: Any

    def release(self) -> None:
        self.vao.release()
        self.buffer.release()


@dataclass
class _Target:
    colour: Any  # moderngl.Texture
    depth: Any  # moderngl.Texture or None
    fbo: Any
    dtype: type

    def release(self) -> None:
        for obj in (self.fbo, self.colour, self.depth):
            if obj is not None:
                obj.release()


def _alive(fbo) -> bool:
    import moderngl

    return fbo is not None and not isinstance(fbo.mglo, moderngl.InvalidObject)


class ModernGLDevice:
    """``ctx``: a moderngl context to draw in; None creates a headless EGL one, which
    ``close`` then releases."""

    def __init__(self, ctx=None):
        self.owns_context = ctx is None
        self.ctx = ctx if ctx is not None else create_gl_context()
        self._programs: dict[str, _Program] = {}
        # Checked before a BTF's tables are uploaded (core/codecs/gpu_fit.py).
        self.max_texture_size = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        # The largest side an image drawn into may have (``target``): the texture, renderbuffer
        # and viewport limits together.
        viewport = self.ctx.info.get("GL_MAX_VIEWPORT_DIMS", (self.max_texture_size,) * 2)
        self.max_target_size = min(
            self.max_texture_size,
            int(self.ctx.info.get("GL_MAX_RENDERBUFFER_SIZE", self.max_texture_size)),
            *(int(v) for v in viewport),
        )

    def _activate(self) -> None:
        make_current(self.ctx)

    def program(self, interface: ShaderInterface) -> _Program:
        if interface.name not in self._programs:
            self._activate()
            gl = compile_program(self.ctx, interface)
            self._programs[interface.name] = _Program(gl, interface)
        return self._programs[interface.name]

    def texture(self, array: np.ndarray, *, linear: bool = False, wrap_x: bool = False):
        array = np.ascontiguousarray(array, dtype=np.float32)
        h, w = array.shape[:2]
        channels = 1 if array.ndim == 2 else array.shape[2]
        self._activate()
        tex = self.ctx.texture((w, h), channels, array.tobytes(), dtype="f4")
        mode = self.ctx.LINEAR if linear else self.ctx.NEAREST
        tex.filter = (mode, mode)
        tex.repeat_x, tex.repeat_y = wrap_x, False
        return tex

    def vertices(self, program: _Program, attributes: Mapping[str, np.ndarray]) -> _Vertices:
        names = [name for _, _, name in program.interface.vertex_inputs]
        columns = [np.asarray(attributes[n], dtype=np.float32) for n in names]
        columns = [c[:, None] if c.ndim == 1 else c for c in columns]  # a float per vertex
        data = np.ascontiguousarray(np.hstack(columns))  # interleaved, in location order
        layout = " ".join(f"{c.shape[1]}f" for c in columns)
        self._activate()
        buffer = self.ctx.buffer(data.tobytes())
        vao = self.ctx.vertex_array(program.gl, [(buffer, layout, *names)])
        return _Vertices(vao, buffer)

    def target(self, width: int, height: int, fmt: str, depth: bool) -> _Target:
        """DeviceError (exit 2: a smaller size works) for a side beyond the driver's texture
        limit, checked before anything is allocated, or a target the driver then refuses
        (llvmpipe takes no texture over 1 GiB, whatever its 16384-pixel limit says)."""
        dtype, np_dtype = _TARGET_DTYPES[fmt]
        if max(width, height) > self.max_target_size:
            raise DeviceError(
                f"{width}×{height} is larger than the OpenGL driver's {self.max_target_size} "
                "pixels per side; choose a smaller size"
            )
        self._activate()
        made = []
        try:
            made.append(self.ctx.texture((width, height), 4, dtype=dtype))
            if depth:
                made.append(self.ctx.depth_texture((width, height)))
            fbo = self.ctx.framebuffer(
                color_attachments=[made[0]], depth_attachment=made[1] if depth else None
            )
        except Exception as exc:  # moderngl.Error: out of memory, an incomplete framebuffer
            for texture in made:
                texture.release()
            size = width * height * 4 * np.dtype(np_dtype).itemsize
            raise DeviceError(
                f"the OpenGL driver ({self.ctx.info.get('GL_RENDERER', '?')}) refuses a "
                f"{width}×{height} {fmt} image ({size / 2**30:.1f} GiB: {exc}); choose a "
                "smaller size"
            ) from None
        return _Target(made[0], made[1] if depth else None, fbo, np_dtype)

    def target_texture(self, target: _Target):
        return target.colour

    @contextmanager
    def bound(self, target: _Target) -> Iterator[None]:
        """``clear``, ``set_state`` and ``draw`` belong inside (the context is current)."""
        self._activate()
        previous = self.ctx.fbo
        target.fbo.use()  # also sets the viewport to the whole target
        try:
            yield
        finally:
            if _alive(previous):  # none at first in a standalone context, or released
                previous.use()

    def clear(self, colour: tuple[float, float, float, float]) -> None:
        fbo = self.ctx.fbo
        fbo.color_mask = (True, True, True, True)  # moderngl's clear honours the masks
        fbo.depth_mask = True
        fbo.clear(*colour, depth=1.0)

    def set_state(self, state: DrawState) -> None:
        ctx = self.ctx
        if state.depth_test == "NONE":
            ctx.disable(ctx.DEPTH_TEST)
        else:
            ctx.enable(ctx.DEPTH_TEST)
            ctx.depth_func = _DEPTH_FUNCS[state.depth_test]
        # Masks are per framebuffer in moderngl: set on the bound one (applied at once).
        ctx.fbo.depth_mask = state.depth_write
        ctx.fbo.color_mask = (state.colour_write,) * 4
        if state.blend == "ADD":
            ctx.enable(ctx.BLEND)
            ctx.blend_func = (ctx.ONE, ctx.ONE)
        elif state.blend == "OVER":  # premultiplied alpha: the same factors for colour and alpha
            ctx.enable(ctx.BLEND)
            ctx.blend_func = (ctx.ONE, ctx.ONE_MINUS_SRC_ALPHA)
        else:
            ctx.disable(ctx.BLEND)

    def draw(self, program: _Program, vertices: _Vertices, uniforms, samplers) -> None:
        gl = program.gl
        for name, value in uniforms.items():
            if name not in gl:  # optimised away by the GLSL compiler
                continue
            value = np.asarray(value, dtype=np.float32)
            if value.ndim == 2:
                gl[name].write(value.T.tobytes())  # GLSL's mat4 is column-major
            else:
                gl[name].value = tuple(value.tolist())
        slots = {name: slot for slot, _, name in program.interface.samplers}
        for name, tex in samplers.items():
            tex.use(slots[name])
            if name in gl:
                gl[name].value = slots[name]
        vertices.vao.render()

    def read(self, target: _Target) -> np.ndarray:
        w, h = target.colour.size
        self._activate()
        pixels = np.frombuffer(target.colour.read(), dtype=target.dtype)
        return pixels.astype(np.float32).reshape(h, w, 4)

    def release(self, *objects) -> None:
        self._activate()
        for obj in objects:
            if obj is not None:
                obj.release()

    def close(self) -> None:
        """Release the compiled programs, and the context if this adapter created it."""
        self.release(*self._programs.values())
        self._programs = {}
        if self.owns_context:
            self.ctx.release()
