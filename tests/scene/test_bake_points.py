"""The bake grid (btf_addon/scene/bake_points.py): point counts after welding, where the grid
vertices lie, the playback rule checked against positions computed independently, the view
bins, the footprints and the refusal of grids over the limit."""

from __future__ import annotations

import re

import numpy as np
import pytest

from btf_addon.core.sampling.btf_importance import square_to_hemisphere
from btf_addon.scene import bake_points, primitives
from btf_addon.scene.bake_points import (
    BakeGridTooLarge,
    bin_centre,
    bin_directions,
    bin_weights,
    build_grid,
    grid_bytes,
    locate,
    playback,
)


def _corners(tris: np.ndarray, normals: np.ndarray | None = None) -> np.ndarray:
    """(T, 3, 3) positions (+ optional (T, 3, 3) normals, else the face's) → (3T, 6) float32."""
    tris = np.asarray(tris, dtype=np.float64)
    if normals is None:
        face = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-300)
        normals = np.repeat(face[:, None], 3, axis=1)
    return np.concatenate([tris, normals], axis=2).reshape(-1, 6).astype(np.float32)


def _tris(corners: np.ndarray) -> np.ndarray:
    return corners[:, :3].astype(np.float64).reshape(-1, 3, 3)


def _ij(n: int) -> list[tuple[int, int]]:
    """The grid vertices in local index order, enumerated independently of the module."""
    return [(i, j) for i in range(n + 1) for j in range(n + 1 - i)]


def _spacing_for(longest: float, n: int) -> float:
    return longest / (n - 0.5)  # ceil(longest / spacing) = n


def _lattice(rng, nx: int, ny: int) -> np.ndarray:
    """A flat, smooth-shaded grid of nx × ny vertices at awkward float coordinates, each
    triangle's corners rotated at random (every edge kind, both directions)."""
    x, y = np.meshgrid(np.arange(nx) * 0.137 + 0.3141, np.arange(ny) * 0.137 - 2.718)
    v = np.stack([x, y, np.full_like(x, 0.577)], -1).astype(np.float32).astype(np.float64)
    nrm = rng.normal(size=v.shape) * 0.2 + (0, 0, 1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    tris, norms = [], []
    for r in range(ny - 1):
        for c in range(nx - 1):
            a, b, cc, d = (r, c), (r, c + 1), (r + 1, c + 1), (r + 1, c)
            for tri in ((a, b, cc), (a, cc, d)):
                tri = np.roll(np.array(tri), rng.integers(3), axis=0)
                tris.append(v[tri[:, 0], tri[:, 1]])
                norms.append(nrm[tri[:, 0], tri[:, 1]])
    return _corners(np.array(tris), np.array(norms))


def _positions(grid, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every grid vertex's expected position (from the formula) and its point's position."""
    tris, expected, got = _tris(corners), [], []
    for t, n in enumerate(grid.tri_cuts):
        for k, (i, j) in enumerate(_ij(int(n))):
            c = tris[t]
            expected.append(c[0] + i / n * (c[1] - c[0]) + j / n * (c[2] - c[0]))
            got.append(grid.positions[grid.tri_points[grid.tri_first[t] + k]])
    return np.array(expected), np.array(got)


@pytest.mark.parametrize("n", [1, 2, 5, 13])
def test_single_triangle_has_all_its_grid_vertices_on_it(rng, n):
    tri = rng.normal(size=(1, 3, 3))
    corners = _corners(tri)
    longest = max(np.linalg.norm(tri[0, a] - tri[0, b]) for a, b in ((0, 1), (1, 2), (2, 0)))
    grid = build_grid([corners], _spacing_for(longest, n))
    assert grid.tri_cuts.tolist() == [n]
    assert grid.point_count == (n + 1) * (n + 2) // 2
    assert len(grid.tri_points) == grid.point_count
    expected, got = _positions(grid, corners)
    np.testing.assert_allclose(got, expected, atol=1e-5 * np.abs(tri).max())
    # Barycentric reconstruction: each point lies in the triangle's plane, inside it.
    c = _tris(corners)[0]
    basis = np.stack([c[1] - c[0], c[2] - c[0]], axis=1)
    bary, *_ = np.linalg.lstsq(basis, (grid.positions - c[0]).T, rcond=None)
    np.testing.assert_allclose(basis @ bary + c[0][:, None], grid.positions.T, atol=1e-5)
    assert np.all(bary > -1e-5) and np.all(bary.sum(axis=0) < 1 + 1e-5)
    np.testing.assert_allclose(np.linalg.norm(grid.normals, axis=1), 1.0, atol=1e-6)


@pytest.mark.parametrize("n", [1, 4, 7])
def test_quad_welds_its_shared_edge(rng, n):
    """A quad at awkward coordinates whose two triangles walk the diagonal in opposite
    directions: its interior points are bit-identical only when computed canonically."""
    a = rng.normal(size=3)
    u, v = np.array([1.0, 0.1, 0.2]), np.array([-0.1, 1.0, 0.3])
    b, c, d = a + u, a + u + v + rng.normal(scale=0.02, size=3), a + v
    tris = np.array([[a, b, c], [c, d, a]])
    corners = _corners(tris, np.tile(np.array([0.0, 0.0, 1.0]), (2, 3, 1)))
    diagonal = np.linalg.norm(_tris(corners)[0, 2] - _tris(corners)[0, 0])
    grid = build_grid([corners], _spacing_for(diagonal, n))
    assert grid.tri_cuts.tolist() == [n, n]
    assert grid.point_count == (n + 1) ** 2  # 2 · (n+1)(n+2)/2 − (n + 1) shared
    # A crease (the second triangle's normals turned away) keeps both sides' points.
    creased = _corners(
        tris, np.stack([np.tile([0.0, 0.0, 1.0], (3, 1)), np.tile([1.0, 0, 0], (3, 1))])
    )
    assert build_grid([creased], _spacing_for(diagonal, n)).point_count == (n + 1) * (n + 2)


def test_edge_points_are_bit_identical_from_both_sides():
    """An edge crossing x = 0 next to its 9th of 63 cuts: computed from either end the point
    rounds to different float32 values, so only the canonical order welds it."""
    n, m, d = 63, 9, np.float32(0.0371)
    p = np.array([np.float32(-m * float(d)), 0.0, 0.0])
    q = np.array([np.nextafter(np.float32((n - m) * float(d)), np.float32(1)), 0.0, 0.0])
    from_p = np.float32(p[0] + m / n * (q[0] - p[0]))
    assert from_p != np.float32(q[0] + (n - m) / n * (p[0] - q[0]))  # the case is a real one
    mid = (p + q) / 2
    off = np.array([0.0, 1.5, 0.0])  # wide enough that the edge, not the area, sets n
    r, s = mid + off, mid - off
    corners = _corners(np.array([[p, q, r], [q, p, s]]), np.tile([0.0, 0.0, 1.0], (2, 3, 1)))
    grid = build_grid([corners], float(np.linalg.norm(q - p)) / (n - 0.5))
    assert grid.tri_cuts.tolist() == [n, n]
    assert grid.point_count == (n + 1) ** 2


@pytest.mark.parametrize("n", [1, 3])
def test_smooth_lattice_welds_to_one_grid(rng, n):
    nx, ny = 6, 5
    corners = _lattice(rng, nx, ny)
    diagonal = np.linalg.norm(_tris(corners)[0].max(0) - _tris(corners)[0].min(0))
    grid = build_grid([corners], _spacing_for(diagonal, n))
    assert set(grid.tri_cuts.tolist()) == {n}
    assert grid.point_count == (n * (nx - 1) + 1) * (n * (ny - 1) + 1)
    expected, got = _positions(grid, corners)
    np.testing.assert_allclose(got, expected, atol=1e-6)


def test_cube_keeps_a_point_per_face_at_its_hard_edges():
    corners = primitives.cube(size=2.0).world_space_corners()
    grid = build_grid([corners], 10.0)
    assert grid.point_count == 24  # 4 per face, none shared across faces
    _, per_corner = np.unique(grid.positions.round(5), axis=0, return_counts=True)
    assert per_corner.tolist() == [3] * 8
    assert np.allclose(np.abs(grid.normals).max(axis=1), 1.0)  # each an axis
    n = int(np.ceil(2 * np.sqrt(2) / 1.0))
    assert build_grid([corners], 1.0).point_count == 6 * (n + 1) ** 2


def test_smooth_sphere_welds_to_about_its_vertex_count():
    sphere = primitives.uv_sphere(segments=48, rings=24)
    vertices = 48 * 23 + 2
    grid = build_grid([sphere.world_space_corners()], 1.0)
    assert set(grid.tri_cuts.tolist()) == {1}
    # The primitive's seam and poles are not bit-identical in its positions: a few more.
    assert vertices <= grid.point_count <= 1.1 * vertices


def test_meshes_keep_their_own_points():
    plane = primitives.plane().world_space_corners()
    grid = build_grid([plane, plane, np.zeros((0, 12), np.float32)], 10.0)
    assert grid.point_count == 8
    assert grid.mesh_first_triangle.tolist() == [0, 2, 4, 4]
    assert grid.point_mesh.tolist() == [0] * 4 + [1] * 4
    assert build_grid([], 1.0).point_count == 0


def _random_mesh(rng, count: int = 40):
    tris = rng.normal(size=(count, 1, 3)) * 3 + rng.normal(size=(count, 3, 3)) * rng.uniform(
        0.05, 1.0, size=(count, 1, 1)
    )
    return _corners(tris)


def _random_surface_points(rng, grid, count: int):
    tri = rng.integers(len(grid.tri_cuts), size=count)
    bu, bv = rng.random(count), rng.random(count)
    fold = bu + bv > 1
    return tri, np.where(fold, 1 - bu, bu), np.where(fold, 1 - bv, bv)


def _surface(corners, tri, bu, bv):
    c = _tris(corners)[tri]
    return c[:, 0] + bu[:, None] * (c[:, 1] - c[:, 0]) + bv[:, None] * (c[:, 2] - c[:, 0])


def test_locate_reproduces_surface_positions(rng):
    corners = _random_mesh(rng)
    grid = build_grid([corners], 0.2)
    assert grid.tri_cuts.max() > 3 and grid.tri_cuts.min() < grid.tri_cuts.max()
    tri, bu, bv = _random_surface_points(rng, grid, 5000)
    tri[:9] = np.argmax(grid.tri_cuts)
    # The special cases: grid lines, corners, the far edge bu + bv = 1, just outside (past
    # the far edge, in the last row's lower cell: no upper cell there).
    n = grid.tri_cuts[tri[:9]]
    bu[:9] = [0, 1, 0, 1 / n[3], 0.3, 2 / n[5], 0.0, -1e-9, 1.6 / n[8]]
    bv[:9] = [0, 0, 1, 0.0, 0.7, 1 - 2 / n[5], 1 / n[6], 0.5, (n[8] - 1.6 + 1e-9) / n[8]]
    ids, w = locate(grid, tri, bu, bv)
    assert ids.shape == w.shape == (5000, 3)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(w >= 0)
    got = np.einsum("na,nad->nd", w, grid.positions[ids].astype(np.float64))
    scale = np.abs(_tris(corners)).max()
    np.testing.assert_allclose(got, _surface(corners, tri, bu, bv), atol=1e-5 * scale)
    # At a grid vertex its own point carries all the weight.
    for m in range(3):
        assert w[m, np.argmax(w[m])] == pytest.approx(1.0, abs=1e-12)


def test_locate_past_the_far_edge_uses_the_last_rows_lower_cell(rng):
    """Half a cell past the far edge there is no upper cell: the lower cell's clamped weights
    put the point on the far edge (module docstring)."""
    corners = _random_mesh(rng)
    grid = build_grid([corners], 0.2)
    t = int(np.argmax(grid.tri_cuts))
    n = int(grid.tri_cuts[t])
    ids, w = locate(grid, np.array([t]), np.array([1.6 / n]), np.array([(n - 1.1) / n]))
    np.testing.assert_allclose(w, [[0.0, 0.4, 0.6]], atol=1e-9)
    got = w @ grid.positions[ids[0]].astype(np.float64)
    expected = _surface(corners, np.array([t]), np.array([1.4 / n]), np.array([(n - 1.4) / n]))
    np.testing.assert_allclose(got, expected, atol=1e-5 * np.abs(_tris(corners)).max())


def test_locate_non_finite_takes_the_first_vertex(rng):
    grid = build_grid([_random_mesh(rng, 5)], 0.3)
    tri = np.array([1, 2, 3])
    ids, w = locate(grid, tri, np.array([np.nan, 0.2, np.inf]), np.array([0.1, np.nan, 0.0]))
    assert w.tolist() == [[1.0, 0.0, 0.0]] * 3
    assert ids[:, 0].tolist() == grid.tri_points[grid.tri_first[tri]].tolist()


@pytest.mark.parametrize("views", [1, 2, 5, 7])
def test_bin_weights_at_bin_centres_and_linear_in_the_square(rng, views):
    dirs = bin_directions(views)
    bins, w = bin_weights(dirs, views)
    own = np.where(bins == np.arange(views * views)[:, None], w, 0).sum(axis=1)
    np.testing.assert_allclose(own, 1.0, atol=1e-5)
    # A linear function of the bin centres' square coordinates is reproduced exactly inside
    # the clamped region, and clamped outside it.
    r, c = np.divmod(np.arange(views * views), views)
    f = 0.3 + 1.7 * bin_centre(c, views) - 0.9 * bin_centre(r, views)
    s = rng.random((2000, 2))
    bins, w = bin_weights(square_to_hemisphere(s), views)
    lo, hi = bin_centre(0, views), bin_centre(views - 1, views)
    clamped = np.clip(s, lo, hi)
    np.testing.assert_allclose(
        (w * f[bins]).sum(1), 0.3 + 1.7 * clamped[:, 0] - 0.9 * clamped[:, 1], atol=1e-9
    )
    # The heaviest bin is the nearest bin centre on the square (away from ties).
    heaviest = bins[np.arange(len(bins)), np.argmax(w, axis=1)]
    centres = np.stack([bin_centre(c, views), bin_centre(r, views)], 1)
    distance = np.abs(s[:, None, :] - centres[None]).max(axis=2)  # the bilinear cell's metric
    nearest = np.argmin(distance, axis=1)
    ordered = np.sort(distance, axis=1)
    clear = views == 1 or (ordered[:, 1] - ordered[:, 0] > 1e-6)
    assert np.all((heaviest == nearest)[clear])


def test_bin_weights_grazing_and_invalid_views():
    wo = np.array(
        [
            [1, 0, 0],
            [1, 0, -0.3],
            [0.2, -1, 1e-12],
            [0, 0, -1],
            [0, 0, 0],
            [np.nan, 0, 1],
            [0, np.inf, 1],
        ],
        dtype=np.float64,
    )
    bins, w = bin_weights(wo, 7)
    assert np.all(np.isfinite(w)) and np.all((bins >= 0) & (bins < 49))
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
    assert bins[0].tolist() == bins[1].tolist()  # below the horizon reads as grazing
    np.testing.assert_allclose(w[0], w[1], atol=1e-5)
    assert bins[0][np.argmax(w[0])] == 3 * 7 + 6  # +x: the square's right edge, middle row
    for row in (5, 6):
        assert bins[row, 0] == 0 and w[row].tolist() == [1.0, 0.0, 0.0, 0.0]
    # Below the horizon in any azimuth: as the same azimuth just above it.
    below, above = bin_weights(np.array([[0.3, 0.8, -0.5], [0.3, 0.8, 1e-9]]), 7)
    assert below[0].tolist() == below[1].tolist()
    np.testing.assert_allclose(above[0], above[1], atol=1e-5)


def test_playback_reproduces_linear_values(rng):
    views, corners = 5, _random_mesh(rng, 30)
    grid = build_grid([corners], 0.25)
    r, c = np.divmod(np.arange(views * views), views)
    a = rng.normal(size=(3, 2))  # 2 channels, each linear in the position and in the bin
    by_bin = bin_centre(c, views)[:, None] * [1.0, -2.0] + bin_centre(r, views)[:, None] * [
        0.3,
        0.7,
    ]
    values = (grid.positions.astype(np.float64) @ a)[:, None] + 0.5 + by_bin[None]
    tri, bu, bv = _random_surface_points(rng, grid, 3000)
    s = rng.uniform(bin_centre(0, views), bin_centre(views - 1, views), size=(3000, 2))
    got = playback(grid, values, tri, bu, bv, square_to_hemisphere(s), views)
    expected = (
        _surface(corners, tri, bu, bv) @ a + 0.5 + s[:, :1] * [1.0, -2.0] + s[:, 1:] * [0.3, 0.7]
    )
    np.testing.assert_allclose(got, expected, atol=1e-5 * (np.abs(expected).max() + 1))


def _holder_pairs(grid) -> np.ndarray:
    """(triangle · P + point) for every grid vertex: which triangles hold which points."""
    sizes = np.diff(np.r_[grid.tri_first, len(grid.tri_points)])
    return np.repeat(np.arange(len(sizes)), sizes) * grid.point_count + grid.tri_points


def test_footprints_lie_in_the_cells_around_their_point(rng):
    meshes = [
        _random_mesh(rng, 20),
        primitives.uv_sphere(segments=12, rings=6).world_space_corners(),
    ]
    grid = build_grid(meshes, 0.3, footprint=16, seed=3)
    tris = np.concatenate([_tris(m) for m in meshes])
    t, b = grid.footprint_tri, grid.footprint_bary.astype(np.float64)
    assert t.shape == (grid.point_count, 16) and b.shape == (grid.point_count, 16, 2)
    assert np.all(b >= 0) and np.all(b.sum(-1) <= 1 + 1e-6)
    p = np.arange(grid.point_count)[:, None]
    assert np.all(np.isin(t * grid.point_count + p, _holder_pairs(grid)))
    c = tris[t]
    pos = (
        c[..., 0, :]
        + b[..., :1] * (c[..., 1, :] - c[..., 0, :])
        + b[..., 1:] * (c[..., 2, :] - c[..., 0, :])
    )
    longest = np.linalg.norm(c - np.roll(c, 1, axis=-2), axis=-1).max(-1)
    reach = 1.01 * longest / grid.tri_cuts[t] + 1e-6
    assert np.all(np.linalg.norm(pos - grid.positions[:, None], axis=-1) <= reach)
    again = build_grid(meshes, 0.3, footprint=16, seed=3)
    assert np.array_equal(again.footprint_bary, grid.footprint_bary)
    assert not np.array_equal(build_grid(meshes, 0.3, seed=4).footprint_bary, grid.footprint_bary)


def test_footprint_is_uniform_over_the_point_neighbourhood(rng):
    # Two flat triangles sharing only corner 0, areas 1 : 3: the stratified samples split so.
    tris = np.array([[[0, 0, 0], [1, 0, 0], [0, 2, 0]], [[0, 0, 0], [0, -3, 0], [2, 0, 0]]], float)
    grid = build_grid([_corners(tris)], 10.0, footprint=64)
    shared = grid.tri_points[0]
    assert grid.tri_points[3] == shared
    in_big = int((grid.footprint_tri[shared] == 1).sum())
    assert abs(in_big - 48) <= 1
    # An interior vertex of a regular lattice: its 6 cells are symmetric about it.
    corners = _lattice(rng, 4, 4)
    grid = build_grid([corners], 0.05, footprint=1024)
    t, b = grid.footprint_tri, grid.footprint_bary.astype(np.float64)
    c = _tris(corners)[t]
    pos = (
        c[..., 0, :]
        + b[..., :1] * (c[..., 1, :] - c[..., 0, :])
        + b[..., 1:] * (c[..., 2, :] - c[..., 0, :])
    )
    centre = np.argmin(np.linalg.norm(grid.positions - grid.positions.mean(0), axis=1))
    cell = 0.137 / grid.tri_cuts[0]
    assert np.linalg.norm(pos[centre].mean(0) - grid.positions[centre]) < 0.05 * cell


def test_zero_area_triangles_give_finite_points_and_footprints():
    tris = np.array(
        [
            [[1, 1, 1], [1, 1, 1], [1, 1, 1]],  # a point
            [[0, 0, 0], [2, 0, 0], [4, 0, 0]],  # collinear: cut but flat
            [[5, 0, 0], [6, 0, 0], [5, 1, 0]],  # a proper one
        ],
        float,
    )
    normals = np.zeros((3, 3, 3))
    normals[..., 2] = 1.0
    normals[0] = [[1, 0, 0], [-1, 0, 0], [0, 0, 0]]  # a zero blend: the fallback normal
    grid = build_grid([_corners(tris, normals)], 0.5, footprint=8)
    for a in (grid.positions, grid.normals, grid.footprint_bary):
        assert np.all(np.isfinite(a))
    # The collinear triangle's points (nothing else holds them) sample themselves.
    own = np.unique(grid.tri_points[grid.tri_first[1] : grid.tri_first[2]])  # welded on the line
    # no area: one cut (bake_points._longest), whatever its length
    assert grid.tri_cuts[1] == 1 and np.all(grid.footprint_tri[own] == 1)
    b = grid.footprint_bary[own].astype(np.float64)
    assert np.all(b == b[:, :1])
    c = tris[1]
    at = c[0] + b[:, 0, :1] * (c[1] - c[0]) + b[:, 0, 1:] * (c[2] - c[0])
    np.testing.assert_allclose(at, grid.positions[own], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(grid.normals, axis=1), 1.0, atol=1e-6)


def test_oversized_grids_are_refused_with_a_spacing_that_fits(rng, monkeypatch):
    corners = _random_mesh(rng, 10)
    monkeypatch.setattr(bake_points, "MAX_POINTS", 500)

    def no_build(*args):
        raise AssertionError("built before refusing")

    monkeypatch.setattr(bake_points, "_vertices", no_build)
    with pytest.raises(BakeGridTooLarge, match=r"spacing .*at least") as info:
        build_grid([corners], 0.001)
    assert "500" in str(info.value)
    fit = float(re.search(r"at least ([0-9.e+-]+)", str(info.value)).group(1))
    monkeypatch.undo()
    monkeypatch.setattr(bake_points, "MAX_POINTS", 500)
    assert len(build_grid([corners], fit).tri_points) <= 500
    monkeypatch.setattr(bake_points, "MAX_POINTS", 20)
    with pytest.raises(BakeGridTooLarge, match="fewer objects"):
        build_grid([corners], 1.0)
    monkeypatch.undo()
    huge = _corners(np.tile([[[0, 0, 0], [1e3, 0, 0], [0, 1e3, 0]]], (2000, 1, 1)))
    with pytest.raises(BakeGridTooLarge, match=r"raise the spacing to at least"):
        build_grid([huge], 1e-3)


def test_grid_bytes_bounds_the_grid(rng):
    meshes = [_random_mesh(rng, 30), primitives.cube().world_space_corners()]
    for spacing in (0.1, 0.5, 5.0):
        grid = build_grid(meshes, spacing)
        assert grid.nbytes <= grid_bytes(meshes, spacing) < 40 * grid.nbytes
