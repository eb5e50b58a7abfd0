"""Mapping and texel filtering as rendered: GLSL against the numpy reference pixel by pixel,
GLSL against OpenCL (texel-edge picks), and a real-world tile count on a plane of known size."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import count_periods, shared_material, stripe_btf

from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.mapping import mapped_evaluate
from btf_addon.core.sampling.envmap import Environment, VirtualLights
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

SIZE = 64  # pixels per side of the orthographic views: small and quick


def one_light(direction) -> VirtualLights:
    d = np.asarray(direction, dtype=np.float64)
    return VirtualLights((d / np.linalg.norm(d))[None], np.ones((1, 3)), np.ones(1))


def tilted_plane_scene(material: Material, normal, size=2.0, view=2.0):
    """A plane of ``size`` through the origin facing ``normal``, seen orthographically about
    25° off the normal (straight along it θv = 0, where φv is undefined and float32 rounding
    decides it) with ``view`` units across the image."""
    normal = np.asarray(normal, dtype=np.float64) / np.linalg.norm(normal)
    mesh = plane(size)
    # world_from_object: object +Z → normal, keeping object +X roughly along world +X.
    x = np.cross((0.0, 1.0, 0.0), normal)
    x /= np.linalg.norm(x)
    y = np.cross(normal, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, y, normal
    mesh.world_from_object = m
    eye = 5.0 * (normal + 0.4 * x + 0.2 * y)
    camera = Camera(look_at(eye, (0, 0, 0), y), perspective=False, ortho_scale=view)
    env = Environment(np.zeros((4, 8, 3)))
    return Scene([mesh], [material], camera, env)


def pixel_points(scene: Scene, size: int):
    """Per pixel (row 0 at the top) the plane point the pixel centre sees, and the frame."""
    cam = scene.camera.world_from_camera
    right, up, back, eye = cam[:3, 0], cam[:3, 1], cam[:3, 2], cam[:3, 3]
    half = scene.camera.ortho_scale / 2
    c = (np.arange(size) + 0.5) / size * 2 - 1
    xs, ys = np.meshgrid(c * half, -c * half)
    origin = eye + xs[..., None] * right + ys[..., None] * up
    m = scene.meshes[0].world_from_object
    n = m[:3, 2]
    t_hit = -(origin @ n) / (-back @ n)
    p = (origin - t_hit[..., None] * back).reshape(-1, 3)
    local = (p - m[:3, 3]) @ m[:3, :3]  # orthonormal world_from_object here
    uv = local[:, :2] / 2.0 + 0.5  # plane(2.0)'s UVs
    k = len(p)
    return p, np.tile(n, (k, 1)), np.tile(m[:3, 0], (k, 1)), np.tile(m[:3, 1], (k, 1)), uv, back


@pytest.mark.parametrize("mapping", ["UV", "BOX"])
@pytest.mark.parametrize("texel_filter", ["NEAREST", "LINEAR"])
def test_glsl_mapping_matches_numpy_per_pixel(gl_ctx, mapping, texel_filter):
    from btf_addon.gl.renderer import GLSLRenderer

    btf = MLVQBTF.from_directory(shared_material("wallpaper"))
    material = Material(
        btf,
        uv_scale=0.3,
        uv_rotation_rad=0.4,
        uv_offset=(0.1, 0.2),
        mapping=mapping,
        texel_filter=texel_filter,
        box_blend=0.5,
    )
    # A tilted normal so Box mapping blends all three projections.
    scene = tilted_plane_scene(material, (0.3, 0.5, 0.81), view=1.5)
    light = (0.2, -0.4, 1.0)
    image = GLSLRenderer(scene, SIZE, SIZE, gl_ctx).render(one_light(light))
    p, n, t, b, uv, back = pixel_points(scene, SIZE)
    block = scene.material_blocks()[0]
    wi = np.tile(np.asarray(light) / np.linalg.norm(light), (len(p), 1))
    ref = mapped_evaluate(btf, block, p, n, t, b, uv, wi, np.tile(back, (len(p), 1)))
    ref = ref.reshape(SIZE, SIZE, 3)
    scale = float(np.abs(ref).mean())
    bad = np.abs(image - ref).max(axis=-1) > 5e-3 * scale
    # The rasteriser interpolates position and uv in float32: LINEAR, continuous in both,
    # agrees everywhere within 0.5 % of the mean; NEAREST may pick the neighbouring texel
    # where a pixel centre lies within that rounding of a texel edge (≤ 1 % of pixels).
    allowed = 0 if texel_filter == "LINEAR" else SIZE * SIZE // 100
    assert int(bad.sum()) <= allowed, (int(bad.sum()), float(np.abs(image - ref).max() / scale))


def interior(depth: np.ndarray) -> np.ndarray:
    """Surface pixels whose 8 neighbours are surface too: silhouettes excluded (a rasterised
    and a ray-cast edge pixel may see different things, whatever the filter)."""
    hit = depth < 1e9
    out = hit.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            out &= np.roll(np.roll(hit, dy, axis=0), dx, axis=1)
    return out


@pytest.mark.opencl
def test_filtering_removes_the_texel_edge_disagreement_between_glsl_and_opencl(
    cl_context, gl_ctx, rng
):
    """Nearest texels: where a pixel's uv lies within float32 rounding of a texel edge, the
    rasteriser and the ray caster can pick different texels (a full texel-to-texel step);
    bilinear weights change continuously with uv, so the two back ends agree everywhere."""
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.gl.renderer import GLSLRenderer

    btf = MLVQBTF.from_directory(shared_material("wallpaper"))
    env = Environment(rng.gamma(0.6, 1.0, size=(32, 64, 3)) * [1.0, 0.9, 0.7])
    lights = env.virtual_lights(8, seed=1)
    w, h = 96, 72
    worst, picks = {}, {}
    for texel_filter in ("NEAREST", "LINEAR"):
        # 16 repeats: many texel edges per pixel row, so some pixel centres fall on one.
        material = Material(btf, uv_scale=16.0, texel_filter=texel_filter)
        camera = Camera(look_at((0, -2.2, 0.3), (0, 0, 0)))
        scene = Scene([uv_sphere(1.0, segments=96, rings=48)], [material], camera, env)
        passes = CLRenderer(scene, w, h, cl_context).render_direct(lights)
        a = passes.combined[..., :3]
        b = GLSLRenderer(scene, w, h, gl_ctx).render(lights)
        inside = interior(np.asarray(passes.depth).reshape(h, w))
        diff = np.abs(a - b).max(axis=-1)[inside] / np.abs(b[inside]).mean()
        worst[texel_filter] = float(diff.max())
        picks[texel_filter] = int((diff > 0.05).sum())
    # Measured with PoCL and llvmpipe: nearest 5 pixels > 5 % of the mean (worst 0.21), linear
    # none (worst 0.005, the rasteriser's smooth-normal interpolation).
    assert worst["LINEAR"] < 0.02 and picks["LINEAR"] == 0, worst
    assert picks["NEAREST"] >= 1 and worst["NEAREST"] > 5 * worst["LINEAR"], (worst, picks)


@pytest.mark.parametrize("mapping", ["UV", "BOX"])
def test_real_world_size_shows_the_expected_number_of_tiles(gl_ctx, mapping):
    """A 0.5 m plane with a 25 mm tile shows 20 tiles across, whatever its UVs, in both
    mappings; with the unit scale at 1 unit = 0.5 m the same plane is 0.25 m: 10 tiles.
    (GLSL here; the OpenCL side uses the same block: tests/kernels/test_mapping_kernel.py.)"""
    from btf_addon.gl.renderer import GLSLRenderer

    size = 0.5
    mesh = plane(size, uv_repeats=3.0)  # UVs not 1:1: real-world size must not care
    material = Material(stripe_btf(25.0), mapping=mapping, real_world=True, texel_filter="LINEAR")
    camera = Camera(look_at((0, 0, 3), (0, 0, 0), (0, 1, 0)), perspective=False, ortho_scale=size)
    scene = Scene([mesh], [material], camera, Environment(np.zeros((4, 8, 3))))
    width = 256  # 12.8 pixels per stripe period at 20 periods
    image = GLSLRenderer(scene, width, 8, gl_ctx).render(one_light((0, 0, 1)))
    assert count_periods(image[4, :, 0]) == 20
    scene.metres_per_unit = 0.5
    image = GLSLRenderer(scene, width, 8, gl_ctx).render(one_light((0, 0, 1)))
    assert count_periods(image[4, :, 0]) == 10


def _rotation(axis, deg: float) -> np.ndarray:
    """(3, 3) rotation about ``axis`` by ``deg`` (Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = np.radians(deg)
    return np.eye(3) + np.sin(a) * kx + (1 - np.cos(a)) * kx @ kx


@pytest.mark.parametrize("space", ["OBJECT", "WORLD"])
def test_box_mapped_cube_turns_with_its_object_in_object_space_only(gl_ctx, space):
    """Turn the cube, the camera and the light together: in object space the image is the
    same (the tile and each face's anisotropy direction turned with the cube); in world space
    the tile stays behind, by choice."""
    from btf_addon.gl.renderer import GLSLRenderer
    from btf_addon.scene.primitives import cube

    btf = MLVQBTF.from_directory(shared_material("wallpaper"))
    material = Material(
        btf, mapping="BOX", box_space=space, box_blend=0.2, uv_scale=0.7, texel_filter="LINEAR"
    )
    eye, light = np.array([3.0, -4.0, 2.5]), np.array([0.3, -0.5, 1.0])
    images = []
    for turn in (np.eye(3), _rotation((1.0, 2.0, 0.5), 35.0)):
        mesh = cube(2.0)
        mesh.world_from_object = np.eye(4)
        mesh.world_from_object[:3, :3] = turn
        camera = Camera(look_at(turn @ eye, (0, 0, 0), turn @ np.array([0.0, 0.0, 1.0])))
        scene = Scene([mesh], [material], camera, Environment(np.zeros((4, 8, 3))))
        images.append(GLSLRenderer(scene, SIZE, SIZE, gl_ctx).render(one_light(turn @ light)))
    a, b = images
    rel = float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(a**2)))
    if space == "OBJECT":
        # float32 rounding of the turned geometry only (measured 6e-6 on llvmpipe)
        assert rel < 1e-3, rel
    else:
        assert rel > 0.1, rel  # a different part of the tile on every face (measured 0.29)


def test_material_blocks_past_the_first_texture_row(gl_ctx):
    """Blocks are laid out TABLE_WIDTH floats a row (any number of instances fits): a mesh
    whose block lies on the texture's second row draws as the same mesh drawn alone."""
    from btf_addon.core.codecs.packed import TABLE_WIDTH
    from btf_addon.core.mapping import MATERIAL_BLOCK_FLOATS
    from btf_addon.gl.renderer import GLSLRenderer

    btf = MLVQBTF.from_directory(shared_material("wallpaper"))
    shifted = Material(btf, uv_offset=(0.3, 0.6), uv_scale=0.4, texel_filter="LINEAR")
    scene = tilted_plane_scene(shifted, (0.2, 0.1, 1.0), view=1.5)
    alone = GLSLRenderer(scene, SIZE, SIZE, gl_ctx).render(one_light((0.2, -0.4, 1.0)))
    hidden = TABLE_WIDTH // MATERIAL_BLOCK_FLOATS + 2  # the visible block on row 2
    far = plane(0.01)
    far.world_from_object = np.eye(4)
    far.world_from_object[:3, 3] = (100.0, 100.0, 100.0)  # outside the view
    scene.meshes = [far] * hidden + scene.meshes
    scene.materials = [Material(btf), *scene.materials]
    for m in scene.meshes[:hidden]:
        assert m.material == 0
    scene.meshes[-1].material = 1
    many = GLSLRenderer(scene, SIZE, SIZE, gl_ctx).render(one_light((0.2, -0.4, 1.0)))
    assert np.array_equal(many, alone)
