"""core/mapping.py: texel filtering, UV/Box mapping, real-world size (numpy reference)."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.codecs.packed import defines
from btf_addon.core.grid import RingGrid
from btf_addon.core.mapping import (
    MATERIAL_BLOCK_FLOATS,
    Placement,
    bilinear_texels,
    box_weights,
    filtered_evaluate,
    map_points,
    mapped_evaluate,
    material_block,
    rigid_frame,
    uv_units_per_uv,
)
from btf_addon.core.model import BTFMeta
from btf_addon.scene.primitives import plane
from btf_addon.scene.scene import Material

# One view and one light direction: a dense BTF that is just an RGB image per texel (isotropic
# in angle), so spatial behaviour can be read off directly.
FLAT = RingGrid((0.0,), (1,))


def image_btf(image: np.ndarray, **kw) -> DenseBTF:
    """image: (h, w, 3) → a dense BTF whose value at any angle is the texel's colour."""
    return DenseBTF(image[None, None].astype(np.float32), FLAT, FLAT, **kw)


UP = np.array([[0.0, 0.0, 1.0]])


def test_bilinear_weights_sum_to_one_and_pick_the_texel_at_its_centre(rng):
    uv = rng.uniform(-3, 3, size=(500, 2))
    centres, w = bilinear_texels(uv, 5, 7)
    assert np.allclose(w.sum(axis=1), 1.0, atol=1e-12)  # float64 arithmetic: exact to rounding
    assert np.all((centres >= 0) & (centres < 1))
    c = np.array([[2.5 / 5, 3.5 / 7]])  # the centre of texel (2, 3)
    centres, w = bilinear_texels(c, 5, 7)
    assert w[0, 0] == pytest.approx(1.0, abs=1e-9)
    assert np.allclose(centres[0, 0], c[0])


def test_bilinear_wraps_around_the_tile():
    # u = 0 lies between the last texel's centre and the first's: half of each.
    centres, w = bilinear_texels(np.array([[0.0, 0.5 / 4]]), 4, 4)
    assert np.allclose(w[0], [0.5, 0.5, 0.0, 0.0])
    assert np.allclose(centres[0, :2, 0], [3.5 / 4, 0.5 / 4])


def test_linear_filter_is_continuous_where_nearest_jumps(rng):
    image = rng.uniform(0.1, 1.0, size=(4, 4, 3))
    btf = image_btf(image)
    # Two points either side of the edge between texels 1 and 2 (u = 0.5).
    uv = np.array([[0.5 - 1e-6, 0.3], [0.5 + 1e-6, 0.3]])
    wi = wo = np.repeat(UP, 2, axis=0)
    near = filtered_evaluate(btf, uv, wi, wo, "NEAREST")
    lin = filtered_evaluate(btf, uv, wi, wo, "LINEAR")
    assert np.abs(near[0] - near[1]).max() > 0.01  # random texels differ (≥0.01 w.p. ~1)
    assert np.abs(lin[0] - lin[1]).max() < 1e-4  # slope ≤ 1 per texel · 2e-6 · 4 texels
    # Halfway between texel centres (1, 1) and (2, 1) the mean of the two.
    mid = filtered_evaluate(btf, np.array([[0.5, 1.5 / 4]]), UP, UP, "LINEAR")
    assert np.allclose(mid[0], image[1, 1:3].mean(axis=0), atol=1e-6)  # float32 output


def test_nearest_equals_evaluate_and_analytic_is_never_filtered(rng):
    from btf_addon.core.codecs.analytic import LambertianBTF

    btf = image_btf(rng.uniform(size=(3, 3, 3)))
    uv = rng.uniform(size=(50, 2))
    wi = np.repeat(UP, 50, axis=0)
    assert np.array_equal(filtered_evaluate(btf, uv, wi, wi, "NEAREST"), btf.evaluate(uv, wi, wi))
    lam = LambertianBTF(0.5)
    assert np.array_equal(filtered_evaluate(lam, uv, wi, wi), lam.evaluate(uv, wi, wi))
    with pytest.raises(ValueError, match="texel filter"):
        filtered_evaluate(btf, uv, wi, wi, "CUBIC")


def test_box_weights_blend_and_hard_selection():
    m = np.array([[1.0, 0.0, 0.0], [0.7, 0.7, 0.1], [0.6, 0.5, 0.62]])
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    hard = box_weights(m, 0.0)
    assert np.array_equal(hard, [[1, 0, 0], [1, 0, 0], [0, 0, 1]])  # ties: the first axis
    soft = box_weights(m, 0.2)
    assert np.allclose(soft.sum(axis=1), 1.0)
    assert np.allclose(soft[0], [1, 0, 0])  # a face's centre sees one projection
    assert np.allclose(soft[1], [0.5, 0.5, 0.0])  # the diagonal: half each


def test_packed_block_defines_and_checks():
    d = defines()
    assert d["MATERIAL_BLOCK_FLOATS"] == MATERIAL_BLOCK_FLOATS
    assert d["MAPPING_BOX"] == 1 and d["FILTER_LINEAR"] == 0 and d["FILTER_NEAREST"] == 1
    assert d["M_BOX_FROM_WORLD"] + 12 <= MATERIAL_BLOCK_FLOATS
    with pytest.raises(KeyError, match="missing"):
        material_block(material=0)


def test_uv_density_and_real_world_tile_count():
    # A 2 m plane, UVs 0..1 across it: 2 m per UV unit; a 10 mm tile → 200 tiles per UV unit.
    mesh = plane(2.0)
    assert uv_units_per_uv(mesh.positions, mesh.uvs) == pytest.approx(2.0)
    assert uv_units_per_uv(mesh.positions, np.zeros_like(mesh.uvs)) is None  # no unwrap
    btf = image_btf(np.ones((2, 2, 3)), tile_size_mm=(10.0, 20.0))
    a = Material(btf, real_world=True).block(0, mesh)
    assert np.allclose(a[4:8], [200.0, 0.0, 0.0, 100.0])  # uv_matrix slot: 2000 mm / tile
    # Blender's unit scale: 1 unit = 1 cm → the plane is 2 cm → 2 and 1 tiles.
    b = Material(btf, real_world=True).block(0, mesh, metres_per_unit=0.01)
    assert np.allclose(b[4:8], [2.0, 0.0, 0.0, 1.0])
    # Object scale counts (world-space area): scaled ×3 → 600 tiles.
    scaled = plane(2.0)
    scaled.world_from_object = np.diag([3.0, 3.0, 3.0, 1.0])
    assert Material(btf, real_world=True).block(0, scaled)[4] == pytest.approx(600.0)
    # Unknown size: real-world cannot apply, the UV scale stays.
    unknown = image_btf(np.ones((2, 2, 3)))
    assert np.allclose(
        Material(unknown, real_world=True, uv_scale=3).block(0, mesh)[4:8], [3, 0, 0, 3]
    )
    p = Placement(real_world=True, tile_size_mm=(12.0, 12.0))
    assert p.tile_mm_here(2.0, 1.0) == pytest.approx(12.0)


def test_tile_size_unknown_by_default_and_validated():
    meta = BTFMeta("dense", "x", 1, 1, 1, 1, "g")
    assert meta.tile_size_mm is None and meta.tile_size_source == "unknown"
    assert meta.to_json()["tile_size_mm"] is None
    known = BTFMeta("dense", "x", 1, 1, 1, 1, "g", tile_size_mm=(5, 6))
    assert known.tile_size_mm == (5.0, 6.0) and known.tile_size_source == "stated by the source"
    with pytest.raises(ValueError, match="positive"):
        BTFMeta("dense", "x", 1, 1, 1, 1, "g", tile_size_mm=(0, 6))
    btf = image_btf(np.ones((2, 2, 3)), tile_size_mm=(7.0, 7.0), tile_size_source="test")
    again = DenseBTF.from_params(btf.params(), btf.tables())
    assert again.meta.tile_size_mm == (7.0, 7.0) and again.meta.tile_size_source == "test"


def _rotation_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:3, 3] = (0.3, -0.2, 0.1)
    return m


def _cube_face_points(world_from_object, rng, n=64):
    """Points on the +X face of a unit cube (object space), in world space, with normals."""
    local = np.column_stack([np.ones(n), rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)])
    m = world_from_object
    p = local @ m[:3, :3].T + m[:3, 3]
    nrm = np.repeat([m[:3, 0] / np.linalg.norm(m[:3, 0])], n, axis=0)
    return p, nrm


@pytest.mark.parametrize("space", ["OBJECT", "WORLD"])
def test_box_mapping_follows_the_object_in_object_space_only(rng, space):
    btf = image_btf(rng.uniform(size=(4, 4, 3)))
    still, turned = np.eye(4), _rotation_z(30.0)
    p0, n0 = _cube_face_points(still, np.random.default_rng(5))
    p1, n1 = _cube_face_points(turned, np.random.default_rng(5))
    material = Material(btf, mapping="BOX", box_space=space, box_blend=0.0)
    from btf_addon.scene.scene import Mesh

    def tex(world_from_object, p, n):
        mesh = Mesh(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((3, 4)))
        mesh.world_from_object = world_from_object
        block = material.block(0, mesh)
        t = np.cross(n, [0.0, 0.0, 1.0])
        projections = map_points(block, p, n, t, np.cross(n, t), np.zeros((len(p), 2)))
        return projections[0].uv, projections[0].weight

    uv0, w0 = tex(still, p0, n0)
    uv1, w1 = tex(turned, p1, n1)
    assert np.all(w0 == 1.0) and np.all(w1 == 1.0)  # the +X face projects along X only
    if space == "OBJECT":
        assert np.allclose(uv0, uv1, atol=1e-9)  # stable under the object's rotation
    else:
        assert not np.allclose(uv0, uv1, atol=1e-3)  # world space slides, by choice


def test_box_frame_scale_kept_as_distance():
    m = np.diag([2.0, 2.0, 2.0, 1.0]) @ _rotation_z(40.0)
    box = rigid_frame(m)
    r = box[:, :3]
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)  # orthonormal: no scale in the frame
    # The object's +X corner at 1 unit is 2 world units from its centre: box coordinate 2.
    corner = m @ np.array([1.0, 0.0, 0.0, 1.0])
    assert np.allclose(r @ corner[:3] + box[:, 3], [2.0, 0.0, 0.0], atol=1e-12)


def test_box_mapping_is_seamless_with_a_blend_and_not_without(rng):
    """Around a rounded cube edge (normal turning from +X to +Y) the blended value changes
    smoothly; with blend 0 it jumps where the dominant axis switches."""
    btf = image_btf(rng.uniform(0.1, 1.0, size=(8, 8, 3)))
    angles = np.radians(np.linspace(20.0, 70.0, 501))  # 0.1° steps across the 45° switch
    n = np.column_stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)])
    p = 0.9 * n + [0.0, 0.0, 0.37]  # points on a rounded edge of radius 0.9
    t = np.repeat([[0.0, 0.0, 1.0]], len(n), axis=0)
    b = np.cross(n, t)
    view = n.copy()
    steps = {}
    for blend in (0.0, 0.3):
        mesh = plane()
        block = Material(btf, mapping="BOX", box_blend=blend, texel_filter="LINEAR").block(0, mesh)
        v = mapped_evaluate(btf, block, p, n, t, b, np.zeros((len(n), 2)), view, view)
        steps[blend] = float(np.abs(np.diff(v, axis=0)).max())
    # Linear filtering with 8 texels per unit: a 0.1° step moves ≤ 0.0016 units → ≤ ~0.02 in
    # value from the coordinates; the blend adds ≤ 0.1°·(π/180)/0.3 ≈ 0.006 of a full swing.
    assert steps[0.3] < 0.05
    assert steps[0.0] > 3 * steps[0.3]  # the hard switch is a visible seam


def test_old_containers_default_size_reads_as_unknown():
    """Before sizes could be unknown every codec wrote 10 × 10 mm when nothing was known."""
    from btf_addon.core.model import tile_size_from_params

    assert tile_size_from_params({"tile_size_mm": [10.0, 10.0]}) == (None, "unknown")
    assert tile_size_from_params({"tile_size_mm": [4.0, 4.0]}, "synthetic") == (
        (4.0, 4.0),
        "synthetic",
    )
    assert tile_size_from_params({"tile_size_mm": None}) == (None, "unknown")
