"""One eye's progressive image in a headset's frame loop: what Blender's VR session callback
(blender/vr/preview.py) and the XTAL bridge (xr/bridge.py) each do per eye and per frame.

Per frame: a view of the eye's size (a new one when the size changes), the virtual lights of
the render settings (new when the settings, the scene's drawer or — for the headlight — the
view direction change), a restart when the eye's matrices moved beyond
``HEAD_STILL_TOLERANCE`` (a tracked head is never exactly still) or the film changed, then the
frame's K lights. With anti-aliasing on (the settings' film filter) each frame's batch is drawn
at the next subpixel offset (gl/drawer.py): a still head converges to an anti-aliased eye
within the same K-lights budget — the frame budget measures the jittered batches' cost too.

``HeadsetEye`` is the whole eye as both VR paths keep it: that image, the ``FrameBudget`` that
picks K from the intervals between the eye's frames (or, given a ``SharedBudget``, the one
budget of all the eyes of a frame: one decision per frame, the same K for every eye; the
bridge's eyes share one), and the HUD quad (gl/hud.py) with its text (render/hud.py)
re-rasterised at most every ``HUD_REFRESH_S``. What differs between the
paths is passed in, never subclassed: the drawing device (Blender's ``gpu`` or moderngl), the
clock, the budget each frame (the runtime's display period in the bridge, the panel's in
Blender), where the eye sits on the head and the HUD's extra lines. ``HeadsetSettings`` is
what the user sets for both paths alike (``scene.btf_vr``, ``scene.btf_bridge``, the CLI).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.mat4 import inverse
from ..render.frame_budget import HEAD_STILL_TOLERANCE, FrameBudget, view_moved
from ..render.hud import MAX_CHARS, MAX_LINES, hud_quad, raster_text, status_lines
from ..render.lighting import frame_lights
from ..render.settings import Lighting, RenderSettings
from .device import Device
from .drawer import ProgressiveDrawer, ViewAccumulation
from .hud import HudDrawer

HUD_REFRESH_S = 0.25  # the frame time in the HUD changes every frame; re-rasterise 4× a second


@dataclass(frozen=True)
class HeadsetSettings:
    """What the user sets for a headset's eyes, one meaning and one default for Blender's VR
    session and the XTAL bridge alike. ``lights_total``: N virtual lights per eye, accumulated
    while the head is still; ``lights_per_frame``: a fixed K, None for K from the frame budget;
    ``budget_s``: the frame time K adapts to, None for the headset's display period (the
    runtime's in the bridge; Blender's VR session is never told it and holds
    ``render/frame_budget.DEFAULT_BUDGET_S``); ``exposure``: stops; ``show_hud``: the HUD."""

    lights_total: int = 200
    lights_per_frame: int | None = None
    budget_s: float | None = None
    exposure: float = 0.0
    show_hud: bool = True

    @property
    def use_budget(self) -> bool:
        return self.lights_per_frame is None


class EyeAccumulation:
    """The eye's ``view`` (None before the first frame), what its lights were made from and
    ``drawn``, the lights its last ``advance`` added."""

    def __init__(self) -> None:
        self.view: ViewAccumulation | None = None
        self._lights_key: tuple | None = None
        self.drawn = 0

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
        world_from_view = inverse(view_from_world)
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
        self.drawn = drawer.add_batch(view)
        return self.drawn, restarted

    def release(self) -> None:
        if self.view is not None:
            self.view.release()
        self.view, self._lights_key = None, None


class SharedBudget:
    """One ``FrameBudget`` for all the eyes of a headset's frame (issue 30 item 6: with one
    budget per eye, each deciding alone on its own intervals, one eye of a paced runtime
    reached 256 lights per frame while the other stayed at 1).

    K is decided once per frame, when the frame's first eye asks (``lights_for``): a frame
    starts when an eye asks that already asked since the last decision, so neither the eyes'
    order nor an index is needed (Blender's VR callback knows neither). The decision is fed
    the interval since the last one — the whole frame, every eye's work in it — and the lights
    the eyes drew in the last frame, their mean rounded up: the budget's model then prices a
    light drawn in every eye, and a frame where one eye had converged (drew none) counts half.
    Every eye of the frame gets that same K."""

    def __init__(self, budget_s: float, clock: Callable[[], float] = time.perf_counter):
        self.budget = FrameBudget(budget_s, clock=clock)
        self.eyes: list[HeadsetEye] = []
        self.k = self.budget.lights_per_frame
        self._asked: set[int] = set()

    def lights_for(self, eye: HeadsetEye) -> int:
        """K for ``eye``'s frame that starts now (its ``drawn``: the lights of its last)."""
        if not self._asked or id(eye) in self._asked:
            drawn = [e.drawn for e in self.eyes] or [eye.drawn]
            self.k = self.budget.frame(math.ceil(sum(drawn) / len(drawn)))
            self._asked.clear()
        self._asked.add(id(eye))
        return self.k


class HeadsetEye(EyeAccumulation):
    """One eye of a headset between frames (module docstring): its accumulation (``advance``,
    ``view``, ``drawn``), ``budget`` (its ``FrameBudget`` on ``clock``; with ``shared``, the
    ``SharedBudget``'s one budget of all the eyes, which this eye joins) and its HUD
    (``hud_lines``, ``hud_image``, ``hud``, drawn on ``device``)."""

    def __init__(
        self,
        device: Device,
        budget_s: float,
        clock: Callable[[], float] = time.perf_counter,
        shared: SharedBudget | None = None,
    ):
        super().__init__()
        self.device, self.clock = device, clock
        self.shared = shared
        if shared is not None:
            shared.eyes.append(self)
            self.budget = shared.budget
        else:
            self.budget = FrameBudget(budget_s, clock=clock)
        self.fixed_k: int | None = None  # this frame's fixed K; None: the budget's
        self.hud: HudDrawer | None = None  # one per eye: the eyes' texts differ (own times)
        self.hud_lines: list[str] = []
        self.hud_image: np.ndarray | None = None
        self.hud_time = -1.0

    def lights_this_frame(
        self, lights_per_frame: int | None = None, budget_s: float | None = None
    ) -> int:
        """K for the frame that starts now (call once per frame, before ``advance``): the
        fixed ``lights_per_frame``, or the budget's from the interval since the last call and
        the lights drawn in it (shared: the frame's one decision, ``SharedBudget``), holding
        ``budget_s`` from now on (None: the budget it held)."""
        if budget_s:
            self.budget.budget_s = budget_s
        self.fixed_k = lights_per_frame
        if lights_per_frame is not None:
            k = lights_per_frame
        elif self.shared is not None:
            k = self.shared.lights_for(self)
        else:
            k = self.budget.frame(self.drawn)
        self.drawn = 0
        return k

    def status(self) -> str:
        """How K is chosen, for the HUD: the budget's words, or the fixed K."""
        if self.fixed_k is None:
            return self.budget.status()
        return f"{self.fixed_k} lights/frame"

    def draw_hud(
        self,
        clip_from_view: np.ndarray,
        eye_offset: float,
        material: str,
        extra_lines: Sequence[str] = (),
        scale: float = 1.0,
    ) -> None:
        """The HUD into the BOUND target: ``material``, lights so far, ``status``, then
        ``extra_lines``; the text re-rasterised at most every ``HUD_REFRESH_S`` (and every
        frame once converged, when the last lights must show), the texture uploaded only
        when it changed. ``eye_offset``: this eye's offset from the head's centre along
        view +x, in view units; ``scale``: view units per metre (Blender's VR navigation
        scale; 1 in the bridge), so the quad keeps its size and distance in the headset."""
        view = self.view
        now = self.clock()
        if now - self.hud_time >= HUD_REFRESH_S or view.state.converged:
            lines = status_lines(material, view.state.done, view.state.total, self.status())
            lines = [*lines, *(line[:MAX_CHARS] for line in extra_lines)][:MAX_LINES]
            if lines != self.hud_lines:
                self.hud_lines, self.hud_image = lines, raster_text(lines)
            self.hud_time = now
        self.draw_hud_image(clip_from_view, eye_offset, scale)

    def draw_hud_image(
        self, clip_from_view: np.ndarray, eye_offset: float, scale: float = 1.0
    ) -> None:
        """The current HUD image again (e.g. into a capture), its text unchanged."""
        if self.hud is None:
            self.hud = HudDrawer(self.device)
        image = self.hud_image
        self.hud.set_image(image)
        corners = hud_quad(eye_offset / scale, image.shape[1] / image.shape[0]) * scale
        self.hud.draw(clip_from_view, corners)

    def release(self) -> None:
        super().release()
        if self.hud is not None:
            self.hud.release()
            self.hud = None
