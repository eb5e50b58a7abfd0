"""The light bake's light direction (kernels/render_direct.cl ``bake_light_direction``, cl/bake.py
``light_directions``): the direction a measured material's response is baked and played back
to (kernels/include/btf_bake.h ``bake_response``), against answers known without our code."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.grid import UBO2003
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.bake_points import build_grid
from btf_addon.scene.lights import SunLight
from btf_addon.scene.primitives import cube, plane
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl

BLACK = Environment.constant((0.0, 0.0, 0.0))
#: A sun 36° off the zenith, towards +x and −y.
SUN = np.array([0.5, -0.3, 0.81]) / np.linalg.norm([0.5, -0.3, 0.81])


def _grid(scene: Scene, spacing: float, footprint: int = 8):
    return build_grid([m.world_space_corners() for m in scene.meshes], spacing, footprint)


def _bake(cl_context, scene: Scene, spacing: float, samples: int = 16):
    from btf_addon.cl.bake import bake_light
    from btf_addon.cl.renderer import CLRenderer

    renderer = CLRenderer(scene, 48, 36, cl_context, film=None)
    grid = _grid(scene, spacing)
    baked = bake_light(renderer, grid.footprint_tri, grid.footprint_bary, 1, samples, 0)
    return renderer, grid, baked


def _camera() -> Camera:
    return Camera(look_at((0.4, -2.4, 1.6), (0.0, 0.0, 0.0)))


def test_unit_light_directions_rules():
    """The sums' mean direction, raised to 75° from the normal at most along its own azimuth;
    the normal where no light arrived, where it came from all round, or the sums are not
    finite."""
    from btf_addon.cl.bake import MIN_LIGHT_COS, unit_light_directions

    s = np.sin(np.radians(75.0))
    sums = np.array(
        [
            [0.0, 0.0, 2.0, 2.0],  # straight down the normal
            [0.3, -0.4, 1.2, 5.0],  # any length: made unit
            [3.0, 4.0, 0.1, 9.0],  # 89° from the normal: raised to 75°, azimuth kept
            [0.0, 0.0, 0.0, 0.0],  # no light
            [1e-5, 0.0, 0.0, 1.0],  # light from all round
            [np.nan, 0.0, 1.0, 1.0],  # not finite: read as no light that way
            [np.inf, 0.0, 0.0, np.inf],
        ]
    )
    got = unit_light_directions(sums)
    assert got.dtype == np.float32 and got.shape == (7, 3)
    want = [
        [0, 0, 1],
        np.array([0.3, -0.4, 1.2]) / 1.3,
        [0.6 * s, 0.8 * s, MIN_LIGHT_COS],
        [0, 0, 1],
        [0, 0, 1],
        [0, 0, 1],
        [0, 0, 1],
    ]
    np.testing.assert_allclose(got, want, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-6)


def test_a_sun_gives_its_direction_and_its_shadow_the_normal(cl_context):
    """A ground under one Blender sun and a black World, a cube floating above it: a point
    the sun reaches takes the sun's direction in the ground's frame (plane(): tangent +x,
    bitangent +y, normal +z) exactly, one the cube shadows everywhere on its footprint has no
    light, so the normal. Where each point lies is decided here by the cube's shadow on the
    ground, computed from the geometry alone."""
    ground = plane(6.0)
    box = cube(2.0)
    box.world_from_object = np.eye(4)
    box.world_from_object[:3, 3] = (0.0, 0.0, 2.0)
    scene = Scene(
        [ground, box],
        [Material(LambertianBTF(0.5))],
        _camera(),
        BLACK,
        lights=[SunLight(SUN, np.ones(3))],
    )
    _, grid, baked = _bake(cl_context, scene, 0.25)
    on_ground = grid.point_mesh == 0
    d, p = baked.light_dir[on_ground], grid.positions[on_ground]
    # the cube [−1, 1]² × [1, 3] seen from ground point p along SUN: its shadow is the union
    # of its slices' shifts by −z·SUN.xy/SUN.z, z in [1, 3]
    t = SUN[:2] / SUN[2]

    def distance_to_shadow(z):  # signed: < 0 inside the slice's shadow square
        q = p[:, :2] + z * t
        return np.max(np.abs(q) - 1.0, axis=1)

    inside = np.min([distance_to_shadow(z) for z in np.linspace(1.0, 3.0, 81)], axis=0)
    margin = 2 * 0.25  # a footprint reaches about one spacing from its point
    lit, dark = inside > margin, inside < -margin
    assert lit.sum() > 100 and dark.sum() > 20
    np.testing.assert_allclose(d[lit], np.broadcast_to(SUN, (lit.sum(), 3)), atol=1e-5)
    np.testing.assert_allclose(d[dark], np.broadcast_to([0, 0, 1], (dark.sum(), 3)), atol=1e-6)
    # at the shadow's edge: the sun where any of the footprint sees it, else the normal
    edge = ~(lit | dark)
    to_sun = np.linalg.norm(d[edge] - SUN, axis=1) < 1e-5
    to_normal = np.linalg.norm(d[edge] - (0, 0, 1), axis=1) < 1e-6
    assert np.all(to_sun | to_normal)


def _world() -> Environment:
    """A sky brighter towards the zenith and one side, with a bright patch 27° above the
    horizon."""
    h, w = 32, 64
    theta = (np.arange(h) + 0.5) / h * np.pi
    phi = (np.arange(w) + 0.5) / w * 2 * np.pi
    image = np.ones((h, w, 3)) * (0.3 + np.cos(theta)[:, None, None].clip(0) * 0.7)
    image *= 1.0 + 0.5 * np.cos(phi)[None, :, None]
    image[10:12, 20:23] *= 300.0
    return Environment(image.astype(np.float32))


def test_a_lone_plane_takes_the_worlds_irradiance_weighted_mean_direction(cl_context):
    """A lone plane (nothing occludes it) under a structured World: each point's direction is
    the World's mean direction weighted by luminance × cos θ, computed here by quadrature over
    the map's pixels (Environment's own pixel directions, 8 × 8 sub-cells each).

    The kernel draws 256 directions per point from the plain table: their mean direction
    scatters by a degree or two (measured: 1.45° at most over the grid's 81 points, 0.06° for
    the mean over them); 3° and 1° bound them. The answer without the luminance weight lies
    40° away, without cos θ 6° (the mean over the points catches that)."""
    env = _world()
    scene = Scene([plane(2.0)], [Material(LambertianBTF(0.5))], _camera(), env)
    *_, baked = _bake(cl_context, scene, 0.4)
    # reference: sub-cell centres of every pixel, weighted by solid angle
    k = 8
    h, w = env.height, env.width
    t = (np.arange(h * k) + 0.5) / (h * k)
    s = (np.arange(w * k) + 0.5) / (w * k)
    ss, tt = np.meshgrid(s, t)
    dirs = env.directions_from_image_coords(ss.ravel(), tt.ravel())
    solid = np.sin(tt.ravel() * np.pi)  # ∝ the sub-cell's solid angle
    lum = env.lookup(dirs) @ np.array([0.2126, 0.7152, 0.0722])
    cos = np.maximum(dirs[:, 2], 0.0)
    mean = (lum * cos * solid) @ dirs
    want = mean / np.linalg.norm(mean)
    angle = np.degrees(np.arccos(np.clip(baked.light_dir @ want, -1.0, 1.0)))
    assert angle.max() < 3.0, angle.max()
    average = baked.light_dir.mean(axis=0)
    average /= np.linalg.norm(average)
    assert np.degrees(np.arccos(min(float(average @ want), 1.0))) < 1.0
    assert want[2] < 0.95  # the test means something: the answer is not the normal


def _dense_with_light_dependent_detail(texels: int = 4) -> DenseBTF:
    """A measured BTF whose texel pattern changes with the light direction (random per texel,
    light and view): the response to one light carries its detail only for that light."""
    v = UBO2003.directions()
    rng = np.random.default_rng(9)
    angular = v[None, :, 2] / np.pi
    values = angular[:, :, None, None, None] * rng.uniform(
        0.2, 1.0, (len(v), len(v), texels, texels, 3)
    )
    return DenseBTF(values.astype(np.float32))


def test_a_measured_plane_under_a_sun_plays_back_the_final_renders_texels(cl_context):
    """A lone measured plane under one sun (black World): its light is the sun alone, so the
    bake's light direction is the sun's and its ratio the sun's irradiance in every bin and
    footprint position; played back, each pixel is the BTF at its own texel lit by the sun,
    which is what the final render computes, pixel for pixel (float32 sums: 1e-4 relative).
    A response to a light along the normal (what bakes before FORMAT_VERSION 4 used) would
    carry this BTF's texel pattern for the wrong light: tens of percent off."""
    from btf_addon.cl.bake import render_baked

    scene = Scene(
        [plane(2.0, uv_repeats=6.0)],
        [Material(_dense_with_light_dependent_detail())],
        _camera(),
        BLACK,
        lights=[SunLight(SUN, np.array([2.0, 1.5, 1.0]))],
    )
    renderer, grid, baked = _bake(cl_context, scene, 0.5)
    np.testing.assert_allclose(
        baked.light_dir, np.broadcast_to(SUN, baked.light_dir.shape), atol=1e-5
    )
    np.testing.assert_allclose(
        baked.ratio, np.broadcast_to([2.0, 1.5, 1.0], baked.ratio.shape), rtol=1e-4
    )
    played = render_baked(renderer, grid, baked, aa_samples=1)[..., :3]
    final = renderer.render_direct(BLACK.virtual_lights(1)).combined[..., :3]
    seen = final.sum(-1) > 0
    assert seen.mean() > 0.3
    np.testing.assert_allclose(played[seen], final[seen], rtol=1e-4, atol=1e-7)
    assert np.all(played[~seen] == 0)
