"""One F12 frame on the OpenCL renderer: the sequence of renderer calls that F12
(blender/final_render.py) and the accuracy report's rungs (blender/accuracy/run.py) both run,
written once so that a rung is timed and measured exactly as F12 renders it."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..core.sampling.envmap import VirtualLights
from ..render.settings import RenderSettings
from .renderer import CLRenderer, RenderPasses

#: The light of the Sampled mode's direct pass when the caller has none: that pass writes only
#: Depth, Normal and UV (its Combined is replaced), so any light will do, and the World's
#: virtual lights need the plain sampling tables, which the Sampled mode never reads.
DATA_PASSES_ONLY = VirtualLights(np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 3)), np.ones(1))


def render_frame(
    renderer: CLRenderer,
    settings: RenderSettings,
    lights: VirtualLights | None,
    progress: Callable[[float], bool] | None = None,
    show: Callable[[np.ndarray], None] | None = None,
    transparent: bool = False,
) -> RenderPasses:
    """Every pass of one frame with the film and the mode of ``settings``, lit by the frame's
    virtual ``lights`` (render/lighting.py ``frame_lights``; None in the Sampled mode, which
    needs none).

    Sampled: Depth, Normal and UV from the deterministic kernel with the first light (cheap),
    then Combined path traced, ``show(combined)`` seeing the image after each progressive pass.
    Virtual Lights: every pass from ``lights`` over ``settings.aa_samples`` subpixels.
    ``progress(fraction)`` follows the Combined render; returning False stops it part-way (the
    image holds the work done so far). ``transparent``: Film › Transparent (the World left out
    where camera rays miss). The launch options come from ``settings`` too, so a rung of the
    accuracy report is launched as F12 launches it."""
    renderer.set_film(settings.film())
    # None: the environment's choice (BTF_FIXED_LAUNCHES), as on the command line.
    renderer.fixed_launch_split = settings.fixed_launch_split or None
    renderer.importance_sampling = settings.btf_importance_sampling
    renderer.clamp_indirect = settings.clamp_indirect
    renderer.samples_per_camera_ray = settings.samples_per_camera_ray
    renderer.adaptive_threshold = settings.noise_threshold
    renderer.transparent = transparent
    if not settings.sampled:
        return renderer.render_direct(lights, progress, aa_samples=settings.aa_samples)
    passes = renderer.render_direct(DATA_PASSES_ONLY if lights is None else lights.prefix(1))
    passes.combined = renderer.render_sampled(
        settings.samples, settings.seed, progress, max_bounces=settings.max_bounces, preview=show
    )
    return passes
