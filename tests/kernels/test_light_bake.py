"""The light bake on the device (btf_addon/cl/bake.py; kernels/render_direct.cl ``bake_light``
and ``render_baked``, kernels/include/btf_bake.h, the shared path kernels/include/btf_path.h).

- ``bake_lookup`` and ``bake_square`` against their numpy references (scene/bake_points.py
  ``playback``, core/sampling/btf_importance.py ``hemisphere_to_square``);
- a known answer: a Lambertian plane under a constant World bakes a ratio of 1 and plays back
  albedo × World everywhere;
- a separable measured BTF played back from its bake reproduces F12 (``render_sampled``);
- a cancelled bake keeps its finished passes (and exactly them);
- ``bake_scene`` bakes what the analysis (scene/bake_analysis.py) asks for and nothing else."""

from __future__ import annotations

import time

import numpy as np
import pytest
from helpers import render_program_with, run_kernel

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.grid import UBO2003
from btf_addon.core.sampling.btf_importance import hemisphere_to_square
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.accuracy.ladder import relative_rmse
from btf_addon.scene.bake_points import (
    GRAZING,
    build_grid,
    pack_values,
    playback,
    playback_direction,
)
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl

TEST_KERNELS = """
__kernel void lookup_test(__global const int *tri_cuts, __global const int *tri_first,
                          __global const int *tri_points, __global const float *values,
                          const int view_bins, __global const int *tri,
                          __global const float *bary, __global const float *wo,
                          __global float *out)
{
  int i = get_global_id(0);
  float3 light_dir;
  float3 v = bake_lookup(tri_cuts, tri_first, tri_points, values, view_bins, tri[i],
                         bary[2 * i], bary[2 * i + 1], vload3(i, wo), &light_dir);
  vstore3(v, 2 * i, out);
  vstore3(light_dir, 2 * i + 1, out);
}

__kernel void square_test(__global const float *wo, __global float *out)
{
  int i = get_global_id(0);
  vstore2(bake_square(vload3(i, wo)), i, out);
}
"""

ALBEDO = np.array([0.6, 0.5, 0.4])
SKY = np.array([0.8, 1.0, 1.2])  # the constant World's radiance


@pytest.fixture(scope="module")
def program(cl_context):
    return render_program_with(cl_context, TEST_KERNELS)


def _hemisphere(rng, n: int) -> np.ndarray:
    """(n, 3) uniform directions on the upper hemisphere."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = np.abs(d[:, 2])
    return d


def _edge_views(rng) -> np.ndarray:
    """Directions at the rules' edges: the normal, grazing (z = 1e-7), below the horizon (bake
    reads them as grazing), straight down (read as the normal), the concentric map's diagonals
    (|x| = |y|: its branch switch) and axes, and views of other lengths."""
    phi = rng.uniform(0.0, 2 * np.pi, 64)
    ring = np.column_stack([np.cos(phi), np.sin(phi)])
    diag = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]], float) / np.sqrt(2)
    axes = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]], float)
    flat = np.concatenate([ring, diag, axes])
    return np.concatenate(
        [
            [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.0, 0.0, 3.0], [1e-20, 0.0, 1.0]],
            np.column_stack([flat, np.full(len(flat), 1e-7)]),  # grazing
            np.column_stack([flat, np.zeros(len(flat))]),  # on the horizon
            np.column_stack([flat, -rng.uniform(0.01, 1.0, len(flat))]),  # below
            np.column_stack([flat * 0.6, np.full(len(flat), 0.8)]),  # diagonals at 37°
            np.column_stack([flat, np.full(len(flat), 2.0)]) * 4.0,  # not unit
        ]
    )


def _queries(rng, grid, per_tri: int = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(tri, bu, bv) float32 barycentrics: random inside every triangle, its corners, points on
    its edges (bu = 0, bv = 0, bu + bv = 1 as float32 gives it: possibly past the far edge by
    rounding), grid vertices and cell edges of its cut, and a few non-finite ones."""
    tris, us, vs = [], [], []
    for t, n in enumerate(grid.tri_cuts):
        r = rng.random((per_tri, 2))
        fold = r.sum(axis=1) > 1.0
        r[fold] = 1.0 - r[fold]
        e = rng.random(3)
        k = rng.integers(0, n + 1, size=(2, 2))
        k[:, 1] = np.minimum(k[:, 1], n - k[:, 0])  # i + j ≤ n
        s = rng.random()
        special = [
            (0.0, 0.0), (1.0, 0.0), (0.0, 1.0),  # corners
            (e[0], 0.0), (0.0, e[1]), (e[2], 1.0 - e[2]),  # edges
            *(k / n),  # grid vertices
            (1.0 / n, s * (n - 1) / n), (s / n, 1.0 - s / n - 1.0 / n),  # cell edges
        ]  # fmt: skip
        pts = np.concatenate([r, np.array(special, float)])
        tris.append(np.full(len(pts), t))
        us.append(pts[:, 0])
        vs.append(pts[:, 1])
    bu, bv = np.concatenate(us), np.concatenate(vs)
    tri = np.concatenate(tris)
    bad = np.array([[np.nan, 0.3], [0.2, np.inf], [-np.inf, 0.1], [np.nan, np.nan]])
    tri = np.concatenate([tri, rng.integers(0, len(grid.tri_cuts), len(bad))])
    bu, bv = np.concatenate([bu, bad[:, 0]]), np.concatenate([bv, bad[:, 1]])
    return tri.astype(np.int32), bu.astype(np.float32), bv.astype(np.float32)


@pytest.fixture(scope="module")
def lookup_grid() -> object:
    """Triangles of different cuts: a coarse sphere's (n = 2 near its poles, 3 at its
    equator) and a plane's (n = 8 at spacing 0.4: √2·2 / 0.4 = 7.07 → 8); 302 points."""
    sphere, ground = uv_sphere(1.0, 8, 4), plane(2.0)
    grid = build_grid([sphere.world_space_corners(), ground.world_space_corners()], 0.4)
    assert set(grid.tri_cuts.tolist()) == {2, 3, 8}
    return grid


def _lookup(cl_context, program, grid, rows, tri, bu, bv, wo) -> np.ndarray:
    """(N, 2, 3) float32: the kernel's lookup_test of packed ``rows`` (P, V² + 1, 4) at the
    queries: per query its value, then its light direction."""
    import pyopencl as cl

    view_bins = round(np.sqrt(rows.shape[1] - 1))
    out = np.empty((len(tri), 2, 3), np.float32)
    run_kernel(
        cl_context,
        cl.Kernel(program, "lookup_test"),
        len(tri),
        [
            grid.tri_cuts.astype(np.int32),
            grid.tri_first.astype(np.int32),
            grid.tri_points.astype(np.int32),
            rows.ravel(),
            np.int32(view_bins),
            tri,
            np.column_stack([bu, bv]).ravel(),
            np.asarray(wo, np.float32).ravel(),
        ],
        [out],
    )
    return out


@pytest.mark.parametrize("view_bins", [1, 3, 5])
def test_bake_lookup_matches_numpy_playback(cl_context, program, lookup_grid, view_bins):

    grid = lookup_grid
    rng = np.random.default_rng(11 + view_bins)
    tri, bu, bv = _queries(rng, grid)
    n = len(tri)
    wo = _hemisphere(rng, n)
    edge = _edge_views(rng)
    wo[: len(edge)] = edge
    wo = rng.permutation(wo).astype(np.float32)  # edge views on all kinds of queries
    bins = view_bins * view_bins
    # values in [0.5, 1]: the result is a convex blend of them, so ≥ 0.5 and a relative
    # tolerance is meaningful
    values = rng.uniform(0.5, 1.0, (grid.point_count, bins, 3)).astype(np.float32)
    directions = _light_directions(rng, grid.point_count)
    out = _lookup(cl_context, program, grid, pack_values(values, directions), tri, bu, bv, wo)
    expected = playback(grid, values.astype(np.float64), tri, bu, bv, wo, view_bins)
    # float32 against float64 on the same float32 inputs: bu·n and the square's atan2 in
    # float32 (a few ulp: up to ~1e-6 of a cell or a bin's width, which moves a blend of
    # values 0.5 apart by ~1e-6), 12 float32 products summed (~1e-6). Measured: 2.7e-7 relative
    # at most; 1e-5 leaves room for other devices' atan2 while any wrong vertex, bin or cell
    # (differences of ~0.1 between random values) fails by four orders of magnitude.
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out[:, 0], expected, rtol=1e-5, atol=0)
    # The light direction: a normalised blend of unit vectors within 60° of the normal (so at
    # least 0.5 long): float32 against float64, a few ulp. Measured below 3e-7; a wrong vertex
    # or weight moves it by ~0.1.
    want = playback_direction(grid, directions, tri, bu, bv)
    np.testing.assert_allclose(out[:, 1], want, rtol=0, atol=2e-6)


def _light_directions(rng, points: int) -> np.ndarray:
    """(points, 3) float32 unit directions within 60° of the normal, as a bake stores them."""
    d = rng.normal(size=(points, 3))
    d[:, 2] = np.abs(d[:, 2]) + 2.0
    return (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def test_bake_lookup_light_direction_without_one_is_the_normal(cl_context, program, lookup_grid):
    """Directions that are all zero (or cancel) blend to nothing: the lookup answers the
    normal, the direction bakes before FORMAT_VERSION 4 were to, never a NaN."""

    grid = lookup_grid
    rng = np.random.default_rng(3)
    tri, bu, bv = _queries(rng, grid)
    n = len(tri)
    values = np.ones((grid.point_count, 1, 3), np.float32)
    rows = pack_values(values, np.zeros((grid.point_count, 3), np.float32))
    out = _lookup(cl_context, program, grid, rows, tri, bu, bv, _hemisphere(rng, n))
    assert np.array_equal(out[:, 1], np.tile(np.float32([0, 0, 1]), (n, 1)))
    want = playback_direction(grid, np.zeros((grid.point_count, 3)), tri, bu, bv)
    assert np.array_equal(want, np.tile([0.0, 0.0, 1.0], (n, 1)))


def test_bake_square_matches_hemisphere_to_square(cl_context, program):
    import pyopencl as cl

    rng = np.random.default_rng(7)
    wo = np.concatenate([_edge_views(rng), _hemisphere(rng, 20000)]).astype(np.float32)
    out = np.empty((len(wo), 2), np.float32)
    run_kernel(cl_context, cl.Kernel(program, "square_test"), len(wo), [wo.ravel()], [out])
    # The reference with bin_weights' rule for views at or below the horizon (z = GRAZING·|xy|;
    # none at all: the normal), which hemisphere_to_square itself leaves to its callers.
    w = wo.astype(np.float64)
    h = np.hypot(w[:, 0], w[:, 1])
    w[:, 2] = np.where(w[:, 2] > 0, w[:, 2], np.where(h > 0, GRAZING * h, 1.0))
    expected = hemisphere_to_square(w)
    # square coordinates in [0, 1]: float32 rounding (6e-8) and PoCL's atan2 (a few ulp) of
    # a result scaled by 4/π·r ≤ 1.3. Measured: 1.1e-7 at most.
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-6)
    assert np.all((out >= 0) & (out <= 1))
    np.testing.assert_array_equal(out[:2], [[0.5, 0.5], [0.5, 0.5]])  # the normal; straight down


# --- bakes on the renderer ------------------------------------------------------------------


def _lone_plane(btf, camera=None) -> Scene:
    camera = camera or Camera(look_at((0.0, -2.6, 1.3), (0.0, 0.2, 0.0)))
    return Scene([plane(2.0)], [Material(btf)], camera, Environment.constant(SKY))


def _grid(scene: Scene, spacing: float, footprint: int = 16):
    return build_grid([m.world_space_corners() for m in scene.meshes], spacing, footprint)


@pytest.fixture(scope="module")
def lambert(cl_context):
    from btf_addon.cl.renderer import CLRenderer

    scene = _lone_plane(LambertianBTF(ALBEDO))
    return CLRenderer(scene, 8, 6, cl_context), scene


def test_lambertian_plane_under_a_constant_world_bakes_ratio_one_and_plays_back_albedo_times_world(
    lambert,
):
    """An analytic material's bake is its traced light over its unshadowed light, the same
    paths through an empty scene (btf_bake.h bake_over_unshadowed): on a lone plane nothing
    shadows or reflects, and the two take the same random numbers, so the ratio is 1 in every
    bin and channel (float32 sums of the same terms: 1e-6). Playback multiplies it by the
    unshadowed light converged per pixel (btf_lobe.h): Lambert's value is ρ/π·cos θi
    (core/codecs/analytic.py), cosine draws give ρ each, and a constant World's pyramid is that
    constant at every level, so each pixel is ρ·L exactly (float32: 1e-5)."""
    from btf_addon.cl.bake import PASS_SAMPLES, BakedLight, bake_light, render_baked

    renderer, scene = lambert
    grid = _grid(scene, 1.0, footprint=8)  # n = 3 per triangle: 16 points
    assert grid.point_count == 16
    baked = bake_light(
        renderer, grid.footprint_tri, grid.footprint_bary, view_bins=3, samples=64,
        max_bounces=0,
    )  # fmt: skip
    assert baked.ratio.shape == (16, 9, 3) and baked.ratio.dtype == np.float32
    assert baked.view_bins == 3 and baked.samples == 64 and 64 % PASS_SAMPLES == 0
    np.testing.assert_allclose(baked.ratio, 1.0, atol=1e-5)
    image = render_baked(renderer, grid, baked, aa_samples=1)
    seen = image[..., :3].sum(-1) != (SKY).sum()  # the plane, not the World behind it
    assert seen.mean() > 0.3
    np.testing.assert_allclose(
        image[seen][:, :3], np.broadcast_to(ALBEDO * SKY, (seen.sum(), 3)), rtol=1e-5
    )
    # and a ratio of 0.5 (a shadow the bake saw) halves it
    half = BakedLight(baked.ratio * 0.5, 3, 64, 0.0)
    shadowed = render_baked(renderer, grid, half, aa_samples=1)
    np.testing.assert_allclose(shadowed[seen][:, :3], 0.5 * image[seen][:, :3], rtol=1e-6)


def _separable_dense(texels: int = 8) -> DenseBTF:
    """A measured-format BTF whose texels differ only by a colour factor: value = A(view,
    light)·a(texel), A a diffuse term with a view-dependent strength and a mild lobe around the
    mirror direction. Its bake ratio (light over the response to a light along the normal) is
    then the same at every texel, so playback × the pixel's own response is exactly F12's
    value up to the bake's interpolation between view bins."""
    v = UBO2003.directions()
    lights = UBO2003.directions()
    mirror = v * np.array([-1.0, -1.0, 1.0])
    lobe = np.clip(mirror @ lights.T, 0.0, None)  # (views, lights)
    angular = lights[None, :, 2] / np.pi * (0.6 + 0.4 * v[:, None, 2]) * (1 + 0.6 * lobe**2)
    texel = np.random.default_rng(1).uniform(0.2, 1.0, (texels, texels, 3))
    data = angular[:, :, None, None, None] * texel[None, None]
    return DenseBTF(data.astype(np.float32), name="separable")


def _inner(mask: np.ndarray) -> np.ndarray:
    """Pixels of ``mask`` whose 8 neighbours are in it too (F12's film samples land up to the
    filter's 1.5 px footprint from the centre: edge pixels mix World and surface differently)."""
    p = np.pad(mask, 1, constant_values=True)
    h, w = mask.shape
    return np.all([p[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
                   for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)  # fmt: skip


def test_playback_of_a_separable_measured_btf_reproduces_f12(cl_context):
    from btf_addon.cl.bake import bake_light, render_baked
    from btf_addon.cl.renderer import CLRenderer

    scene = _lone_plane(_separable_dense())  # seen from 27° above: views at 50-80° from the normal
    renderer = CLRenderer(scene, 32, 24, cl_context)
    grid = _grid(scene, 0.5)
    baked = bake_light(
        renderer, grid.footprint_tri, grid.footprint_bary, view_bins=5, samples=128,
        max_bounces=0,
    )  # fmt: skip
    renderer.transparent = True
    try:
        coverage = render_baked(renderer, grid, baked, aa_samples=64)[..., 3]
    finally:
        renderer.transparent = False
    image = render_baked(renderer, grid, baked, aa_samples=64)
    reference = renderer.render_sampled(1024)
    surface, world = _inner(coverage == 1.0), _inner(coverage == 0.0)
    assert surface.sum() >= 100 and world.sum() >= 200  # both are in the frame
    # The World where camera rays miss: the constant's float32 value (measured: 4.6e-7, SKY's
    # rounding); in F12 too away from the plane's edge, up to the rounding of its filtered sum
    # of 1024 samples (measured: 7.7e-6).
    missed = coverage == 0.0
    np.testing.assert_allclose(image[missed][:, :3], np.broadcast_to(SKY, (missed.sum(), 3)),
                               rtol=0, atol=1e-6)  # fmt: skip
    np.testing.assert_allclose(reference[world][:, :3], np.broadcast_to(SKY, (world.sum(), 3)),
                               rtol=0, atol=5e-5)  # fmt: skip
    # The baked frame against F12's 1024 samples on the surface. Measured: relative RMSE
    # 1.66-1.74 % over bake seeds 0-2, 1.50-1.58 % of it a mean bias: the ratio interpolated
    # bilinearly between 5 × 5 view bins (0.6 % at 9 bins, 0.0 % at 13). F12's own noise is
    # 0.13 % (two seeds), the bake's values at the bins are within 0.2 % of a quadrature of
    # the BTF. The same plane with its texels averaged (a playback that lost the texel's
    # detail) is 21 % off.
    error = relative_rmse(image[surface][None], reference[surface][None])
    assert error < 0.035, error
    bias = float(np.mean(image[surface][:, :3] / reference[surface][:, :3] - 1.0))
    assert abs(bias) < 0.03, bias


def test_a_cancelled_bake_keeps_its_finished_passes(lambert, monkeypatch):
    from btf_addon.cl import bake

    renderer, scene = lambert
    grid = _grid(scene, 0.25, footprint=4)  # n = 12 per triangle: 169 points
    # launches of 16 points after the first (of 64): the cancel comes in the middle of a pass
    monkeypatch.setattr(bake, "LAUNCH_SECONDS", 1e-9)
    seen = []

    def progress(fraction: float) -> bool:
        seen.append(fraction)
        return fraction <= 0.3

    args = (renderer, grid.footprint_tri, grid.footprint_bary, 3)
    cancelled = bake.bake_light(*args, samples=64, max_bounces=0, progress=progress)
    passes = 64 // bake.PASS_SAMPLES
    assert seen[-1] > 0.3 and all(f <= 0.3 for f in seen[:-1])
    assert len(seen) < 20  # it stopped there, not at the end (4 passes: 4 × 11 launches)
    # The pass under way when the callback said no is dropped, every finished one kept:
    # fraction = (p·P + k)/(passes·P) with 0 < k ≤ P points of pass p done.
    finished = int(np.ceil(seen[-1] * passes - 1e-9)) - 1
    assert cancelled.samples == finished * bake.PASS_SAMPLES
    assert cancelled.samples % bake.PASS_SAMPLES == 0 and 0 <= cancelled.samples < 64
    assert cancelled.samples == 16  # 169 + 3 × 16 points of 676 is the first past 30 %
    assert cancelled.ratio.shape == (grid.point_count, 9, 3)
    assert np.all(np.isfinite(cancelled.ratio))
    # ... and they are exactly a bake of that many samples: each point's paths depend on its
    # index, seed and sample numbers only, not on the launches.
    whole = bake.bake_light(*args, samples=cancelled.samples, max_bounces=0)
    np.testing.assert_array_equal(cancelled.ratio, whole.ratio)
    assert np.all(cancelled.ratio > 0)


def test_a_bake_cancelled_in_its_first_pass_is_empty(lambert, monkeypatch):
    from btf_addon.cl import bake

    renderer, scene = lambert
    grid = _grid(scene, 0.25, footprint=4)  # 169 points: the first launch does 64 of them
    monkeypatch.setattr(bake, "LAUNCH_SECONDS", 1e-9)
    seen = []

    def stop(fraction: float) -> bool:
        seen.append(fraction)
        return fraction == 0.0  # the light directions (one launch here) go on

    baked = bake.bake_light(renderer, grid.footprint_tri, grid.footprint_bary, 3, samples=64,
                            max_bounces=0, progress=stop)  # fmt: skip
    assert seen == [0.0, 64 / (4 * 169)]  # stopped in the middle of pass 0
    # nothing finished: no samples and a ratio of 0 (0 light over 0 response, bake._finish)
    assert baked.samples == 0
    assert baked.ratio.shape == (grid.point_count, 9, 3)
    np.testing.assert_array_equal(baked.ratio, 0.0)


def test_a_bake_cancelled_while_finding_light_directions_is_empty(lambert):
    """The light directions come first (cl/bake.py light_directions), their launches report
    progress 0 and can be cancelled: nothing is baked, and no direction is half-found (the
    normal everywhere, as a bake with none)."""
    from btf_addon.cl import bake

    renderer, scene = lambert
    grid = _grid(scene, 0.25, footprint=4)
    seen = []

    def stop(fraction: float) -> bool:
        seen.append(fraction)
        return False

    baked = bake.bake_light(renderer, grid.footprint_tri, grid.footprint_bary, 3, samples=64,
                            max_bounces=0, progress=stop)  # fmt: skip
    assert seen == [0.0]
    assert baked.samples == 0
    np.testing.assert_array_equal(baked.ratio, 0.0)
    np.testing.assert_array_equal(baked.light_dir, np.tile([0, 0, 1], (grid.point_count, 1)))


def _ray_box(origins: np.ndarray, dirs: np.ndarray, half: float) -> np.ndarray:
    """(N,) distance to the cube [−half, half]³ along each ray (inf: a miss), slab method."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (-half - origins) / dirs, (half - origins) / dirs
    near = np.nanmax(np.minimum(t0, t1), axis=1)
    far = np.nanmin(np.maximum(t0, t1), axis=1)
    return np.where((near <= far) & (near > 0), near, np.inf)


def test_render_baked_reads_the_bake_in_the_renderers_triangle_order(cl_context):
    """Bake values that are each point's own position, played back without the response: a
    pixel then shows the position of the surface it sees (a point inside a flat cell is the
    same blend of the cell's vertices as its value), wherever the BVH put its triangle."""
    from btf_addon.cl.bake import BakedLight, render_baked
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.scene.primitives import cube

    w, h, offset = 24, 18, 3.0
    camera = Camera(look_at((3.0, -4.0, 2.5), (0.0, 0.0, 0.0)))
    scene = Scene([cube(2.0)], [Material(LambertianBTF(0.5))], camera, Environment.constant(SKY))
    renderer = CLRenderer(scene, w, h, cl_context, film=None)
    # a reordering to undo, or the test would pass without it (12 triangles: BVH leaves)
    assert not np.array_equal(renderer.triangle_order, np.arange(12))
    grid = _grid(scene, 0.7, footprint=1)  # n = 5 per triangle (2·√2 / 0.7 = 4.04)
    ratio = np.repeat(grid.positions[:, None, :] + offset, 4, axis=1)  # > 0, every bin
    baked = BakedLight(ratio.astype(np.float32), view_bins=2, samples=1, seconds=0.0)
    image = render_baked(renderer, grid, baked, aa_samples=1, times_response=False)
    # the same camera rays in float64 (kernels/include/btf_surface.h camera_ray_at)
    world_from_clip = np.linalg.inv(camera.clip_from_world(w / h))
    y, x = np.mgrid[0:h, 0:w] + 0.5
    ndc = np.stack([x / w * 2 - 1, 1 - y / h * 2], -1).reshape(-1, 2)
    ones = np.ones((len(ndc), 1))
    near = np.hstack([ndc, -ones, ones]) @ world_from_clip.T
    far = np.hstack([ndc, ones, ones]) @ world_from_clip.T
    o = near[:, :3] / near[:, 3:]
    d = far[:, :3] / far[:, 3:] - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = _ray_box(o, d, 1.0)
    hit = np.isfinite(t)
    assert 80 <= hit.sum() <= len(t) - 80  # the cube and the World both in the frame
    expected = o + d * np.where(hit, t, 0.0)[:, None] + offset
    got = image[..., :3].reshape(-1, 3)
    # float32 camera rays against float64 ones: world_from_clip spans clip_start 0.01 to
    # clip_end 1000, so a float32 ray's direction is off by ~2e-5 rad, 1e-4 along the surface
    # 5 units away (measured: 1.3e-4 at most); a value from another triangle's points is off
    # by a cell (0.4) or more.
    np.testing.assert_allclose(got[hit], expected[hit], rtol=0, atol=1e-3)
    np.testing.assert_allclose(got[~hit], np.broadcast_to(SKY, ((~hit).sum(), 3)), atol=1e-6)


def _scene(*meshes) -> Scene:
    return Scene(
        list(meshes),
        [Material(LambertianBTF(0.5))],
        Camera(look_at((0.0, -6.0, 2.0), (0, 0, 0))),
        Environment.constant(SKY),
    )


KNOBS = dict(spacing=0.5, view_bins=2, samples=16, footprint=4, bounces=1)


def test_bake_scene_skips_a_lone_convex_sphere_without_a_device(monkeypatch):
    from btf_addon.cl import bake

    def refuse(*_args, **_kwargs):
        raise AssertionError("no device work for a scene that needs no bake")

    monkeypatch.setattr(bake, "CLRenderer", refuse)
    monkeypatch.setattr(bake, "bake_light", refuse)
    scene = _scene(uv_sphere(0.5, 12, 6, name="Ball"))
    t0 = time.perf_counter()
    result = bake.bake_scene(scene, None, bake.BakeKnobs(**KNOBS))  # no context either
    assert time.perf_counter() - t0 < 5.0  # grid and analysis only (measured 0.002 s)
    (mesh,) = result.meshes
    assert mesh.name == "Ball" and not mesh.baked and mesh.points == 0
    assert not mesh.shadows and not mesh.interreflection
    assert mesh.line().startswith("Ball: not baked (") and "alone and convex" in mesh.line()
    ratio = result.arrays["ratio"]
    assert ratio.shape == (len(result.arrays["positions"]), 4, 3) and len(ratio) > 0
    np.testing.assert_array_equal(ratio, 0.0)
    assert result.knobs["samples"] == 0


def test_bake_scene_bakes_a_sphere_resting_on_a_plane(cl_context):
    from btf_addon.cl.bake import BakeKnobs, bake_scene

    ball = uv_sphere(0.5, 12, 6, name="Ball")
    ball.world_from_object = np.eye(4)
    ball.world_from_object[2, 3] = 0.5  # touching the ground at the origin
    scene = _scene(plane(3.0, name="Ground"), ball)
    result = bake_scene(scene, cl_context, BakeKnobs(**KNOBS))
    ratio, point_mesh = result.arrays["ratio"], result.arrays["point_mesh"]
    assert ratio.shape == (len(point_mesh), 4, 3)
    assert result.knobs["samples"] == 16 and result.knobs["view_bins"] == 2
    for index, (mesh, name) in enumerate(zip(result.meshes, ("Ground", "Ball"), strict=True)):
        own = point_mesh == index
        assert mesh.name == name and mesh.baked and mesh.shadows and mesh.interreflection
        assert mesh.points == own.sum() > 0
        lit = np.any(ratio[own] > 0, axis=(1, 2))
        # Every point sees some sky or its light reflected (one bounce), but a point at the
        # contact may take all 16 samples into the other mesh; measured: all points lit.
        assert lit.mean() > 0.9, lit.mean()
        assert np.all(np.isfinite(ratio[own]))
        line = mesh.line()
        assert line.startswith(f"{name}: shadows + interreflection baked at {mesh.points} points")
        other = "Ball" if name == "Ground" else "Ground"
        assert f"'{other}'" in line  # the reason names the neighbour


def test_a_bake_beyond_the_memory_budget_is_refused_before_any_device_work(monkeypatch):
    """The host's sums are bounded up front (cl/bake.py BAKE_VALUE_BYTES): a budget of 1 MiB
    refuses a sphere on a ground at 1 cm before a renderer exists, saying what to change."""
    from btf_addon.cl import bake
    from btf_addon.core import memory

    def no_renderer(*_args, **_kwargs):
        raise AssertionError("a refused bake must not build a renderer")

    monkeypatch.setattr(bake, "CLRenderer", no_renderer)
    memory.set_limit(1 << 20)
    try:
        with pytest.raises(memory.MemoryLimitError, match="raise the spacing"):
            ball = uv_sphere(0.5, 12, 6, name="Ball")
            ball.world_from_object = np.eye(4)
            ball.world_from_object[2, 3] = 0.5
            scene = _scene(plane(3.0, name="Ground"), ball)
            bake.bake_scene(scene, None, bake.BakeKnobs(spacing=0.01))
    finally:
        memory.set_limit(None)
