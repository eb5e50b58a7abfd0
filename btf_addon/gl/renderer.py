"""A standalone GLSL renderer (moderngl, offscreen) for plain-array scenes (scene/scene.py).

The progressive drawer (gl/drawer.py) on the moderngl adapter with one view, seen from the
scene's camera: the same shaders and steps as Blender's viewport. Used headless
(tests, benchmarks, and the stereo work: a caller may pass its own context).
"""

from __future__ import annotations

import numpy as np

from ..core.sampling.envmap import VirtualLights
from ..render.progressive import ProgressiveState
from ..scene.scene import Scene
from .converge import converge, rgb_top_first
from .drawer import ProgressiveDrawer, ViewAccumulation, check_size
from .moderngl_device import ModernGLDevice


class GLSLRenderer:
    """``ctx``: a moderngl context to draw in (None: a new headless EGL context)."""

    def __init__(self, scene: Scene, width: int, height: int, ctx=None):
        check_size(width, height)  # before a context is made for nothing
        self.scene = scene
        self.width, self.height = width, height
        self.device = ModernGLDevice(ctx)
        self.ctx = self.device.ctx
        self.drawer = ProgressiveDrawer(self.device, scene)
        self.view = ViewAccumulation(self.device, width, height)

    @property
    def state(self) -> ProgressiveState | None:
        return self.view.state

    def set_lights(self, lights: VirtualLights, per_pass: int) -> None:
        self.view.set_lights(lights, per_pass)

    def _pose(self) -> tuple[np.ndarray, np.ndarray]:
        """The scene camera's clip_from_world and shader vector at this size."""
        cam = self.scene.camera
        return cam.clip_from_world(self.width / self.height), cam.shader_vector()

    def restart(self) -> None:
        """Clear the accumulation and draw the depth pre-pass and the World."""
        self.drawer.restart(self.view, *self._pose())

    def render_pass(self) -> int:
        """Add the next batch of lights; returns how many were added (0 once converged)."""
        if self.view.state is None:
            raise RuntimeError("set_lights first")
        return self.drawer.add_batch(self.view)

    def resolve(self) -> np.ndarray:
        """(height, width, 3) float32 linear image, row 0 at the top."""
        self.drawer.resolve(self.view)
        return rgb_top_first(self.view.read())

    def render(self, lights: VirtualLights, per_pass: int | None = None) -> np.ndarray:
        """``lights`` to convergence over the World, ``per_pass`` a batch (None: all in one),
        each batch jittered by ``view.jitter`` (None: pixel centres); as ``resolve``."""
        self.set_lights(lights, per_pass or len(lights.pdf))
        drawn = converge(self.drawer, self.view, *self._pose(), film=self.view.jitter)
        return rgb_top_first(drawn.image)

    def release(self) -> None:
        self.view.release()
        self.drawer.release()
        self.device.close()
