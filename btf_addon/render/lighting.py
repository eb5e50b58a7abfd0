"""The virtual lights a frame is shaded with, from the render settings and the scene."""

from __future__ import annotations

import numpy as np

from ..core.sampling.envmap import VirtualLights
from ..scene.scene import Scene
from .settings import Lighting, RenderSettings

#: Headlight irradiance: π makes a white Lambertian surface facing the viewer show 1.0.
HEADLIGHT_IRRADIANCE = np.pi


def frame_lights(
    settings: RenderSettings, scene: Scene, towards_viewer: np.ndarray
) -> VirtualLights:
    """``towards_viewer``: unit world direction from the scene to the viewer (the headlight)."""
    if settings.lighting is Lighting.HEADLIGHT:
        d = np.asarray(towards_viewer, dtype=np.float64)
        d = d / np.linalg.norm(d)
        return VirtualLights(d[None], np.full((1, 3), HEADLIGHT_IRRADIANCE), np.ones(1))
    return scene.environment.virtual_lights(settings.lights_total, seed=settings.seed)
