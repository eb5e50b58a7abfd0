"""The help overlay: the current bindings drawn over the 3D viewport while help is on.

One POST_PIXEL draw handler for every 3D view, added when a Wiimote session starts and removed
when it ends; it draws only while the session's help is visible. Text goes through ``blf``
(Blender's font drawing), on a dark backdrop so it reads over any material. Not drawn in VR
itself: the VR session's HUD quad (blender/vr/preview.py) shows the same rows through
``current_help``).
"""

from __future__ import annotations

import blf
import bpy
import gpu
from gpu_extras.batch import batch_for_shader

from ...controllers.bindings import help_lines

_handler = None
_source = None  # a callable → (visible, bindings)


def _draw() -> None:
    lines = current_help()
    if not lines:
        return
    size, pad = 14, 8
    line_h = int(size * 1.5)
    width = 460
    height = line_h * len(lines) + 2 * pad
    x0, y0 = 20, 40
    shader = gpu.shader.from_builtin("UNIFORM_COLOR")
    quad = ((x0, y0), (x0 + width, y0), (x0, y0 + height), (x0 + width, y0 + height))
    batch = batch_for_shader(shader, "TRI_STRIP", {"pos": quad})
    gpu.state.depth_test_set("NONE")  # whatever an earlier draw left (4.2: LESS_EQUAL)
    gpu.state.blend_set("ALPHA")
    shader.uniform_float("color", (0.0, 0.0, 0.0, 0.6))
    batch.draw(shader)
    gpu.state.blend_set("NONE")
    font = 0
    blf.size(font, size)
    for i, (inputs, text) in enumerate(lines):
        y = y0 + height - pad - line_h * (i + 1) + 4
        blf.color(font, 1.0, 0.85, 0.4, 1.0)
        blf.position(font, x0 + pad, y, 0)
        blf.draw(font, inputs)
        blf.color(font, 1.0, 1.0, 1.0, 1.0)
        blf.position(font, x0 + pad + 190, y, 0)
        blf.draw(font, text)


def current_help() -> list[tuple[str, str]] | None:
    """The help rows while a session shows its help, else None (the VR HUD draws them too)."""
    if _source is None:
        return None
    visible, bindings = _source()
    return [("Wiimote", "(Home: hide)"), *help_lines(bindings)] if visible else None


def show(source) -> None:
    """Start drawing for ``source`` (→ (visible, bindings)); a no-op in background mode."""
    global _handler, _source
    _source = source
    if _handler is None and not bpy.app.background:
        _handler = bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_PIXEL")


def hide() -> None:
    global _handler, _source
    _source = None
    if _handler is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handler, "WINDOW")
        _handler = None


def register() -> None:
    pass


def unregister() -> None:
    hide()
