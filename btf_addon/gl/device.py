"""The few GPU operations the progressive drawer (gl/drawer.py) needs, as an interface.

Two adapters implement it: moderngl (gl/moderngl_device.py, headless EGL: tests, CLI,
benchmarks) and Blender's ``gpu`` module (blender/gpu_draw.py: viewport, F12 fallback, and the
VR per-eye drawing to come). Objects the adapters return (programs, textures, vertex batches,
targets) are opaque to the drawer: it only hands them back to the same adapter.

Conventions shared by both adapters:
- arrays are float32; a texture is ``(h, w)`` or ``(h, w, 4)``, rows uploaded as given (row 0
  is texture coordinate t = 0);
- a target is a colour attachment (optionally with depth) of a Blender ``GPUOffScreen`` format
  name (``RGBA32F``, ``RGBA16F``); ``read`` returns ``(h, w, 4)`` float32 with row 0 at the
  bottom (OpenGL's order);
- uniforms are numpy arrays or float tuples; a ``(4, 4)`` array is a mat4 in the usual
  row-major numpy layout (the adapter transposes for GLSL where it must).
"""

from __future__ import annotations

from collections.abc import Mapping
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from .interface import ShaderInterface


@dataclass(frozen=True)
class DrawState:
    """Fixed-function state for the next draws. Names follow ``gpu.state``."""

    depth_test: str = "NONE"  # NONE | LESS | EQUAL
    depth_write: bool = True
    colour_write: bool = True
    # NONE | ADD (source + destination, colour and alpha) | OVER (premultiplied "over":
    # source + destination·(1 − source alpha), colour and alpha)
    blend: str = "NONE"


DEFAULT_STATE = DrawState()
# The depth pre-pass: nearest surface's depth, no colour.
DEPTH_PREPASS = DrawState(depth_test="LESS", colour_write=False)
# A batch of lights added on exactly the surface the pre-pass found (same vertices, same
# matrices → bit-identical depth), nothing else touched.
ADD_LIGHTS = DrawState(depth_test="EQUAL", depth_write=False, blend="ADD")
# An overlay with premultiplied alpha (the VR HUD, gl/hud.py) over what is drawn already.
OVER = DrawState(blend="OVER")


class Device(Protocol):
    def program(self, interface: ShaderInterface) -> Any:
        """A compiled program for ``interface`` (cached per interface name)."""

    def texture(self, array: np.ndarray, *, linear: bool = False, wrap_x: bool = False) -> Any:
        """``(h, w)`` (one channel) or ``(h, w, 4)`` float32 → a float texture. ``linear``
        and ``wrap_x`` matter only for ``texture()`` reads (``texelFetch`` ignores them)."""

    def vertices(self, program: Any, attributes: Mapping[str, np.ndarray]) -> Any:
        """A triangle list for ``program``: ``(n, k)`` float32 per vertex input name."""

    def target(self, width: int, height: int, fmt: str, depth: bool) -> Any:
        """An offscreen colour target of format ``fmt``, with a depth buffer if ``depth``."""

    def target_texture(self, target: Any) -> Any:
        """The colour texture of ``target``, to sample in a later draw."""

    def bound(self, target: Any) -> AbstractContextManager:
        """Draw into ``target`` inside the ``with``; the previous target is bound again after."""

    def clear(self, colour: tuple[float, float, float, float]) -> None:
        """Clear the bound target: colour to ``colour``, depth (if any) to 1 (far), whatever
        the write masks."""

    def set_state(self, state: DrawState) -> None: ...

    def draw(
        self,
        program: Any,
        vertices: Any,
        uniforms: Mapping[str, Any],
        samplers: Mapping[str, Any],
    ) -> None:
        """Draw ``vertices`` with ``program`` into the bound target."""

    def read(self, target: Any) -> np.ndarray:
        """``(h, w, 4)`` float32 colour of ``target``, row 0 at the bottom."""

    def release(self, *objects: Any) -> None:
        """Free GPU objects this adapter made (None is skipped)."""
