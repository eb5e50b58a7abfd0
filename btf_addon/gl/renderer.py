"""A standalone GLSL renderer (moderngl, offscreen) for plain-array scenes (scene/scene.py).

The same shaders as the viewport: a depth pre-pass, then batches of K virtual lights added into
a float target with depth test EQUAL (only the visible surface accumulates), the World drawn
behind. ``resolve`` divides by the number of lights accumulated so far. Used for headless
renders (``render --engine glsl``), the stereo/XTAL work, tests and benchmarks.
"""

from __future__ import annotations

import numpy as np

from ..core.envmap import VirtualLights
from ..render.progressive import ProgressiveState
from ..scene.lights import pack_lights
from ..scene.scene import Scene
from .interface import BACKGROUND_SHADER, SURFACE_SHADER
from .query import compile_program, create_gl_context, upload_tables


def _f32(m: np.ndarray) -> bytes:
    """Column-major float32 bytes of a matrix, as GLSL's mat4 expects."""
    return np.asarray(m, dtype=np.float32).T.tobytes()


class GLSLRenderer:
    def __init__(self, scene: Scene, width: int, height: int, ctx=None):
        if width < 1 or height < 1 or max(width, height) > 16384:
            raise ValueError(f"resolution {width}×{height} is outside 1…16384")
        self.scene = scene
        self.width, self.height = width, height
        self.ctx = ctx or create_gl_context()
        ctx = self.ctx
        self.surface = compile_program(ctx, SURFACE_SHADER)
        self.background = compile_program(ctx, BACKGROUND_SHADER)
        self.color = ctx.texture((width, height), 4, dtype="f4")
        self.depth = ctx.depth_texture((width, height))
        self.fbo = ctx.framebuffer(color_attachments=[self.color], depth_attachment=self.depth)
        self.bg_color = ctx.texture((width, height), 4, dtype="f4")
        self.bg_fbo = ctx.framebuffer(color_attachments=[self.bg_color])
        self._material_textures = [upload_tables(ctx, m.btf) for m in scene.materials]
        self._meshes = [self._upload_mesh(m) for m in scene.meshes]
        env = scene.environment
        image = np.ascontiguousarray(env.radiance[..., :3], dtype=np.float32)
        self.env_tex = ctx.texture((env.width, env.height), 3, image.tobytes(), dtype="f4")
        self.env_tex.filter = (ctx.LINEAR, ctx.LINEAR)
        self.env_tex.repeat_x, self.env_tex.repeat_y = True, False
        quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype=np.float32)
        self.quad = ctx.vertex_array(self.background, [(ctx.buffer(quad.tobytes()), "2f", "pos")])
        self.lights_tex = None
        scene_lights = pack_lights(scene.lights)  # (n, 20) = five RGBA texels per light
        self.scene_lights_tex = ctx.texture(
            (len(scene_lights) * 5, 1), 4, scene_lights.tobytes(), dtype="f4"
        )
        self.scene_lights_tex.filter = (ctx.NEAREST, ctx.NEAREST)
        self.state: ProgressiveState | None = None

    # --- uploads ----------------------------------------------------------------------------
    def _upload_mesh(self, mesh):
        buf = self.ctx.buffer(mesh.world_space_corners().tobytes())
        vao = self.ctx.vertex_array(self.surface, [(buf, "3f 3f 2f 4f", "pos", "nor", "uv", "tan")])
        return vao, mesh.material

    def set_lights(self, lights: VirtualLights, per_pass: int) -> None:
        n = len(lights.pdf)
        texels = lights.packed()  # (n, 8) = two RGBA texels per light
        if self.lights_tex is not None:
            self.lights_tex.release()
        self.lights_tex = self.ctx.texture((2 * n, 1), 4, texels.tobytes(), dtype="f4")
        self.lights_tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        self.state = ProgressiveState(total=n, per_pass=per_pass)

    # --- drawing ------------------------------------------------------------------------------
    def _camera_uniforms(self):
        cam = self.scene.camera
        return cam.clip_from_world(self.width / self.height), cam.shader_vector()

    def restart(self) -> None:
        """Clear the accumulation and draw the depth pre-pass and the World."""
        ctx = self.ctx
        clip_from_world, _ = self._camera_uniforms()
        self.bg_fbo.use()
        ctx.disable(ctx.DEPTH_TEST | ctx.BLEND)
        self.background["world_from_clip"].write(_f32(np.linalg.inv(clip_from_world)))
        self.background["viewport_size"].value = (self.width, self.height)
        env = self.scene.environment
        self.background["env_params"].value = (env.rotation_z_rad, 1.0)
        self.env_tex.use(0)
        self.background["environment"].value = 0
        self.quad.render()
        self.fbo.use()
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.fbo.color_mask = (False, False, False, False)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.depth_func = "<"
        self._draw_meshes(0, 0)
        self.fbo.color_mask = (True, True, True, True)
        if self.state is not None:
            self.state.restart()

    def _draw_meshes(self, first: int, count: int) -> None:
        clip_from_world, camera = self._camera_uniforms()
        self.surface["clip_from_world"].write(_f32(clip_from_world))
        self.surface["camera"].value = tuple(camera)
        for vao, material_index in self._meshes:
            material = self.scene.materials[material_index]
            ints, floats = self._material_textures[material_index]
            ints.use(0)
            floats.use(1)
            if self.lights_tex is not None:
                self.lights_tex.use(2)
            self.scene_lights_tex.use(3)
            for name, slot in (
                ("btf_int_tables", 0),
                ("btf_float_tables", 1),
                ("lights", 2),
                ("scene_lights", 3),
            ):
                self.surface[name].value = slot
            m = material.uv_transform()
            self.surface["uv_transform"].value = (m[0, 0], m[1, 0], m[0, 1], m[1, 1])
            self.surface["light_range"].value = (
                first,
                count,
                2.0**material.exposure,
                len(self.scene.lights),
            )
            vao.render()

    def render_pass(self) -> int:
        """Add the next batch of lights; returns how many were added (0 once converged)."""
        if self.state is None:
            raise RuntimeError("set_lights first")
        first, count = self.state.next_batch()
        if count == 0:
            return 0
        ctx = self.ctx
        self.fbo.use()
        ctx.enable(ctx.DEPTH_TEST | ctx.BLEND)
        ctx.depth_func = "=="  # only the surface the pre-pass found visible
        ctx.depth_mask = False
        ctx.blend_func = (ctx.ONE, ctx.ONE)
        try:
            self._draw_meshes(first, count)
        finally:
            ctx.depth_mask = True
            ctx.disable(ctx.BLEND)
        self.state.advance(count)
        return count

    def resolve(self) -> np.ndarray:
        """(height, width, 3) float32 linear image, row 0 at the top."""
        accum = np.frombuffer(self.color.read(), dtype=np.float32).reshape(
            self.height, self.width, 4
        )
        bg = np.frombuffer(self.bg_color.read(), dtype=np.float32).reshape(
            self.height, self.width, 4
        )
        done = max(self.state.done if self.state else 0, 1)
        covered = accum[..., 3:4] > 0
        image = np.where(covered, accum[..., :3] / done, bg[..., :3])
        return np.ascontiguousarray(image[::-1])  # OpenGL's row 0 is the bottom

    def render(self, lights: VirtualLights, per_pass: int | None = None) -> np.ndarray:
        self.set_lights(lights, per_pass or len(lights.pdf))
        self.restart()
        while self.render_pass():
            pass
        return self.resolve()

    def release(self) -> None:
        for obj in (
            self.color,
            self.depth,
            self.fbo,
            self.bg_color,
            self.bg_fbo,
            self.env_tex,
            self.scene_lights_tex,
        ):
            obj.release()
