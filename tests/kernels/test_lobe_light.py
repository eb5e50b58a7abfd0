"""An analytic object's unshadowed light as the light bake plays it back (kernels/include/
btf_lobe.h through render_direct.cl ``render_baked``; the World's pyramid and suns:
core/sampling/world_pyramid.py), checked against F12 (``render_sampled``, an independent
estimator: next-event draws of the map, its sun, BTF draws, MIS), plus the hard cases.

A bake of ones plays back exactly the unshadowed light, so a lone convex object under the World
(nothing to shadow or reflect) is a known answer: F12's image."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from helpers import studiolights_dir

from btf_addon.core.codecs.analytic import GGXBTF, PrincipledBTF
from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.accuracy.ladder import relative_rmse
from btf_addon.scene.bake_points import build_grid
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl

W = H = 48


def _ones(scene: Scene):
    from btf_addon.cl.bake import BakedLight

    grid = build_grid([m.world_space_corners() for m in scene.meshes], 0.2, 1)
    return grid, BakedLight(np.ones((grid.point_count, 9, 3), np.float32), 3, 16, 0.0)


def _sphere_scene(btf, env: Environment) -> Scene:
    camera = Camera(look_at((0.0, -3.2, 0.8), (0.0, 0.0, 0.0)), fov_y_rad=np.radians(30.0))
    return Scene([uv_sphere(1.0, 48, 24)], [Material(btf)], camera, env)


def _inner(mask: np.ndarray) -> np.ndarray:
    """Pixels whose 8 neighbours are in ``mask`` too (the film's footprint stays inside)."""
    p = np.pad(mask, 1, constant_values=False)
    return np.all(
        [p[1 + dy : 1 + dy + H, 1 + dx : 1 + dx + W] for dy in (-1, 0, 1) for dx in (-1, 0, 1)],
        axis=0,
    )


@pytest.fixture(scope="module")
def forest():
    return Environment(read_exr(studiolights_dir() / "forest.exr"))


@pytest.mark.parametrize(
    "btf",
    [GGXBTF((0.9, 0.7, 0.5), roughness=0.35), PrincipledBTF((0.8, 0.3, 0.2), 0.4, 0.5)],
    ids=["ggx", "principled"],
)
def test_a_lone_glossy_sphere_plays_back_f12s_light(cl_context, forest, btf):
    """The demo's glossy lobe (GGX, roughness 0.35) and a half-metallic Principled under
    forest.exr, whose sun and sky through the leaves are small bright sources (40 suns).
    After 64 frames of 32 directions (the drawer's default, what a still head sees once the
    film has converged), against 1024 F12 samples. Measured at 48 × 48: GGX 2.0 %,
    Principled 2.75 %; against 4096 samples (two of which differ by 0.5–0.6 %) 1.9 % and
    2.6 %, the blur of the pyramid's levels (64 directions: 1.3 %, 1.75 %). Bound 3.5 %.
    Fewer directions blur more: 4 of them are further off."""
    from btf_addon.cl.bake import render_baked
    from btf_addon.cl.renderer import CLRenderer

    scene = _sphere_scene(btf, forest)
    renderer = CLRenderer(scene, W, H, cl_context)
    reference = renderer.render_sampled(1024)
    grid, ones = _ones(scene)
    image = render_baked(renderer, grid, ones, aa_samples=64)
    coverage = render_baked(renderer, grid, replace(ones), aa_samples=64, times_response=False)
    seen = _inner(coverage[..., 0] > 0.999)
    assert seen.sum() > 400
    error = relative_rmse(image[seen][None, :, :3], reference[seen][None, :, :3])
    assert error < 0.035, error
    few = render_baked(renderer, grid, ones, aa_samples=64, lobe_samples=4)
    assert relative_rmse(few[seen][None, :, :3], reference[seen][None, :, :3]) > error


def test_hard_worlds_and_views_stay_finite(cl_context):
    """A plane seen at grazing angles (the view 0.3° above it), a World of zeros with one
    3e38 pixel and a NaN/Inf pixel (cleaned by Environment), and a black World: every pixel
    is finite and ≥ 0; the black World's is 0."""
    from btf_addon.cl.bake import render_baked
    from btf_addon.cl.renderer import CLRenderer

    image = np.zeros((32, 64, 3))
    image[5, 7] = 3e38
    image[20, 30] = (np.nan, np.inf, -np.inf)
    camera = Camera(look_at((0.0, -40.0, 0.2), (0.0, 0.0, 0.0)), fov_y_rad=np.radians(20.0))
    for env in (Environment(image), Environment.constant((0.0, 0.0, 0.0))):
        scene = Scene([plane(200.0)], [Material(GGXBTF(0.8, 0.05))], camera, env)
        renderer = CLRenderer(scene, 32, 24, cl_context)
        grid, ones = _ones(scene)
        out = render_baked(renderer, grid, ones, aa_samples=4)
        assert np.all(np.isfinite(out)) and out.min() >= 0.0
    assert out[..., :3].max() == 0.0
