"""One view drawn to convergence: restart, every batch of its lights, resolve, read back.

The standalone renderer (gl/renderer.py), stereo captures (gl/stereo_capture.py) and F12's
GLSL fallback (blender/glsl_fallback.py) all draw a still view this way; the viewport and the
headset eyes instead add batches across redraws (blender/viewport.py, gl/eye.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..render.pixel_filter import PixelFilter
from .drawer import ProgressiveDrawer, ViewAccumulation

#: The fraction of the lights added so far (after each batch, 1.0 after the last) → whether
#: to go on; False stops the view where it is (a cancelled render).
Progress = Callable[[float], bool]


@dataclass(frozen=True, eq=False)
class Converged:
    """``image``: (height, width, 4) float32 resolved image, row 0 at the bottom (OpenGL's
    order, Blender's render results'); ``lights``: how many were accumulated; ``stopped``:
    ``progress`` stopped the view before its last batch, so ``image`` is what was drawn so
    far."""

    image: np.ndarray
    lights: int
    stopped: bool


def rgb_top_first(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) float32 of a bottom-first (h, w, 4) image, row 0 at the top (numpy's and
    image files' order)."""
    return np.ascontiguousarray(image[::-1, :, :3])


def converge(
    drawer: ProgressiveDrawer,
    view: ViewAccumulation,
    clip_from_world: np.ndarray,
    camera,
    *,
    film: PixelFilter | None = None,
    transparent: bool = False,
    progress: Progress | None = None,
) -> Converged:
    """Draw ``view`` (its lights set: ``ViewAccumulation.set_lights``) from ``clip_from_world``
    and ``camera`` (as ``ProgressiveDrawer.restart``) until all its lights are added or
    ``progress`` says stop, then resolve and read it. ``film``: each batch at the filter's next
    subpixel offset (None: pixel centres); ``transparent``: no World, neither in the jittered
    batches nor behind the surfaces (premultiplied alpha 0 there)."""
    if view.state is None:
        raise RuntimeError("set the view's lights first")
    # Set together: a jittered batch with the World in it gives every pixel a sum, and the
    # transparent resolve would then find no background to leave out.
    view.jitter, view.jitter_world = film, not transparent
    drawer.restart(view, clip_from_world, camera)
    state = view.state
    stopped = False
    while drawer.add_batch(view):
        if progress is not None and not progress(state.done / state.total):
            stopped = not state.converged  # a stop after the last batch cancels nothing
            break
    drawer.resolve(view, transparent_background=transparent)
    return Converged(view.read(), state.done, stopped)
