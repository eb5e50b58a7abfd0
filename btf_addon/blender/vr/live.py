"""What keeps Blender's VR session callback cheap per eye (issue 35): the drawer's uniforms
converted to Blender's types once, not once per mesh, and the depsgraph updates that change
what the eyes show told apart from those that do not.

- ``CachedUniformsDevice``: Blender's ``gpu`` adapter (``blender/gpu_draw.py``) converts every
  uniform of every draw (numpy → ``mathutils.Matrix`` or a tuple); a frame draws each mesh about
  three times per eye with the same matrices (depth pre-pass, lights, and again per piece of
  ``MAX_LIGHTS_PER_DRAW``). Here an array is converted once and found again by identity, and
  tuples (already what ``uniform_float`` takes) are passed on unconverted.
- ``drawn_data_changed``: Blender sends ``depsgraph_update_post`` for changes the eyes never
  see — the Scene's own properties (our exposure and VR settings, read every frame anyway), the
  scene camera moved, the window manager's XR data. Only objects that are drawn (anything but
  cameras), their data (meshes, curves, lights, …), materials, node groups, images and the World
  make the drawer re-export (and so restart the eyes)."""

from __future__ import annotations

import numpy as np

from ..gpu_draw import BlenderGPUDevice, _matrix

#: Converted arrays kept; the cache is emptied when it grows past this (a moving head makes
#: new clip_from_world and camera arrays every frame).
UNIFORM_CACHE_SIZE = 512

#: ID types whose updates never change the eyes' image (read each frame, or not drawn).
NOT_DRAWN_ID_TYPES = ("Scene", "WindowManager", "Screen", "WorkSpace", "Camera", "Text")


class CachedUniformsDevice(BlenderGPUDevice):
    """``BlenderGPUDevice`` whose ``draw`` converts each distinct uniform value once.
    ``conversions`` counts the conversions made (tests, the benchmark)."""

    def __init__(self) -> None:
        self._converted: dict[int, tuple[object, object]] = {}  # id → (the value, converted)
        self.conversions = 0

    def uniform(self, value):
        """``value`` as ``gpu``'s ``uniform_float`` takes it. A tuple goes as it is (a sequence
        of numbers is what it takes; the base adapter made an array and a list of each); an
        array or list is converted once (a Matrix for 2D, else a tuple) and found again by
        identity: the drawer hands every mesh of a view the same ``clip_from_world`` and
        ``camera`` arrays, made anew (never changed in place) when the view restarts. The
        cache holds the value itself, so its id cannot be reused while cached."""
        if isinstance(value, tuple):
            return value
        cached = self._converted.get(id(value))
        if cached is not None and cached[0] is value:
            return cached[1]
        array = np.asarray(value)
        converted = _matrix(array) if array.ndim == 2 else tuple(array.tolist())
        if len(self._converted) >= UNIFORM_CACHE_SIZE:
            self._converted.clear()
        self._converted[id(value)] = (value, converted)
        self.conversions += 1
        return converted

    def draw(self, program, vertices, uniforms, samplers) -> None:
        program.bind()
        for name, value in uniforms.items():
            program.uniform_float(name, self.uniform(value))
        for name, tex in samplers.items():
            program.uniform_sampler(name, tex)
        vertices.draw(program)


def _id_type(datablock) -> str:
    return type(datablock).__name__ if datablock is not None else ""


def drawn_data_changed(updates) -> bool:
    """Whether any of the depsgraph's ``updates`` (``depsgraph.updates``: each with ``id``) can
    change what the eyes draw (module docstring)."""
    for update in updates:
        datablock = update.id
        kind = _id_type(datablock)
        if kind == "Object":
            if getattr(datablock, "type", "") != "CAMERA":
                return True
        elif kind not in NOT_DRAWN_ID_TYPES:
            return True
    return False
