"""Blender's lights as plain data, in Cycles' units, and their packed layout for the kernels.

Units (checked against Cycles renders, tests/blender/test_cycles_compare.py):
- Sun: strength is irradiance (W/m²) perpendicular to the light.
- Point and Spot of power P watts: radiant intensity P/(4π) W/sr in every direction (a spot's
  cone only masks it, it does not concentrate it). A radius r > 0 makes it a disc of that radius
  facing the shaded point (soft shadows), with the same intensity.
- Spot mask: smoothstep((cos γ − cos(size/2)) / ((1 − cos(size/2)) · blend)), γ the angle off
  the spot's axis; blend 0 gives a hard edge.
- Area of power P: a one-sided Lambertian emitter of radiance P/(π · area) along its −Z, with
  shapes square, rectangle, disk and ellipse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LIGHT_FLOATS = 20  # per light in the packed layout: five float4 rows, see pack_lights
TYPE_SUN, TYPE_POINT, TYPE_AREA = 0, 1, 2


@dataclass
class SunLight:
    """A distant light: ``direction`` (3,) unit, from the surface towards the light, world space;
    ``irradiance`` (3,) RGB W/m² measured perpendicular to it (Blender's Sun strength × colour)."""

    direction: np.ndarray
    irradiance: np.ndarray


@dataclass
class PointLight:
    """A point or spot light: ``intensity`` (3,) W/sr = colour × power / 4π; ``radius`` > 0
    softens shadows. A spot has a unit ``axis`` (its emission direction), the cosine of its half
    cone angle and its blend; a point light has axis None."""

    position: np.ndarray
    intensity: np.ndarray
    radius: float = 0.0
    axis: np.ndarray | None = None
    cos_half_angle: float = -1.0
    blend: float = 0.0

    @classmethod
    def from_power(cls, position, power_rgb, **kwargs) -> PointLight:
        return cls(
            np.asarray(position, float), np.asarray(power_rgb, float) / (4 * np.pi), **kwargs
        )


@dataclass
class AreaLight:
    """A one-sided rectangle or ellipse centred at ``position``, emitting along ``normal``;
    ``half_u``, ``half_v`` (3,) are its half extents as world vectors; ``radiance`` (3,)."""

    position: np.ndarray
    normal: np.ndarray
    half_u: np.ndarray
    half_v: np.ndarray
    radiance: np.ndarray
    ellipse: bool = False

    @property
    def area(self) -> float:
        full = 4.0 * float(np.linalg.norm(np.cross(self.half_u, self.half_v)))
        return full * np.pi / 4 if self.ellipse else full

    @classmethod
    def from_power(cls, position, normal, half_u, half_v, power_rgb, ellipse=False) -> AreaLight:
        light = cls(
            *(np.asarray(v, float) for v in (position, normal, half_u, half_v)),
            radiance=np.zeros(3),
            ellipse=ellipse,
        )
        light.radiance = np.asarray(power_rgb, float) / (np.pi * max(light.area, 1e-30))
        return light


Light = SunLight | PointLight | AreaLight


def pack_lights(lights: list[Light]) -> np.ndarray:
    """(max(N, 1), LIGHT_FLOATS) float32, read by kernels/include/btf_lights.h:

    row 0: position (sun: direction towards the light), type;
    row 1: RGB (sun irradiance, point intensity, area radiance), radius;
    row 2: spot axis or area normal, cos of the spot's half angle (−1: no cone);
    row 3: area half extent u, spot smoothing factor 1/((1 − cos half) · blend) (0: hard edge);
    row 4: area half extent v, 1 for an ellipse or disk.
    """
    out = np.zeros((max(len(lights), 1), LIGHT_FLOATS), dtype=np.float32)
    for i, light in enumerate(lights):
        row = out[i]
        if isinstance(light, SunLight):
            row[0:3], row[3], row[4:7] = light.direction, TYPE_SUN, light.irradiance
        elif isinstance(light, PointLight):
            row[0:3], row[3] = light.position, TYPE_POINT
            row[4:7], row[7] = light.intensity, light.radius
            row[11] = -1.0
            if light.axis is not None:
                row[8:11], row[11] = light.axis, light.cos_half_angle
                width = (1.0 - light.cos_half_angle) * light.blend
                row[15] = 1.0 / width if width > 1e-12 else 0.0
        else:
            row[0:3], row[3] = light.position, TYPE_AREA
            row[4:7], row[8:11] = light.radiance, light.normal
            row[12:15], row[16:19], row[19] = light.half_u, light.half_v, float(light.ellipse)
    return out
