"""A Blender light → ``scene.lights`` in Cycles' units (power in watts, colour, exposure)."""

from __future__ import annotations

import math

import numpy as np

from ...scene.lights import AreaLight, Light, PointLight, SunLight

# Blender's Area light shapes (its RNA enum identifiers) that have a separate Y size, and those
# with round outlines.
SHAPES_WITH_SIZE_Y = frozenset({"RECTANGLE", "ELLIPSE"})
ROUND_SHAPES = frozenset({"DISK", "ELLIPSE"})


def export_light(light, world_from_light: np.ndarray, messages: list[str]) -> Light | None:
    """``light``: a ``bpy.types.Light``; ``world_from_light``: (4, 4) float64 (the instance's
    matrix). None, with a message, for a light type the renderers do not draw."""
    strength = np.array(light.color, dtype=np.float64) * light.energy
    strength *= 2.0 ** getattr(light, "exposure", 0.0)  # Blender 4.x+ lights have exposure
    axes = world_from_light[:3, :3]
    position = world_from_light[:3, 3].copy()
    minus_z = -axes[:, 2] / max(np.linalg.norm(axes[:, 2]), 1e-30)
    if light.type == "SUN":
        return SunLight(-minus_z, strength)
    if light.type in {"POINT", "SPOT"}:
        spot = {}
        if light.type == "SPOT":
            spot = dict(
                axis=minus_z,
                cos_half_angle=math.cos(light.spot_size / 2),
                blend=float(light.spot_blend),
            )
        return PointLight.from_power(
            position, strength, radius=float(light.shadow_soft_size), **spot
        )
    if light.type == "AREA":
        if getattr(light, "spread", math.pi) < math.pi - 1e-6:
            messages.append(f"area light {light.name!r}: spread is rendered as 180°")
        size_y = light.size_y if light.shape in SHAPES_WITH_SIZE_Y else light.size
        # The object's scale stretches the light, as in Cycles.
        return AreaLight.from_power(
            position,
            minus_z,
            axes[:, 0] * light.size / 2,
            axes[:, 1] * size_y / 2,
            strength,
            ellipse=light.shape in ROUND_SHAPES,
        )
    messages.append(f"{light.type.lower()} light {light.name!r} is not supported")
    return None
