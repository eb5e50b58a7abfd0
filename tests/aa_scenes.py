"""Scenes of the anti-aliasing tests (tests/kernels and tests/gl test_antialiasing.py) and
benchmarks/bench_aa.py: an edge whose filtered image is known exactly, and a checkerboard
receding to the horizon (the aliasing case)."""

from __future__ import annotations

import numpy as np

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.grid import UBO2003
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.pixel_filter import PixelFilter
from btf_addon.scene.primitives import plane
from btf_addon.scene.scene import Camera, Material, Scene, look_at

W, H = 24, 6  # a strip across one vertical edge


def rel_rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))


def edge_scene():
    """A black half-plane (x < 0) under a white World, seen straight from above: the column of
    its edge, in raster units, is ``edge_x``. Each pixel's exact filtered value is then the
    filter's mass beyond the edge — no renderer needed for the reference."""
    half = plane(40.0, material=0)
    half.world_from_object = np.eye(4)
    half.world_from_object[0, 3] = -20.0  # covers x ∈ [−40, 0]
    eye = (0.37, 0.0, 10.0)  # the edge falls between pixel centres
    cam = Camera(look_at(eye, (0.37, 0.0, 0.0), up=(0.0, 1.0, 0.0)), perspective=False)
    cam.ortho_scale = 12.0  # 0.5 world units per pixel
    scene = Scene([half], [Material(LambertianBTF(0.0))], cam, Environment.constant((1, 1, 1)))
    clip = cam.clip_from_world(W / H) @ np.array([0.0, 0.0, 0.0, 1.0])
    edge_x = (clip[0] / clip[3] + 1.0) / 2.0 * W
    return scene, edge_x


def expected_edge(pixel_filter: PixelFilter, edge_x: float) -> np.ndarray:
    """(W,) fraction of each pixel's filter mass on the white side (x > edge_x)."""
    t = edge_x - (np.arange(W) + 0.5)  # edge relative to each pixel centre
    r = pixel_filter.radius
    inside = pixel_filter.cdf(np.minimum(np.abs(t), r)) / (2 * pixel_filter.cdf(r))
    return 0.5 - np.sign(t) * inside


def checker_btf(texels: int = 2) -> DenseBTF:
    """A Lambertian checkerboard (albedo 0.9 / 0.1) as a dense BTF: value ρ/π·cos θi."""
    cos_i = UBO2003.directions()[:, 2]
    albedo = np.where(np.add.outer(np.arange(texels), np.arange(texels)) % 2 == 0, 0.9, 0.1)
    data = albedo[None, None, :, :, None] * (cos_i / np.pi)[None, :, None, None, None]
    data = np.broadcast_to(data, (UBO2003.size, UBO2003.size, texels, texels, 3))
    return DenseBTF(np.ascontiguousarray(data), name="checker")


def horizon_scene():
    """A checkered plane receding to the horizon: far squares are far below a pixel."""
    ground = plane(400.0, uv_repeats=800.0, material=0)
    cam = Camera(look_at((0.0, 0.0, 1.0), (0.0, 12.0, 0.0)), fov_y_rad=np.radians(50.0))
    env = Environment.constant((1.0, 1.0, 1.0))
    return Scene([ground], [Material(checker_btf())], cam, env)
