"""The bridge's drawing device: gl/moderngl_device.py's adapter on the session's context, with
two duties of the frame loop.

- **Interrupts.** moderngl builds a program's Python members from C and does not check the
  calls it makes there: a KeyboardInterrupt raised meanwhile leaves a NULL that it stores, and
  the process dies (SIGSEGV in ``MGLContext_program``; found by tests/xr/
  test_bridge_interrupts.py). Programs are compiled with Ctrl-C held back (core/interrupts.py);
  a compile lasts milliseconds to a second, then the interrupt lands.
- **Warm-up** (issue 30 item 7). The first frames of a run take seconds where later ones take
  milliseconds: the drawer's programs are compiled, the scene's tables and meshes uploaded,
  and a driver compiles its shader variants at their first draws (llvmpipe JIT-compiles each
  program for the state it is drawn with). ``spent`` sums, per kind, the seconds the device
  spent compiling programs (``"shader compile"``), uploading (``"uploads"``) and in draws of
  a program in a state never drawn before (``"first draws"``: the driver's variant compile,
  plus that draw's own work) since the last ``take_spent``, which the bridge reads after each
  frame to say why a frame was slow.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from ..core.interrupts import deferred
from ..gl.interface import ShaderInterface
from ..gl.moderngl_device import ModernGLDevice

COMPILE = "shader compile"
UPLOADS = "uploads"
FIRST_DRAWS = "first draws"


class BridgeDevice(ModernGLDevice):
    """``ModernGLDevice`` on ``ctx`` (module docstring); ``clock``: seconds, injectable."""

    def __init__(self, ctx, clock: Callable[[], float] = time.perf_counter):
        super().__init__(ctx)
        self.clock = clock
        self.spent: dict[str, float] = {}
        self._state = None
        self._drawn: set[tuple] = set()  # (program, state) pairs drawn so far

    def _timed(self, kind: str, started: float) -> None:
        self.spent[kind] = self.spent.get(kind, 0.0) + max(self.clock() - started, 0.0)

    def take_spent(self) -> dict[str, float]:
        """The seconds per kind since the last call (and forget them)."""
        spent, self.spent = self.spent, {}
        return spent

    def program(self, interface: ShaderInterface):
        if interface.name in self._programs:
            return self._programs[interface.name]
        started = self.clock()
        with deferred():
            program = super().program(interface)
        self._timed(COMPILE, started)
        return program

    def set_state(self, state) -> None:
        super().set_state(state)
        self._state = state

    def draw(self, program, vertices, uniforms, samplers) -> None:
        key = (program.interface.name, self._state)
        if key in self._drawn:
            super().draw(program, vertices, uniforms, samplers)
            return
        started = self.clock()
        super().draw(program, vertices, uniforms, samplers)
        self._drawn.add(key)
        self._timed(FIRST_DRAWS, started)

    def texture(self, array: np.ndarray, *, linear: bool = False, wrap_x: bool = False):
        started = self.clock()
        texture = super().texture(array, linear=linear, wrap_x=wrap_x)
        self._timed(UPLOADS, started)
        return texture

    def vertices(self, program, attributes):
        started = self.clock()
        vertices = super().vertices(program, attributes)
        self._timed(UPLOADS, started)
        return vertices
