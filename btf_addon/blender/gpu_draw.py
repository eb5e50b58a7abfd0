"""The drawer's device adapter (gl/device.py) on Blender's ``gpu`` module: the viewport, F12's
GLSL fallback and any offscreen per-eye drawing run the one progressive drawer
(gl/drawer.py) through it.

Background Blender needs its GPU context first: draw inside ``RenderEngine.render()`` with
``bl_use_gpu_context``, in a draw callback, or after one rendered frame
(tests/blender_helpers.init_gpu_module).
"""

from __future__ import annotations

from collections.abc import Mapping

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from ..gl.device import DrawState
from ..gl.drawer import ProgressiveDrawer
from ..gl.interface import ShaderCompileError, ShaderInterface
from ..scene.scene import Scene

_shader_cache: dict[str, gpu.types.GPUShader] = {}
# ADDITIVE_PREMULT: ONE, ONE; ALPHA_PREMULT: ONE, ONE_MINUS_SRC_ALPHA (colour and alpha)
_BLEND = {"NONE": "NONE", "ADD": "ADDITIVE_PREMULT", "OVER": "ALPHA_PREMULT"}


def shader(interface: ShaderInterface) -> gpu.types.GPUShader:
    if interface.name not in _shader_cache:
        try:
            _shader_cache[interface.name] = gpu.shader.create_from_info(
                interface.blender_create_info()
            )
        except Exception as exc:  # Blender raises a bare Exception; the log is on the console
            raise ShaderCompileError(
                f"GLSL shader {interface.name!r} failed to compile ({exc}); see the console"
            ) from None
    return _shader_cache[interface.name]


def texture(array: np.ndarray, fmt: str) -> gpu.types.GPUTexture:
    """(h, w, c) or (h, w) float array → a GPU texture (rows uploaded as given)."""
    array = np.ascontiguousarray(array, dtype=np.float32)
    h, w = array.shape[:2]
    return gpu.types.GPUTexture(
        (w, h), format=fmt, data=gpu.types.Buffer("FLOAT", array.size, array.ravel())
    )


def _matrix(m: np.ndarray):
    import mathutils

    return mathutils.Matrix(np.asarray(m, dtype=np.float64).tolist())


class BlenderGPUDevice:
    """Targets are ``GPUOffScreen`` objects (always with a depth buffer); textures and batches
    are freed by Python's garbage collection, offscreens by ``release``."""

    @property
    def max_texture_size(self) -> int:
        """Checked before a BTF's tables are uploaded (core/codecs/gpu_fit.py)."""
        return gpu.capabilities.max_texture_size_get()

    def program(self, interface: ShaderInterface) -> gpu.types.GPUShader:
        return shader(interface)

    def texture(self, array: np.ndarray, *, linear: bool = False, wrap_x: bool = False):
        # The Python API has no sampler settings: Blender's defaults apply (the comparison
        # with the moderngl adapter, which sets them, is tests/blender/test_viewport_draw.py).
        array = np.asarray(array)
        return texture(array, "R32F" if array.ndim == 2 else "RGBA32F")

    def vertices(self, program, attributes: Mapping[str, np.ndarray]):
        return batch_for_shader(program, "TRIS", dict(attributes))

    def target(self, width: int, height: int, fmt: str, depth: bool) -> gpu.types.GPUOffScreen:
        return gpu.types.GPUOffScreen(width, height, format=fmt)

    def target_texture(self, target: gpu.types.GPUOffScreen) -> gpu.types.GPUTexture:
        return target.texture_color

    def bound(self, target: gpu.types.GPUOffScreen):
        return target.bind()  # restores the previous framebuffer on exit

    def clear(self, colour: tuple[float, float, float, float]) -> None:
        gpu.state.active_framebuffer_get().clear(color=colour, depth=1.0)

    def set_state(self, state: DrawState) -> None:
        gpu.state.depth_test_set(state.depth_test)
        gpu.state.depth_mask_set(state.depth_write)
        gpu.state.color_mask_set(*(state.colour_write,) * 4)
        gpu.state.blend_set(_BLEND[state.blend])

    def draw(self, program, vertices, uniforms, samplers) -> None:
        program.bind()
        for name, value in uniforms.items():
            value = np.asarray(value)
            if value.ndim == 2:
                program.uniform_float(name, _matrix(value))
            else:
                program.uniform_float(name, tuple(value.tolist()))
        for name, tex in samplers.items():
            program.uniform_sampler(name, tex)
        vertices.draw(program)

    def read(self, target: gpu.types.GPUOffScreen) -> np.ndarray:
        w, h = target.width, target.height
        with target.bind():
            pixels = gpu.state.active_framebuffer_get().read_color(0, 0, w, h, 4, 0, "FLOAT")
        pixels.dimensions = w * h * 4
        return np.array(pixels, dtype=np.float32).reshape(h, w, 4)

    def release(self, *objects) -> None:
        for obj in objects:
            if isinstance(obj, gpu.types.GPUOffScreen):
                obj.free()


def scene_drawer(scene: Scene, previous: ProgressiveDrawer | None = None) -> ProgressiveDrawer:
    """The progressive drawer of ``scene`` on Blender's gpu module (``previous``: reuse its
    unchanged uploads, gl/drawer.py)."""
    device = previous.device if previous is not None else BlenderGPUDevice()
    return ProgressiveDrawer(device, scene, previous)
