"""Bake points: a grid of points on a scene's surfaces where a light bake stores its values.
UVs are never read, so overlapping or missing UVs are fine.

Grid. Triangle t (every mesh's triangles concatenated in order; corners c0, c1, c2 as
``Mesh.world_space_corners`` gives them) is cut into n² cells,
n = clamp(ceil(min(longest edge, 2·√area) / spacing), 1, MAX_CUTS). Grid vertex (i, j),
i, j ≥ 0, i + j ≤ n, lies at barycentrics (bu, bv) = (i/n, j/n), bu the weight of corner 1
and bv of corner 2: c0 + bu·(c1 − c0) + bv·(c2 − c0);
its normal is the same blend of the corner normals, normalised (a zero blend: the face
normal). Its local index is k(i, j) = i·(n+1) − i·(i−1)/2 + j (rows by i, row i holding
n − i + 1 vertices), and ``tri_points[tri_first[t] + k]`` is its bake point.
Cells of triangle t: lower (i, j) = vertices (i,j), (i+1,j), (i,j+1) for i + j ≤ n − 1; upper
(i, j) = (i+1,j+1), (i,j+1), (i+1,j) for i + j ≤ n − 2.

Welding. Coinciding grid vertices of one mesh become one point when their positions are equal
and their normals agree (dot > WELD_COS), so hard edges keep a point per side. Corner vertices
are copies of the corner rows; an edge-interior vertex is computed from the edge's endpoints
in a canonical order (lexicographically smaller position first, in float64, then rounded), so
two triangles sharing an edge with the same n give bit-identical points. Vertices are grouped
by the exact bytes of their float32 position (−0 read as +0); in a group, every vertex whose
normal agrees with the group's first unassigned vertex joins it, repeated until all are
assigned (exact where a quantised normal would split near-equal normals at a cell boundary).
Points are numbered by first appearance; a point's position and normal are its first vertex's.

Footprint: per point, F surface samples where a bake evaluates the surface: uniform over the
union of the cells around the point in every triangle holding it (each triangle's cells weighed
by their area), stratified over that union in F strata, uniform inside the chosen cell;
seeded. A point whose triangles all have zero area samples itself F times.

Playback (the GLSL and OpenCL code mirror it): ``locate`` gives a surface point's 3 bake points
and weights, a = bu·n, b = bv·n, i = clamp(floor(a), 0, n−1), j = clamp(floor(b), 0, n−1−i),
fa = a − i, fb = b − j; the lower cell (i, j) with weights (1−fa−fb, fa, fb) when fa + fb ≤ 1
or when the upper cell does not exist (i + j = n − 1: the point is past the triangle's far
edge), else the upper cell (i, j) with (fa+fb−1, 1−fa, 1−fb); weights clamped to ≥ 0 and
renormalised; non-finite bu or bv: vertex (0, 0) with weight 1 (weights (1, 0, 0) of the lower
cell (0, 0)). View bin (r, c), index r·V + c, is the direction ``square_to_hemisphere`` of the
square point (x, y) = (bin_centre(c), bin_centre(r)), bin_centre(k) = m + (1 − 2m)·k/(V − 1),
m = BIN_MARGIN (½ for V = 1): column c along the square's x, row r along its y, the outer bins
on the square's border inset by m. ``bin_weights``: s = (hemisphere_to_square(wo) − m)/(1 − 2m)
·(V − 1) clamped to [0, V − 1] per axis, x0 = min(floor(s.x), V − 2),
x1 = min(x0 + 1, V − 1) (y alike),
bins (x0,y0), (x1,y0), (x0,y1), (x1,y1) weighted bilinearly by s − (x0, y0); wo with z ≤ 0 is
read as z = GRAZING·|wo.xy| (a grazing view), one with no xy either as the normal; non-finite:
bin 0 with weight 1. ``playback`` blends the 3 × 4 values with the products of the weights.

Light direction: a bake also holds, per point, the unit direction its light mostly comes from
(in its frame: x along the tangent, z along the normal). ``playback_direction`` blends the 3
located points' directions with ``locate``'s weights and normalises the blend; a blend shorter
than 1e-6 (or not finite) is the normal (0, 0, 1). ``pack_values`` lays a bake out as the GPU
code reads it: per point V² + 1 float4, its bins' values (rgb) then its direction (xyz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from ..core.errors import BTFError
from ..core.sampling.btf_importance import hemisphere_to_square, square_to_hemisphere

#: Cuts per triangle at most: it bounds any triangle at 257·258/2 = 33153 points (a larger
#: triangle is then coarser than the spacing: subdivide it to bake finer). A ground plane of
#: two triangles, 6 m a side, takes 170 cuts at the default 5 cm. A sliver (one long edge,
#: almost no area) is cut by its area instead (``_cuts``): n² cells for nothing otherwise.
MAX_CUTS = 256
MAX_POINTS = 4_000_000  # grid vertices before welding (an upper bound on the points)
WELD_COS = 0.999  # normals agree above this dot product
GRAZING = 1e-6  # z given to views at or below the horizon, relative to |wo.xy|
#: The outer view bins' inset from the square's border: their views lie at θ = 74° (disk
#: radius 0.96), where measured BTFs end (BTFbase: 75°). Bins centred in their cells
#: ((c + ½)/V) put the outermost at 53° for V = 5, and a grazing view (a ground seen from
#: eye height) took that bin's light unchanged: 2 % too dark on the bench's ground.
BIN_MARGIN = 0.02
_CHUNK = 1 << 16  # points per footprint batch: bounds its (chunk, F, 6) temporaries

# The 6 cells around vertex (i, j): (di, dj, upper) of cell (i + di, j + dj); see _cell_masks.
_DI, _DJ = np.array([0, -1, 0, -1, 0, -1]), np.array([0, 0, -1, -1, -1, 0])
_UP = np.array([False, False, False, True, True, True])


class BakeGridTooLarge(BTFError, ValueError):  # noqa: N818 - the name callers catch
    """The grid would exceed MAX_POINTS; the message names the spacing that fits. A BTFError:
    the CLI exits 2 with it and the operator reports it, as any input that cannot be used."""


@dataclass(frozen=True, eq=False)
class BakeGrid:
    spacing: float
    positions: np.ndarray  # (P, 3) float32 world
    normals: np.ndarray  # (P, 3) float32 unit
    tri_cuts: np.ndarray  # (T,) int32 n_t
    tri_first: np.ndarray  # (T,) int32 offset of triangle t's entries in tri_points
    tri_points: np.ndarray  # (sum (n+1)(n+2)/2,) int32 point of each grid vertex, by k(i, j)
    mesh_first_triangle: np.ndarray  # (M + 1,) int32: mesh m owns triangles [a[m], a[m+1])
    point_mesh: np.ndarray  # (P,) int32 the mesh of each point
    footprint_tri: np.ndarray  # (P, F) int32 triangle of each footprint sample
    footprint_bary: np.ndarray  # (P, F, 2) float32 (bu, bv) in that triangle

    @property
    def point_count(self) -> int:
        return len(self.positions)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, f.name).nbytes for f in fields(self) if f.name != "spacing")


def _triangles(corners: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(T, 3, 6) float32 position + normal per corner, and mesh_first_triangle."""
    tris = [np.asarray(c, dtype=np.float32)[:, :6].reshape(-1, 3, 6) for c in corners]
    first = np.concatenate([[0], np.cumsum([len(t) for t in tris], dtype=np.int64)])
    data = np.concatenate(tris) if tris else np.zeros((0, 3, 6), np.float32)
    return data, first.astype(np.int32)


def _longest(tri: np.ndarray) -> np.ndarray:
    """Per triangle, the longest edge, capped at twice the side of a square of its area: a
    sliver's cells then follow its width, not its length (n = 1 where it is thinner than the
    spacing)."""
    p = tri[:, :, :3].astype(np.float64)
    longest = np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).max(axis=1, initial=0.0)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    with np.errstate(invalid="ignore"):
        return np.minimum(longest, 2.0 * np.sqrt(area))


def _cuts(longest: np.ndarray, spacing: float) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore"):
        r = np.ceil(longest / spacing)
    return np.clip(np.where(np.isfinite(r), r, 1), 1, MAX_CUTS).astype(np.int32)


def _entries(n: np.ndarray) -> np.ndarray:
    n = n.astype(np.int64)
    return (n + 1) * (n + 2) // 2


def grid_bytes(corners: list[np.ndarray], spacing: float, footprint: int = 16) -> int:
    """An upper bound of ``build_grid``'s result in bytes (points counted before welding)."""
    tri, first = _triangles(corners)
    e = int(_entries(_cuts(_longest(tri), spacing)).sum())
    return e * 4 + len(tri) * 8 + len(first) * 4 + e * (12 + 12 + 4 + footprint * 12)


def _check_size(longest: np.ndarray, spacing: float) -> None:
    count = int(_entries(_cuts(longest, spacing)).sum())
    if count <= MAX_POINTS:
        return
    if 3 * len(longest) > MAX_POINTS:
        raise BakeGridTooLarge(
            f"a bake grid on {len(longest)} triangles needs {3 * len(longest)} points even at "
            f"one cell per triangle, over the limit of {MAX_POINTS}: bake fewer objects"
        )
    # The count only falls as the spacing grows, and is 3·T at the longest edge: bisect.
    lo, hi = spacing, float(longest[np.isfinite(longest)].max())
    for _ in range(64):
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if _entries(_cuts(longest, mid)).sum() <= MAX_POINTS else (mid, hi)
    step = 10.0 ** (math.floor(math.log10(hi)) - 2)  # 3 significant digits, rounded up
    raise BakeGridTooLarge(
        f"a bake grid at spacing {spacing:.3g} needs up to {count} points, over the limit of "
        f"{MAX_POINTS}: raise the spacing to at least {math.ceil(hi / step) * step:.3g}"
    )


@lru_cache(maxsize=MAX_CUTS)
def _ij(n: int) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) of triangle-local index k = 0 .. (n+1)(n+2)/2 − 1."""
    i = np.repeat(np.arange(n + 1), np.arange(n + 1, 0, -1))
    return i, np.arange(len(i)) - (i * (n + 1) - i * (i - 1) // 2)


def _before(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(G,) whether position a is lexicographically smaller than b."""
    return (a[:, 0] < b[:, 0]) | (
        (a[:, 0] == b[:, 0]) & ((a[:, 1] < b[:, 1]) | ((a[:, 1] == b[:, 1]) & (a[:, 2] < b[:, 2])))
    )


def _vertices(tri: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(G, 3, 6) triangles cut n times → (G, K, 3) float64 positions and normals, by k."""
    c, q = tri[:, :, :3].astype(np.float64), tri[:, :, 3:6].astype(np.float64)
    i, j = _ij(n)
    steps = np.stack([n - i - j, i, j], axis=1)  # n × barycentric weight of each corner
    p = c[:, None, 0] + (i / n)[:, None] * (c[:, None, 1] - c[:, None, 0])
    p += (j / n)[:, None] * (c[:, None, 2] - c[:, None, 0])
    m = np.einsum("kc,gcd->gkd", steps / n, q)
    for u, v in ((0, 1), (0, 2), (1, 2)):  # edge-interior vertices, canonical order
        sel = (steps[:, 3 - u - v] == 0) & (steps[:, u] > 0) & (steps[:, v] > 0)
        swap = _before(c[:, v], c[:, u])[:, None]
        t = np.where(swap, steps[sel, u], steps[sel, v])[..., None] / n
        for out, x in ((p, c), (m, q)):
            a = np.where(swap, x[:, v], x[:, u])[:, None]
            b = np.where(swap, x[:, u], x[:, v])[:, None]
            out[:, sel] = a + t * (b - a)
    for corner, k in ((0, 0), (1, len(i) - 1), (2, n)):  # k(0,0), k(n,0), k(0,n)
        p[:, k], m[:, k] = c[:, corner], q[:, corner]
    face = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    face = np.where(np.linalg.norm(face, axis=1, keepdims=True) > 0, face, (0.0, 0.0, 1.0))
    length = np.linalg.norm(m, axis=2, keepdims=True)
    m = np.where(length > 1e-12, m, face[:, None])
    return p, m / np.linalg.norm(m, axis=2, keepdims=True)


def _weld(mesh: np.ndarray, pos: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    """(E,) the first vertex of each vertex's point (module docstring, Welding)."""
    bits = (pos + np.float32(0.0)).view(np.uint32).astype(np.int64)  # −0 + 0 = +0
    order = np.lexsort((bits[:, 2], bits[:, 1], bits[:, 0], mesh))  # stable: by first seen
    key = np.column_stack([mesh, bits])[order]
    group = np.cumsum(np.r_[True, np.any(key[1:] != key[:-1], axis=1)])
    nrm = nrm[order].astype(np.float64)
    leader = np.empty(len(order), dtype=np.int64)
    pending = np.arange(len(order))
    while pending.size:  # one pass per distinct normal at a position (3 at a cube's corner)
        g = group[pending]
        head = np.r_[True, g[1:] != g[:-1]]
        head_of = pending[head][np.cumsum(head) - 1]
        join = head | (np.einsum("ij,ij->i", nrm[pending], nrm[head_of]) > WELD_COS)
        leader[pending[join]] = head_of[join]
        pending = pending[~join]
    first = np.empty(len(order), dtype=np.int64)
    first[order] = order[leader]
    return first


def _cell_masks(i: np.ndarray, j: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(E, 6) which of the cells (_DI, _DJ, _UP) around vertex (i, j) exist."""
    inner = i + j <= n - 1
    return np.stack([inner, i >= 1, j >= 1, (i >= 1) & (j >= 1), (j >= 1) & inner,
                     (i >= 1) & inner], axis=1)  # fmt: skip


def _footprint(point, ent_tri, i, j, cuts, area, count, f, seed):
    """(P, F) triangles and (P, F, 2) barycentrics of the footprints (module docstring), from
    each grid vertex's point, triangle and (i, j)."""
    n = cuts[ent_tri].astype(np.int64)
    masks = _cell_masks(i, j, n)
    cells = masks.sum(axis=1)
    kinds = np.argsort(~masks, axis=1, kind="stable")  # row e: its existing cells first
    weight = cells * area[ent_tri] / n.astype(np.float64) ** 2
    total = np.bincount(point, weights=weight, minlength=count)
    order = np.argsort(point, kind="stable")  # vertices grouped by point
    start = np.searchsorted(point[order], np.arange(count + 1))
    p_sorted = point[order]
    share = weight[order] / np.where(total > 0, total, np.inf)[p_sorted]  # per point: sums to 1
    cum = np.cumsum(share)
    # p + the cumulative share inside p's run: monotone, and exact to a few ulps of p.
    key = p_sorted + cum - np.r_[0.0, cum][start[:-1]][p_sorted]
    tri_out = np.empty((count, f), dtype=np.int32)
    bary = np.empty((count, f, 2), dtype=np.float32)
    rng = np.random.default_rng(seed)
    for lo in range(0, count, _CHUNK):
        p = np.arange(lo, min(lo + _CHUNK, count))
        r = rng.random((len(p), f, 3))
        target = p[:, None] + (np.arange(f) + r[..., 0]) / f  # one stratum per sample
        s = np.clip(
            np.searchsorted(key, target, side="right"), start[p, None], start[p + 1, None] - 1
        )
        e = order[s]
        into = np.clip((target - key[s] + share[s]) / np.maximum(share[s], 1e-300), 0.0, 1.0)
        cell = kinds[e, np.minimum((into * cells[e]).astype(np.int64), cells[e] - 1)]
        fold = r[..., 1] + r[..., 2] > 1.0  # uniform in the cell's triangle
        r1, r2 = np.where(fold, 1 - r[..., 1], r[..., 1]), np.where(fold, 1 - r[..., 2], r[..., 2])
        up, ci, cj = _UP[cell], i[e] + _DI[cell], j[e] + _DJ[cell]
        a, b = np.where(up, ci + 1 - r1, ci + r1), np.where(up, cj + 1 - r2, cj + r2)
        none = total[p] <= 0  # only zero-area triangles: the point itself
        e0 = order[start[p]][:, None]
        a, b = np.where(none[:, None], i[e0], a), np.where(none[:, None], j[e0], b)
        e = np.where(none[:, None], e0, e)
        tri_out[p] = ent_tri[e]
        bary[p] = np.stack([a / n[e], b / n[e]], axis=-1)
    return tri_out, bary


def build_grid(
    corners: list[np.ndarray], spacing: float, footprint: int = 16, seed: int = 0
) -> BakeGrid:
    """The bake grid of meshes given as world-space corner arrays (3·T, ≥ 6) float32 rows
    (position, unit normal, …); BakeGridTooLarge before anything is built when it would
    exceed MAX_POINTS."""
    if not (math.isfinite(spacing) and spacing > 0) or footprint < 1:
        raise ValueError("spacing must be finite and > 0, footprint ≥ 1")
    tri, mesh_first = _triangles(corners)
    longest = _longest(tri)
    _check_size(longest, spacing)
    cuts = _cuts(longest, spacing)
    sizes = _entries(cuts)
    tri_first = np.concatenate([[0], np.cumsum(sizes)])
    total = int(tri_first[-1])
    pos, nrm = np.empty((total, 3), np.float32), np.empty((total, 3), np.float32)
    ent_i, ent_j = np.empty(total, np.int64), np.empty(total, np.int64)
    for n in np.unique(cuts):
        ts = np.flatnonzero(cuts == n)
        idx = (tri_first[ts][:, None] + np.arange(sizes[ts[0]])).ravel()
        p, m = _vertices(tri[ts], int(n))
        pos[idx], nrm[idx] = p.reshape(-1, 3), m.reshape(-1, 3)
        i, j = _ij(int(n))
        ent_i[idx], ent_j[idx] = np.tile(i, len(ts)), np.tile(j, len(ts))
    ent_tri = np.repeat(np.arange(len(tri)), sizes)
    mesh = np.repeat(np.arange(len(corners)), np.diff(mesh_first))[ent_tri]
    firsts, point = np.unique(_weld(mesh, pos, nrm), return_inverse=True)
    c = tri[:, :, :3].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
    area = np.where(np.isfinite(area), area, 0.0)
    fp_tri, fp_bary = _footprint(point, ent_tri, ent_i, ent_j, cuts, area, len(firsts),
                                 footprint, seed)  # fmt: skip
    return BakeGrid(
        spacing=float(spacing),
        positions=pos[firsts],
        normals=nrm[firsts],
        tri_cuts=cuts,
        tri_first=tri_first[:-1].astype(np.int32),
        tri_points=point.astype(np.int32),
        mesh_first_triangle=mesh_first,
        point_mesh=mesh[firsts].astype(np.int32),
        footprint_tri=fp_tri,
        footprint_bary=fp_bary,
    )


def locate(
    grid: BakeGrid, tri: np.ndarray, bu: np.ndarray, bv: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) point ids and (N, 3) float64 weights summing to 1 for surface points given as
    triangle t and barycentrics (the rule in the module docstring)."""
    tri = np.asarray(tri, dtype=np.int64).ravel()
    bu, bv = (np.asarray(x, dtype=np.float64).ravel() for x in (bu, bv))
    ok = np.isfinite(bu) & np.isfinite(bv)
    n = grid.tri_cuts[tri].astype(np.int64)
    a, b = np.where(ok, bu, 0.0) * n, np.where(ok, bv, 0.0) * n  # non-finite: weights (1, 0, 0)
    i = np.clip(np.floor(a), 0, n - 1).astype(np.int64)
    j = np.clip(np.floor(b), 0, n - 1 - i).astype(np.int64)
    fa, fb = a - i, b - j
    lower = ((fa + fb <= 1.0) | (i + j >= n - 1))[:, None]  # no upper cell on the far edge
    vi = np.where(lower, np.stack([i, i + 1, i], 1), np.stack([i + 1, i, i + 1], 1))
    vj = np.where(lower, np.stack([j, j, j + 1], 1), np.stack([j + 1, j + 1, j], 1))
    w = np.where(
        lower, np.stack([1 - fa - fb, fa, fb], 1), np.stack([fa + fb - 1, 1 - fa, 1 - fb], 1)
    )
    w = np.maximum(w, 0.0)
    w /= w.sum(axis=1, keepdims=True)  # ≥ 1: only negative weights were removed
    k = vi * (n[:, None] + 1) - vi * (vi - 1) // 2 + vj
    return grid.tri_points[grid.tri_first[tri][:, None] + k], w


def bin_centre(index: np.ndarray, view_bins: int) -> np.ndarray:
    """Square coordinate of bin column (or row) ``index``: from BIN_MARGIN to 1 − BIN_MARGIN in
    equal steps (0.5 for one bin)."""
    if view_bins == 1:
        return np.full(np.shape(index), 0.5)
    return BIN_MARGIN + (1 - 2 * BIN_MARGIN) * np.asarray(index, np.float64) / (view_bins - 1)


def bin_directions(view_bins: int) -> np.ndarray:
    """(V², 3) float64 unit directions: bin (r, c) at index r·V + c, at square point
    (bin_centre(c), bin_centre(r))."""
    r, c = np.divmod(np.arange(view_bins * view_bins), view_bins)
    return square_to_hemisphere(np.stack([bin_centre(c, view_bins), bin_centre(r, view_bins)], 1))


def bin_weights(wo: np.ndarray, view_bins: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) view directions (local frame, z along the normal) → (N, 4) int32 bin indices and
    (N, 4) float64 bilinear weights (module docstring)."""
    v = int(view_bins)
    w = np.asarray(wo, dtype=np.float64).reshape(-1, 3)
    ok = np.all(np.isfinite(w), axis=1)
    w = np.where(ok[:, None], w, (0.0, 0.0, 1.0))
    h = np.hypot(w[:, 0], w[:, 1])
    z = np.where(w[:, 2] > 0, w[:, 2], np.where(h > 0, GRAZING * h, 1.0))
    square = hemisphere_to_square(np.column_stack([w[:, :2], z]))
    s = np.clip((square - BIN_MARGIN) / (1 - 2 * BIN_MARGIN) * (v - 1), 0, v - 1)
    lo = np.minimum(np.floor(s), max(v - 2, 0)).astype(np.int64)
    f, hi = s - lo, np.minimum(lo + 1, v - 1)
    (x0, y0), (x1, y1), (fx, fy) = lo.T, hi.T, f.T
    bins = np.stack([y0 * v + x0, y0 * v + x1, y1 * v + x0, y1 * v + x1], 1)
    weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], 1)
    bins[~ok], weights[~ok] = 0, (1.0, 0.0, 0.0, 0.0)
    return bins.astype(np.int32), weights


def playback(grid: BakeGrid, values: np.ndarray, tri, bu, bv, wo, view_bins: int) -> np.ndarray:
    """values (P, V², C) → (N, C): the 3 located points × the 4 view bins, weights multiplied."""
    if values.shape[:2] != (grid.point_count, view_bins * view_bins):
        raise ValueError(f"values must be (points, {view_bins}², C), not {values.shape}")
    ids, wl = locate(grid, tri, bu, bv)
    bins, wv = bin_weights(wo, view_bins)
    return np.einsum("na,nb,nabc->nc", wl, wv, values[ids[:, :, None], bins[:, None, :]])


def playback_direction(grid: BakeGrid, light_dir: np.ndarray, tri, bu, bv) -> np.ndarray:
    """light_dir (P, 3) unit directions → (N, 3) float64: the 3 located points' blend, made
    unit (the module docstring's rule)."""
    if light_dir.shape != (grid.point_count, 3):
        raise ValueError(f"light_dir must be (points, 3), not {light_dir.shape}")
    ids, wl = locate(grid, tri, bu, bv)
    blend = np.einsum("na,nac->nc", wl, light_dir[ids].astype(np.float64))
    length = np.linalg.norm(blend, axis=1, keepdims=True)
    ok = np.isfinite(length) & (length > 1e-6)
    return np.where(ok, blend / np.where(ok, length, 1.0), (0.0, 0.0, 1.0))


def pack_values(ratio: np.ndarray, light_dir: np.ndarray) -> np.ndarray:
    """(P, V², 3) values and (P, 3) light directions → (P, V² + 1, 4) float32, as the GPU code
    reads a bake (kernels/include/btf_bake.h, shaders/bake_lib.glsl); one zero point for none
    (a buffer is never empty)."""
    points, bins = ratio.shape[:2]
    if light_dir.shape != (points, 3):
        raise ValueError(f"light_dir must be ({points}, 3), not {light_dir.shape}")
    out = np.zeros((max(points, 1), bins + 1, 4), np.float32)
    out[:points, :bins, :3] = ratio
    out[:points, bins, :3] = light_dir
    return out
