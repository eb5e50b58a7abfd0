"""The light bake played back in the one drawer (gl/drawer.py, shaders/bake_lib.glsl,
render/bake_playback.py):

- the GLSL lookup against the numpy rule (scene/bake_points.py ``playback``);
- a baked frame of the drawer against the OpenCL playback (cl/bake.py ``render_baked``, itself
  tested against numpy and F12 in tests/kernels/test_light_bake.py), measured and analytic
  materials;
- converged from the first batch whatever the number of lights;
- stale meshes drawn with live light, the status saying so; a bake too large for the device's
  textures refused, not drawn wrong; uploads kept across drawers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.grid import UBO2003
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.bake_playback import BakeStatus, plan
from btf_addon.render.light_bake import LightBake, MeshBake, mesh_digests, scene_digest
from btf_addon.scene.bake_points import build_grid, playback, playback_direction
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

W, H = 64, 48
GRID_KEYS = ("positions", "normals", "tri_cuts", "tri_first", "tri_points", "point_mesh")


# --- the lookup: GLSL against numpy --------------------------------------------------------


def _lookup_bake(rng, view_bins: int):
    """A coarse sphere (cuts 2 and 3) and a plane (cuts 8) with random values in [0.5, 1]."""
    corners = [uv_sphere(1.0, 8, 4).world_space_corners(), plane(2.0).world_space_corners()]
    grid = build_grid(corners, 0.4)
    assert set(grid.tri_cuts.tolist()) == {2, 3, 8}
    arrays = {k: getattr(grid, k) for k in (*GRID_KEYS, "mesh_first_triangle")}
    arrays["ratio"] = rng.uniform(0.5, 1.0, (grid.point_count, view_bins**2, 3)).astype(np.float32)
    d = rng.normal(size=(grid.point_count, 3))
    d[:, 2] = np.abs(d[:, 2]) + 2.0  # within 60° of the normal: blends at least 0.5 long
    arrays["light_dir"] = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    meshes = [MeshBake(n, "", True, True, True, "") for n in ("Sphere", "Plane")]
    return grid, LightBake(arrays, {"view_bins": view_bins}, meshes, "")


def _queries(rng, grid):
    """Per triangle: random points inside, its corners, points on its edges; then non-finite
    barycentrics (read as the triangle's corner 0)."""
    tris, bary = [], []
    for t in range(len(grid.tri_cuts)):
        r = rng.random((8, 2))
        r[r.sum(axis=1) > 1] = 1 - r[r.sum(axis=1) > 1]
        e = rng.random()
        special = [(0, 0), (1, 0), (0, 1), (e, 0), (0, e), (e, 1 - e)]
        pts = np.concatenate([r, np.array(special, float)])
        tris.append(np.full(len(pts), t))
        bary.append(pts)
    bad = np.array([[np.nan, 0.3], [0.2, np.inf], [np.nan, np.nan]])
    tri = np.concatenate([*tris, np.zeros(len(bad), int)])
    return tri, np.concatenate([*bary, bad]).astype(np.float32)


def _views(rng, n: int) -> np.ndarray:
    """Random upper-hemisphere views with the rule's edges among them: the normal, grazing,
    below the horizon (read as grazing), the concentric map's diagonals, not unit."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = np.abs(d[:, 2])
    phi = rng.uniform(0, 2 * np.pi, 16)
    ring = np.column_stack([np.cos(phi), np.sin(phi)])
    diagonal = np.array([[1, 1], [-1, 1], [1, -1], [-1, -1]]) / np.sqrt(2)
    edges = np.concatenate(
        [
            [[0, 0, 1], [0, 0, 3]],
            np.column_stack([ring, np.full(16, 1e-7)]),
            np.column_stack([ring, -rng.uniform(0.01, 1, 16)]),
            np.column_stack([diagonal * 0.6, np.full(4, 0.8)]),
        ]
    )
    d[: len(edges)] = edges
    return rng.permutation(d).astype(np.float32)


@pytest.mark.parametrize("view_bins", [1, 2, 5])
def test_glsl_lookup_matches_the_numpy_playback(gl_ctx, view_bins):
    from btf_addon.gl.query import glsl_bake_lookup

    rng = np.random.default_rng(20 + view_bins)
    grid, bake = _lookup_bake(rng, view_bins)
    tri, bary = _queries(rng, grid)
    wo = _views(rng, len(tri))
    out = glsl_bake_lookup(bake, tri, bary, wo, gl_ctx)
    values = bake.arrays["ratio"].astype(np.float64)
    expected = playback(grid, values, tri, bary[:, 0], bary[:, 1], wo, view_bins)
    # float32 GLSL against float64 on the same inputs: the bilinear weights through bary·n and
    # the concentric map's atan in float32 (llvmpipe's atan is good to ~1e-6 of a bin), then
    # 12 products summed. Any wrong grid vertex, cell or bin moves the result by ~0.1 (random
    # values in [0.5, 1]), four orders of magnitude above the tolerance.
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, expected, rtol=1e-5, atol=0)
    # The light direction (a normalised blend at least 0.5 long): a few float32 ulp; a wrong
    # vertex or weight moves it by ~0.1.
    got = glsl_bake_lookup(bake, tri, bary, wo, gl_ctx, direction=True)
    want = playback_direction(grid, bake.arrays["light_dir"], tri, bary[:, 0], bary[:, 1])
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-6)


# --- the drawer: a baked frame ----------------------------------------------------------------


def _dense(texels: int = 4) -> DenseBTF:
    """A small measured BTF with texel detail (random per texel and direction pair)."""
    v = UBO2003.directions()
    rng = np.random.default_rng(5)
    angular = v[None, :, 2] / np.pi * rng.uniform(0.5, 1.5, (len(v), len(v)))
    texel = rng.uniform(0.2, 1.0, (texels, texels, 3))
    return DenseBTF((angular[:, :, None, None, None] * texel[None, None]).astype(np.float32))


def contact_scene(ball_btf=None) -> Scene:
    """A ball resting on a ground (both need a bake: the contact), under a random World."""
    ground = replace(plane(4.0, uv_repeats=8.0, material=1), name="Ground")
    ball = replace(uv_sphere(0.5, segments=24, rings=12), name="Ball")
    ball.world_from_object = np.eye(4)
    ball.world_from_object[2, 3] = 0.5
    rng = np.random.default_rng(1)
    return Scene(
        [ball, ground],
        [Material(ball_btf or _dense()), Material(LambertianBTF(0.5))],
        Camera(look_at((0, -3, 1.5), (0, 0, 0.3)), fov_y_rad=np.radians(50)),
        Environment(rng.gamma(2.0, 0.5, size=(16, 32, 3))),
    )


@pytest.fixture(scope="module")
def baked(cl_context):
    """The contact scene and its bake (coarse: this tests playback, not the bake's accuracy)."""
    from btf_addon.cl.bake import BakeKnobs, bake_scene

    scene = contact_scene()
    bake = bake_scene(scene, cl_context, BakeKnobs(spacing=0.25, view_bins=3, samples=16))
    assert [m.baked for m in bake.meshes] == [True, True]
    return scene, bake


def _drawn(scene: Scene, lights: int = 8, per_pass: int = 4) -> tuple[np.ndarray, object]:
    from btf_addon.gl.renderer import GLSLRenderer

    renderer = GLSLRenderer(scene, W, H)
    try:
        image = renderer.render(scene.environment.virtual_lights(lights, seed=1), per_pass)
        return image, renderer.drawer.bake_status
    finally:
        renderer.release()


@pytest.mark.opencl
def test_the_drawer_plays_the_bake_back_as_the_opencl_playback(gl_ctx, cl_context, baked):
    from btf_addon.cl.bake import baked_light, playback_grid, render_baked
    from btf_addon.cl.renderer import CLRenderer

    scene, bake = baked
    # One batch of one light: the analytic ground's directions are the drawer's frame 0, as
    # render_baked's single subpixel.
    image, status = _drawn(replace(scene, light_bake=bake), lights=1, per_pass=1)
    assert status == BakeStatus(played=("Ball", "Ground"))
    renderer = CLRenderer(scene, W, H, cl_context, film=None)
    grid, light = playback_grid(bake), baked_light(bake)
    expected = render_baked(renderer, grid, light, aa_samples=1)[..., :3]
    # Pixel centres both: the rasteriser's barycentrics against the ray's, float32 both.
    # Measured: median 2e-5 relative, 99th percentile 1e-3 (pixels on a triangle's edge or
    # the silhouette, where the two pick different triangles or miss). A playback without the
    # response (the measured ball's texel detail) or with the wrong bins is off by > 10 %.
    error = np.abs(image - expected) / np.maximum(expected, 1e-3)
    assert np.median(error) < 1e-4, np.median(error)
    assert np.percentile(error, 95) < 2e-3, np.percentile(error, 95)
    # and it is not the live drawer's image: the ball's contact shadow is in it
    scene_live, _ = _drawn(scene)
    assert np.abs(scene_live - image).mean() > 0.05 * image.mean()


@pytest.mark.opencl
def test_a_glossy_analytic_bake_plays_back_as_the_opencl_playback(gl_ctx, cl_context):
    """A GGX ball on the ground under a World with a sun: its bake is a ratio over its
    unshadowed light, which the drawer computes per pixel (shaders/lobe_lib.glsl: the analytic
    mixture's directions, the World's pyramid, its suns) as render_baked does
    (kernels/include/btf_lobe.h), frame 0 both. Measured: median 2e-5 relative, 95th
    percentile 1e-3 (float32 trigonometry of two compilers along 32 directions, and the
    silhouette's pixels, as the test above; the lookups are texel fetches of the same
    arrays). The drawer without its suns is off by 51 % at the median."""
    from btf_addon.cl.bake import BakeKnobs, bake_scene, baked_light, playback_grid, render_baked
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.core.codecs.analytic import GGXBTF
    from btf_addon.core.sampling.world_pyramid import world_pyramid

    scene = contact_scene(GGXBTF((0.9, 0.6, 0.4), roughness=0.3))
    sky = np.random.default_rng(2).gamma(2.0, 0.5, size=(32, 64, 3))
    sky[9, 40:42] = 400.0  # a sun: the pyramid's suns' row
    scene = replace(scene, environment=Environment(sky))
    assert world_pyramid(scene.environment).suns >= 1
    bake = bake_scene(scene, cl_context, BakeKnobs(spacing=0.25, view_bins=3, samples=16))
    image, status = _drawn(replace(scene, light_bake=bake), lights=1, per_pass=1)
    assert status == BakeStatus(played=("Ball", "Ground"))
    renderer = CLRenderer(scene, W, H, cl_context, film=None)
    expected = render_baked(renderer, playback_grid(bake), baked_light(bake), aa_samples=1)
    error = np.abs(image - expected[..., :3]) / np.maximum(expected[..., :3], 1e-3)
    assert np.median(error) < 1e-4, np.median(error)
    assert np.percentile(error, 95) < 2e-3, np.percentile(error, 95)


@pytest.mark.opencl
def test_baked_meshes_are_converged_from_the_first_batch(gl_ctx, baked):
    """One batch of one light, or 64 lights in 8 batches: the baked pixels are the same (the
    live World behind them is drawn from the same background in both)."""
    from btf_addon.gl.renderer import GLSLRenderer

    scene, bake = baked
    scene = replace(scene, light_bake=bake)
    renderer = GLSLRenderer(scene, W, H)
    try:
        renderer.set_lights(scene.environment.virtual_lights(64, seed=3), per_pass=8)
        renderer.restart()
        assert renderer.render_pass() == 8
        first = renderer.resolve()
    finally:
        renderer.release()
    converged, _ = _drawn(scene, lights=1, per_pass=1)
    # count × value / count in float32: a few ulps
    np.testing.assert_allclose(first, converged, rtol=1e-6, atol=1e-7)


@pytest.mark.opencl
def test_a_moved_mesh_is_stale_and_drawn_with_live_light(gl_ctx, baked):
    _, bake = baked
    moved = contact_scene()
    ball = moved.meshes[0]
    ball.world_from_object = ball.world_from_object.copy()
    ball.world_from_object[0, 3] = 0.3  # the ball rolled: its bake and the ground's are stale
    image, status = _drawn(replace(moved, light_bake=bake))
    assert status.played == () and status.stale == ("Ball", "Ground")
    assert "stale" in status.line() and "bake again" in status.line()
    live, none = _drawn(moved)
    assert none is None  # no bake, no status
    np.testing.assert_array_equal(image, live)


@pytest.mark.opencl
def test_other_lights_or_world_make_every_bake_stale(gl_ctx, baked):
    scene, bake = baked
    dimmer = Environment(scene.environment.radiance * 0.5)
    _, status = _drawn(replace(scene, environment=dimmer, light_bake=bake))
    assert status.played == () and status.stale == ("Ball", "Ground")


@pytest.mark.opencl
def test_a_bake_too_tall_for_the_devices_textures_is_refused(gl_ctx, baked, monkeypatch):
    from btf_addon.render import bake_playback

    scene, bake = baked
    rows = bake_playback.texture_rows(bake)
    assert 0 < rows < 16
    assert "over this GPU" in _plan(scene, bake, max_rows=rows - 1).status.refused
    # in the drawer: taller than llvmpipe's 16384 rows
    monkeypatch.setattr(bake_playback, "texture_rows", lambda _bake: 20000)
    image, status = _drawn(replace(scene, light_bake=bake))
    assert status.played == () and "bake with a larger spacing" in status.refused
    assert status.line().startswith("Light bake not used: ")
    live, _ = _drawn(scene)
    np.testing.assert_array_equal(image, live)


@pytest.mark.opencl
def test_a_drawer_from_the_previous_keeps_the_bakes_uploads(gl_ctx, baked):
    from btf_addon.gl.drawer import ProgressiveDrawer
    from btf_addon.gl.moderngl_device import ModernGLDevice

    scene, bake = baked
    scene = replace(scene, light_bake=bake)
    device = ModernGLDevice(gl_ctx)
    first = ProgressiveDrawer(device, scene)
    tables = first._bake_upload
    second = ProgressiveDrawer(device, replace(scene), previous=first)
    assert second._bake_upload is tables and second.uploads["meshes"] == 0
    third = ProgressiveDrawer(device, replace(scene, light_bake=None), previous=second)
    assert third._bake_upload is None and third.uploads["meshes"] == 2  # places changed
    third.release()


@pytest.mark.opencl
def test_stereo_captures_play_the_bake_back_and_record_it(gl_ctx, baked):
    from btf_addon.gl.moderngl_device import ModernGLDevice
    from btf_addon.gl.stereo_capture import capture_profile, render_stereo
    from btf_addon.render.headsets import profile
    from btf_addon.render.settings import RenderSettings

    scene, bake = baked
    prof = capture_profile(profile("simulated"), 48)
    settings = RenderSettings(lights_total=4)
    device = ModernGLDevice(gl_ctx)
    baked_capture = render_stereo(replace(scene, light_bake=bake), settings, prof, device)
    live_capture = render_stereo(scene, settings, prof, device)
    recorded = baked_capture.metadata("per-eye")["light_bake"]
    assert recorded == "Light bake: baked light on Ball, Ground"
    assert live_capture.metadata("per-eye")["light_bake"] is None
    for eye in ("left", "right"):
        difference = np.abs(baked_capture.images[eye] - live_capture.images[eye])
        assert difference.mean() > 0.05 * live_capture.images[eye].mean()  # the bake's light


# --- which meshes play back (no GL) -------------------------------------------------------------


def _plan(scene: Scene, bake: LightBake, max_rows: int = 16384):
    digests = mesh_digests(scene)
    return plan(
        bake,
        scene,
        [digests[m.name] for m in scene.meshes],
        [len(m.world_space_corners()) // 3 for m in scene.meshes],
        scene_digest(scene),
        max_rows,
    )


@pytest.mark.opencl
def test_plan_matches_meshes_by_name_and_bakes_first_triangles(baked):
    scene, bake = baked
    playback_plan = _plan(scene, bake)
    first = bake.arrays["mesh_first_triangle"]
    assert playback_plan.first_triangle == {0: int(first[0]), 1: int(first[1])}
    # the scene's meshes in another order: each still finds its own triangles
    swapped = replace(scene, meshes=scene.meshes[::-1])
    assert _plan(swapped, bake).first_triangle == {1: int(first[0]), 0: int(first[1])}
    # a mesh the bake skipped, or one it never saw, is live and not called stale
    skipped = replace(bake, meshes=[replace(bake.meshes[0], baked=False), bake.meshes[1]])
    result = _plan(scene, skipped)
    assert result.status.played == ("Ground",) and result.status.stale == ()
    renamed = replace(scene, meshes=[replace(scene.meshes[0], name="Other"), scene.meshes[1]])
    assert _plan(renamed, bake).status.stale == ("Ground",)  # an added mesh: conservative


@pytest.mark.opencl
def test_an_added_mesh_stales_only_the_bakes_it_stands_beside(baked):
    """The analysis is geometric (in front of each other's faces, not distance): a cube below
    the ground is beside the ball (its underside faces it) but behind the ground's one side."""
    from btf_addon.scene.primitives import cube

    scene, bake = baked
    below = replace(cube(0.5, material=1), name="Below")
    below.world_from_object = np.eye(4)
    below.world_from_object[:3, 3] = (0.0, 0.0, -3.0)
    result = _plan(replace(scene, meshes=[*scene.meshes, below]), bake)
    # and the cube itself, never baked, needs one now (beside the ball): the status says so
    assert result.status == BakeStatus(played=("Ground",), stale=("Ball",), missing=("Below",))
    above = replace(below, name="Above")
    above.world_from_object = np.eye(4)
    above.world_from_object[:3, 3] = (1.0, 0.0, 0.25)  # on the ground beside the ball
    result = _plan(replace(scene, meshes=[*scene.meshes, above]), bake)
    assert result.status == BakeStatus(stale=("Ball", "Ground"), missing=("Above",))


def test_status_lines_name_what_plays_back_and_what_is_stale():
    assert BakeStatus().line() == "Light bake: nothing baked in this scene"
    assert BakeStatus(played=("A",)).line() == "Light bake: baked light on A"
    line = BakeStatus(played=("A",), stale=tuple("BCDEFG")).line()
    assert line == (
        "Light bake: baked light on A; stale, live light on B, C, D, E and 2 more: bake again"
    )
    assert BakeStatus(refused="too big").line() == "Light bake not used: too big"
    assert BakeStatus(played=("A",), missing=("Cube",)).line() == (
        "Light bake: baked light on A; Cube needs a bake now: bake again"
    )
    assert "B, C need a bake now" in BakeStatus(missing=("B", "C")).line()
