"""One eye's progressive image in a headset's frame loop: what Blender's VR session callback
(blender/vr/preview.py) and the XTAL bridge (xr/bridge.py) each do per eye and per frame.

Per frame: a view of the eye's size (a new one when the size changes), the virtual lights of
the render settings (new when the settings, the scene's drawer or — for the headlight — the
view direction change), a restart when the eye's matrices moved beyond
``HEAD_STILL_TOLERANCE`` (a tracked head is never exactly still) or the film changed, then the
frame's K lights. With anti-aliasing on (the settings' film filter) each frame's batch is drawn
at the next subpixel offset (gl/drawer.py): a still head converges to an anti-aliased eye
within the same K-lights budget — the frame budget measures the jittered batches' cost too.
"""

from __future__ import annotations

import numpy as np

from ..render.frame_budget import HEAD_STILL_TOLERANCE, view_moved
from ..render.lighting import frame_lights
from ..render.settings import Lighting, RenderSettings
from .drawer import ProgressiveDrawer, ViewAccumulation


class EyeAccumulation:
    """The eye's ``view`` (None before the first frame) and what its lights were made from."""

    def __init__(self) -> None:
        self.view: ViewAccumulation | None = None
        self._lights_key: tuple | None = None

    def advance(
        self,
        drawer: ProgressiveDrawer,
        size: tuple[int, int],
        settings: RenderSettings,
        clip_from_view: np.ndarray,
        view_from_world: np.ndarray,
        k: int,
        transparent: bool = False,
    ) -> tuple[int, bool]:
        """Add this frame's ``k`` (≥ 1) lights for the eye seen through ``clip_from_view`` and
        ``view_from_world`` ((4, 4) each) at ``size`` pixels. ``transparent``: the eye is
        resolved over a transparent background (no World in its jittered batches). Returns
        (lights added, whether the image was started over)."""
        size = tuple(size)
        if self.view is None or self.view.size != size:
            self.release()
            self.view = ViewAccumulation(drawer.device, *size)
        view = self.view
        world_from_view = np.linalg.inv(view_from_world)
        towards_viewer = world_from_view[:3, 2]
        lights_key = (settings.lighting, settings.lights_total, settings.seed, drawer.serial)
        if settings.lighting is Lighting.HEADLIGHT:  # the headlight follows the head
            lights_key += (tuple(towards_viewer.round(4)),)
        k = max(1, int(k))
        if lights_key != self._lights_key:
            view.set_lights(frame_lights(settings, drawer.scene, towards_viewer), k)
            self._lights_key = lights_key
        film = settings.film()
        film_changed = (view.jitter, view.jitter_world) != (film, not transparent)
        view.jitter, view.jitter_world = film, not transparent
        clip_from_world = clip_from_view @ view_from_world
        restarted = (
            film_changed
            or view.clip_from_world is None
            or view_moved(view.clip_from_world, clip_from_world, HEAD_STILL_TOLERANCE)
        )
        if restarted:
            drawer.restart(view, clip_from_world, [*world_from_view[:3, 3], 1.0])
        view.state.per_pass = k
        return drawer.add_batch(view), restarted

    def release(self) -> None:
        if self.view is not None:
            self.view.release()
        self.view, self._lights_key = None, None
