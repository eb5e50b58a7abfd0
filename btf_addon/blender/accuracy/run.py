"""The accuracy report's renders, for the CLI's ``accuracy`` command and the Estimate Quality
vs Time operator alike.

The scene is exported once, at a reduced size (the preview), on the calling (main) thread;
after that everything is bpy-free and may run on a worker thread: each rung is rendered by the
final render's own OpenCL renderer (cl/renderer.py) exactly as F12 renders it: the frame's
virtual lights from render/lighting.py, then F12's sequence of calls (cl/frame.py
``render_frame``). One renderer serves every rung: a rung's film and texel filter are set on it
(a few small uploads), so the scene's BVH and tables are built and uploaded once. No GLSL
fallback: without OpenCL there is no F12 to measure, so it is an error.

With the light bake asked for (``run_bake_sweep``), the bake's knobs are measured after the
ladder against the same reference (render/accuracy/bake_sweep.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import bpy
import numpy as np

from ...cl.bake import BakeKnobs, bake_scene, baked_light, playback_grid, render_baked
from ...cl.context import OpenCLUnavailableError, create_context
from ...cl.frame import render_frame
from ...cl.renderer import CLRenderer
from ...core.errors import BTFError
from ...render.accuracy.bake_sweep import BakeResult, BakeRung, bake_rungs, sweep
from ...render.accuracy.bake_sweep import to_json as bake_json
from ...render.accuracy.ladder import (
    KNOBS,
    Estimate,
    Rung,
    ladder,
    quick_knobs,
    reference_settings,
)
from ...render.lighting import frame_lights
from ...render.settings import RenderSettings
from ...scene.analysis import analyse
from ...scene.scene import Scene
from ..export import export_scene
from ..sync import frame_size, render_settings

#: The preview's longest side in pixels: small enough that a ladder of ~13 rungs plus the
#: reference takes seconds to a minute on a CPU, large enough for the error maps to show where.
PREVIEW_LONGEST = 160


class QuickSizes:
    """The quick estimate's preview and reference (Quality vs Time's default): a third of the
    full estimate's pixels, half its reference samples — four times the quick ladder's most,
    so the reference's own noise adds at most 12 % to a rung's error — and the scene's own
    bounces, so the demo scene answers within a minute on two CPU cores (docs/accuracy.md,
    "Quality vs Time: quick and full")."""

    longest = 96
    reference_samples = 512
    reference_bounces = 0  # the reference takes max(this, the scene's max bounces)


def preview_size(full: tuple[int, int], longest: int = PREVIEW_LONGEST) -> tuple[int, int]:
    """``full`` (w, h) scaled so its longest side is ``longest`` (never enlarged), aspect kept,
    each side at least 1."""
    w, h = full
    k = min(1.0, longest / max(w, h))
    return max(1, round(w * k)), max(1, round(h * k))


class LadderRenderer:
    """``renderer(rung, progress)`` → (h, w, 3) float32 Combined, or None when ``progress``
    answered False (stopped part-way: the image is incomplete). ``setup()`` opens the device,
    builds (or loads) the kernels and uploads the scene; it may run on a worker thread (a first
    kernel compile takes minutes on some drivers: never on Blender's main thread) and fills
    ``setup_seconds`` and ``device_name``."""

    def __init__(
        self,
        scene: Scene,
        width: int,
        height: int,
        device_index: int | None = None,
        base: RenderSettings | None = None,
        transparent: bool = False,
    ):
        self.scene, self.width, self.height = scene, width, height
        self.transparent = transparent  # Film › Transparent, as F12 renders it
        self.device_index = device_index
        self.base = base or RenderSettings()
        self.ctx = None
        #: Every rung's renderer (None before setup), the scene's own film and texel filters
        #: until a rung sets others.
        self.renderer: CLRenderer | None = None
        self.setup_seconds, self.device_name = 0.0, ""

    def setup(self) -> None:
        if self.ctx is not None:
            return
        t0 = time.perf_counter()
        try:
            self.ctx = create_context(self.device_index)
        except OpenCLUnavailableError as exc:
            raise BTFError(
                f"the quality estimate measures the OpenCL final render, and OpenCL is "
                f"unavailable: {exc}"
            ) from None
        self.device_name = self.ctx.device_name
        self.renderer = CLRenderer(
            self.scene, self.width, self.height, self.ctx, analyse(self.scene), self.base.film()
        )
        self.setup_seconds = time.perf_counter() - t0

    def __call__(self, rung: Rung, progress: Callable[[float], bool]) -> np.ndarray | None:
        self.setup()
        settings = rung.settings
        # None (no texel filter knob on this rung): each material's own, as F12.
        self.renderer.set_texel_filter(rung.value("texel_filter"))
        stopped = False

        def step(fraction: float) -> bool:
            nonlocal stopped
            stopped = stopped or not progress(fraction)
            return not stopped

        cam = self.scene.camera
        lights = frame_lights(settings, self.scene, cam.world_from_camera[:3, 2])
        image = render_frame(self.renderer, settings, lights, step, transparent=self.transparent)
        image = image.combined
        return None if stopped else np.asarray(image[..., :3], dtype=np.float32)


def prepare(
    depsgraph,
    longest: int = PREVIEW_LONGEST,
    device_index: int | None = None,
    reference_samples: int = 1024,
    reference_bounces: int = 8,
    setup: bool = True,
    quick: bool = False,
) -> tuple[Estimate, list[Rung], LadderRenderer]:
    """On the main thread: the estimate's frame (the scene's settings and sizes), its rungs and
    the renderer (scene exported at the preview size). Raises BTFError for a scene without a
    camera or with no knob to trade (the headlight). ``setup=False`` leaves the device to
    ``set_up(estimate, renderer)`` on a worker thread. ``quick``: the quick estimate's rungs
    (QUICK_VALUES of the scene's own mode); the caller picks its smaller sizes (QUICK)."""
    scene = depsgraph.scene
    if scene.camera is None:
        raise BTFError(f"the scene {scene.name!r} has no camera to estimate from")
    base = render_settings(scene)  # with the film filter of scene.cycles
    filters = {m.btf.texel_filter for m in bpy.data.materials if m.btf.enabled}
    # The texel filter knob only where BTF materials exist, starting from the scene's own
    # filter where they share one.
    knobs = KNOBS if filters else tuple(k for k in KNOBS if k.name != "texel_filter")
    if quick:  # the scene's own mode, its work knob only (ladder.py QUICK_VALUES)
        knobs = quick_knobs()
    rungs = ladder(
        base, knobs, base_extra={"texel_filter": filters.pop()} if len(filters) == 1 else {}
    )
    if not rungs:
        raise BTFError(
            "no quality knob applies: the scene is lit by the headlight (one deterministic "
            "light); set Lighting to Environment"
        )
    full = frame_size(scene.render)  # as F12 sizes the frame
    preview = preview_size(full, longest)
    t0 = time.perf_counter()
    exported = export_scene(depsgraph, *preview, light_bake=False)
    export_seconds = time.perf_counter() - t0
    renderer = LadderRenderer(
        exported, *preview, device_index, base, transparent=scene.render.film_transparent
    )
    estimate = Estimate(
        base, preview, full, reference_settings(base, reference_samples, reference_bounces)
    )
    estimate.setup_seconds = export_seconds
    estimate.scene = scene.name
    if setup:
        set_up(estimate, renderer)
    return estimate, rungs, renderer


def set_up(estimate: Estimate, renderer: LadderRenderer) -> None:
    """The device part of the setup; its time joins the export's in ``setup_seconds``."""
    renderer.setup()
    estimate.setup_seconds += renderer.setup_seconds
    estimate.device = renderer.device_name


class BakeRunner:
    """Bake and play back at the ladder's preview (render/accuracy/bake_sweep.py's ``BakeFn``):
    the scene as the ladder exported it baked with the rung's knobs (cl/bake.py
    ``bake_scene``, the analysis deciding what), then its converged playback through the
    ladder's renderer (``render_baked`` with the film's subpixels, what the drawer converges
    to: tests/gl/test_bake_playback.py)."""

    def __init__(self, renderer: LadderRenderer, knobs: BakeKnobs):
        self.renderer, self.knobs = renderer, knobs

    def __call__(self, rung: BakeRung, progress: Callable[[float], bool]) -> BakeResult | None:
        self.renderer.setup()
        knobs = replace(
            self.knobs, spacing=rung.spacing, view_bins=rung.view_bins, samples=rung.samples
        )
        stopped = False

        def step(fraction: float) -> bool:
            nonlocal stopped
            stopped = stopped or not progress(fraction)
            return not stopped

        t0 = time.perf_counter()
        bake = bake_scene(self.renderer.scene, self.renderer.ctx, knobs, step)
        seconds = time.perf_counter() - t0
        if stopped:
            return None
        grid, light = playback_grid(bake), baked_light(bake)
        image = render_baked(self.renderer.renderer, grid, light)
        baked = [i for i, m in enumerate(bake.meshes) if m.baked]
        ones = np.zeros_like(light.ratio)
        ones[np.isin(grid.point_mesh, baked)] = 1.0
        seen = render_baked(
            self.renderer.renderer, grid, replace(light, ratio=ones), times_response=False
        )
        return BakeResult(image, seen[..., 0] > 0.999, seconds, bake.nbytes, len(baked))


def run_bake_sweep(
    estimate: Estimate,
    renderer: LadderRenderer,
    knobs: BakeKnobs,
    on_progress: Callable[[float, str], None] | None = None,
    cancelled: Callable[[], bool] = lambda: False,
) -> None:
    """The light bake's knobs against the estimate's reference (rendered first by the
    ladder's ``run``) into ``estimate.bake``; a cancel keeps the rungs finished."""
    if estimate.reference_image is None:
        return
    rungs = bake_rungs(knobs.spacing, knobs.view_bins, knobs.samples)
    runner = BakeRunner(renderer, knobs)
    points = sweep(rungs, runner, estimate.reference_image, on_progress, cancelled)
    estimate.bake = bake_json(points)
