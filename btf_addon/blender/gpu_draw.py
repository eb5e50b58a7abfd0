"""Drawing a plain-array scene with Blender's ``gpu`` module: the viewport and F12 share it.

Same shaders and the same steps as the standalone renderer (btf_addon/gl/renderer.py): a depth
pre-pass, batches of K virtual lights added into an RGBA32F target with depth test EQUAL, the
World drawn behind, and a resolve that divides by the lights accumulated so far. The caller
supplies the view (clip_from_world and the camera) — the viewport's region matrices or the
scene camera — and decides how many batches to draw per call.
"""

from __future__ import annotations

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from ..core.envmap import VirtualLights
from ..core.packed import pack
from ..gl.interface import (
    BACKGROUND_SHADER,
    RESOLVE_SHADER,
    SURFACE_SHADER,
    ShaderCompileError,
    ShaderInterface,
)
from ..render.progressive import ProgressiveState
from ..scene.lights import pack_lights
from ..scene.scene import Scene

_shader_cache: dict[str, gpu.types.GPUShader] = {}
QUAD = [(-1, -1), (1, -1), (-1, 1), (-1, 1), (1, -1), (1, 1)]


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


class SceneDrawer:
    """GPU resources for one exported scene; ``draw_*`` calls need an active framebuffer.

    Built from a ``previous`` drawer, it keeps every upload whose source did not change: BTF
    tables per BTF object (the exporter caches BTFs by file and fallback colour), vertex buffers
    per mesh (same object-space arrays and world matrix), the environment per Environment
    object. So a viewport edit re-uploads only what the depsgraph reported as changed."""

    def __init__(self, scene: Scene, previous: SceneDrawer | None = None):
        self.scene = scene
        self.surface = shader(SURFACE_SHADER)
        self.background_shader = shader(BACKGROUND_SHADER)
        self.resolve_shader = shader(RESOLVE_SHADER)
        old_tables = previous._table_uploads if previous else {}
        old_batches = previous._batch_uploads if previous else {}
        # Keyed by id() of the source, with the source kept alive so an id cannot be reused.
        self._table_uploads: dict[int, tuple[object, tuple]] = {}
        self._batch_uploads: dict[tuple, tuple[object, object]] = {}
        self.tables = []
        for material in scene.materials:
            key = id(material.btf)
            if key not in self._table_uploads:
                if key in old_tables:
                    self._table_uploads[key] = old_tables[key]
                else:
                    packed = pack(material.btf)
                    textures = (texture(packed.ints, "R32F"), texture(packed.floats, "R32F"))
                    self._table_uploads[key] = (material.btf, textures)
            self.tables.append(self._table_uploads[key][1])
        self.batches = []
        for mesh in scene.meshes:
            key = (id(mesh.positions), np.asarray(mesh.world_from_object).tobytes())
            if key not in self._batch_uploads:
                self._batch_uploads[key] = old_batches.get(key) or (
                    mesh.positions,
                    self._batch(mesh),
                )
            batch = self._batch_uploads[key][1]
            if batch is not None:
                self.batches.append((batch, mesh.material))
        env = scene.environment
        if previous is not None and previous.scene.environment is env:
            self.env_tex = previous.env_tex
        else:
            rgba = np.concatenate([env.radiance, np.ones((*env.radiance.shape[:2], 1))], axis=-1)
            # Rows go up top first: texture coordinate t = 0 is the first row uploaded, and the
            # shader reads t = 0 as the zenith (shaders/env_lib.glsl), as moderngl's renderer.
            self.env_tex = texture(rgba, "RGBA32F")
        self.uploads = {
            "tables": len(set(self._table_uploads) - set(old_tables)),
            "meshes": len(set(self._batch_uploads) - set(old_batches)),
        }
        self.quad_bg = batch_for_shader(self.background_shader, "TRIS", {"pos": QUAD})
        self.quad_resolve = batch_for_shader(self.resolve_shader, "TRIS", {"pos": QUAD})
        self.lights_tex = None
        # Blender's lights: five RGBA texels each (scene/lights.py), drawn without shadows.
        self.scene_lights_tex = texture(pack_lights(scene.lights).reshape(1, -1, 4), "RGBA32F")
        self.state: ProgressiveState | None = None

    def _batch(self, mesh):
        data = mesh.world_space_corners()
        if len(data) == 0:
            return None
        attributes = {
            "pos": data[:, 0:3],
            "nor": data[:, 3:6],
            "uv": data[:, 6:8],
            "tan": data[:, 8:12],
        }
        return batch_for_shader(self.surface, "TRIS", attributes)

    def set_lights(self, lights: VirtualLights, per_pass: int) -> None:
        n = len(lights.pdf)
        self.lights_tex = texture(lights.packed().reshape(1, 2 * n, 4), "RGBA32F")
        self.state = ProgressiveState(total=n, per_pass=per_pass)

    def draw_background(self, clip_from_world: np.ndarray, size: tuple[int, int]) -> None:
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("NONE")
        sh = self.background_shader
        sh.bind()
        sh.uniform_float("world_from_clip", _matrix(np.linalg.inv(clip_from_world)))
        sh.uniform_float("viewport_size", size)
        sh.uniform_float("env_params", (self.scene.environment.rotation_z_rad, 1.0))
        sh.uniform_sampler("environment", self.env_tex)
        self.quad_bg.draw(sh)

    def draw_surfaces(self, clip_from_world, camera, first: int, count: int, depth_only: bool):
        sh = self.surface
        sh.bind()
        sh.uniform_float("clip_from_world", _matrix(clip_from_world))
        sh.uniform_float("camera", tuple(camera))
        if depth_only:
            gpu.state.depth_test_set("LESS")
            gpu.state.depth_mask_set(True)
            gpu.state.color_mask_set(False, False, False, False)
            gpu.state.blend_set("NONE")
        else:
            gpu.state.depth_test_set("EQUAL")
            gpu.state.depth_mask_set(False)
            gpu.state.color_mask_set(True, True, True, True)
            gpu.state.blend_set("ADDITIVE_PREMULT")
        for batch, material_index in self.batches:
            material = self.scene.materials[material_index]
            ints, floats = self.tables[material_index]
            sh.uniform_sampler("btf_int_tables", ints)
            sh.uniform_sampler("btf_float_tables", floats)
            sh.uniform_sampler("lights", self.lights_tex)
            sh.uniform_sampler("scene_lights", self.scene_lights_tex)
            m = material.uv_transform()
            sh.uniform_float("uv_transform", (m[0, 0], m[1, 0], m[0, 1], m[1, 1]))
            exposure = 2.0**material.exposure
            sh.uniform_float("light_range", (first, count, exposure, len(self.scene.lights)))
            batch.draw(sh)
        gpu.state.color_mask_set(True, True, True, True)
        gpu.state.depth_mask_set(True)
        gpu.state.blend_set("NONE")
        gpu.state.depth_test_set("NONE")

    def restart(self, background, accumulation, clip_from_world, camera, size) -> None:
        """Draw the World into the ``background`` offscreen, clear the ``accumulation`` one and
        lay down its depth (the pre-pass the light batches test EQUAL against)."""
        with background.bind():
            self.draw_background(clip_from_world, size)
        with accumulation.bind():
            gpu.state.active_framebuffer_get().clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            self.draw_surfaces(clip_from_world, camera, 0, 0, depth_only=True)

    def add_batch(self, accumulation, clip_from_world, camera) -> int:
        """Add the next batch of lights into ``accumulation``; how many (0 once converged)."""
        first, count = self.state.next_batch()
        if count:
            with accumulation.bind():
                self.draw_surfaces(clip_from_world, camera, first, count, depth_only=False)
            self.state.advance(count)
        return count

    def draw_resolve(self, accumulation, background) -> None:
        sh = self.resolve_shader
        sh.bind()
        sh.uniform_sampler("accumulation", accumulation)
        sh.uniform_sampler("background", background)
        sh.uniform_float("resolve_params", (max(self.state.done if self.state else 0, 1), 0, 0, 0))
        self.quad_resolve.draw(sh)
