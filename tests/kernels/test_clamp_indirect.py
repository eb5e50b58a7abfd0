"""Clamp Indirect (issue 33): the Sampled render scales each sample's indirect light (everything
after the path's first bounce) so that no channel exceeds the limit, as Cycles' Clamp Indirect.

Checked against what the clamp means, not against our own earlier output: with the same random
numbers, a sample's direct light is the same whatever the limit, so per pixel

    direct only (0 bounces)  ≤  clamped  ≤  unclamped,    clamped − direct ≤ limit per channel,

and a limit no sample reaches, or 0 (off), changes nothing at all. A sphere on a ground under a
sun and forest.exr: light bounces between them (the scene analysis allows bounces)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import studiolights_dir

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.lights import SunLight
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl

W, H = 24, 16
SAMPLES = 32
SEED = 3


def _scene():
    ground = plane(6.0, material=0)
    ground.world_from_object = np.eye(4)
    ground.world_from_object[2, 3] = -1.0
    sun = SunLight(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), np.full(3, 8.0))
    return Scene(
        [uv_sphere(1.0, 24, 12), ground],
        [Material(LambertianBTF(0.8))],
        Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0))),
        Environment(read_exr(studiolights_dir() / "forest.exr")),
        lights=[sun],
    )


@pytest.fixture(scope="module")
def renderer(cl_context):
    from btf_addon.cl.renderer import CLRenderer

    r = CLRenderer(_scene(), W, H, cl_context)
    assert r.features.shadows  # bounces are rendered in this scene
    r.fixed_launch_split = True  # the same launches, so the same float sums, every render
    return r


def _render(renderer, limit: float, bounces: int = 2) -> np.ndarray:
    renderer.clamp_indirect = limit
    return renderer.render_sampled(SAMPLES, seed=SEED, max_bounces=bounces)[..., :3]


def test_off_and_unreached_limits_change_nothing(renderer):
    off = _render(renderer, 0.0)
    np.testing.assert_array_equal(_render(renderer, 1e30), off)
    assert renderer.clamp_indirect == 1e30  # the renderer keeps what it was given


def test_a_clamp_bounds_each_samples_indirect_light(renderer):
    direct = _render(renderer, 0.0, bounces=0)
    off = _render(renderer, 0.0)
    limit = 0.05
    clamped = _render(renderer, limit)
    # float32 sums of 32 samples in another order: 1e-5 of the brightest pixel
    eps = 1e-5 * float(off.max())
    indirect = off - direct
    assert indirect.mean() > 0.02 * off.mean()  # there is indirect light to clamp
    assert np.all(direct <= clamped + eps) and np.all(clamped <= off + eps)
    assert np.all(clamped - direct <= limit + eps)  # the mean of values ≤ limit
    assert float((off - clamped).max()) > 10 * eps  # and the clamp did take light away


def test_a_default_clamp_on_this_scene_costs_under_one_percent(renderer):
    """Cycles' default limit (10) on an evenly lit scene: the image mean moves by < 1 %."""
    off = _render(renderer, 0.0)
    clamped = _render(renderer, 10.0)
    assert abs(float(clamped.mean()) / float(off.mean()) - 1.0) < 0.01
