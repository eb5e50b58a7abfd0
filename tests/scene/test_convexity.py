"""scene/analysis.py is_convex: the float32 block product against the definition in float64.

The definition (module docstring of scene/analysis.py): no vertex more than ``tolerance`` × the
mesh's size in front of any face's plane. The reference below evaluates it directly, every
vertex against every plane in float64, so the fast path's rounding and blocking are what the
tests check, on meshes placed far from the origin too (float32 would lose the tolerance there
without the centring)."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.scene import analysis
from btf_addon.scene.analysis import is_convex


def _reference(corners: np.ndarray, tolerance: float = 1e-4) -> bool:
    p = corners[:, :3].astype(np.float64).reshape(-1, 3, 3)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(n, axis=1)
    keep = length > 1e-20
    n, o = n[keep] / length[keep, None], p[keep, 0]
    points = p.reshape(-1, 3)
    scale = np.ptp(points, axis=0).max()
    side = points @ n.T - np.sum(n * o, axis=1)
    return bool(side.max() <= tolerance * scale)


def _uv_sphere(segments=24, rings=12, bump=None):
    """Triangle corners (3·T, 3) of a closed UV sphere of radius 1, outward-facing;
    ``bump`` = (vertex index, radial offset) moves one vertex."""
    verts = [(0.0, 0.0, 1.0)]
    for r in range(1, rings):
        th = np.pi * r / rings
        for s in range(segments):
            ph = 2 * np.pi * s / segments
            verts.append((np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)))
    verts.append((0.0, 0.0, -1.0))
    v = np.array(verts)
    if bump is not None:
        i, dr = bump
        v[i] *= 1 + dr
    ring = lambda r, s: 1 + (r - 1) * segments + s % segments  # noqa: E731
    tris = []
    for s in range(segments):
        tris.append((0, ring(1, s), ring(1, s + 1)))
        tris.append((len(v) - 1, ring(rings - 1, s + 1), ring(rings - 1, s)))
        for r in range(1, rings - 1):
            a, b = ring(r, s), ring(r, s + 1)
            c, d = ring(r + 1, s), ring(r + 1, s + 1)
            tris += [(a, c, d), (a, d, b)]
    return v[np.array(tris)].reshape(-1, 3)


def _moved(corners, offset):
    return corners + np.asarray(offset, dtype=np.float64)


TETRAHEDRON = np.array(
    [[0, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 0], [1, 0, 0], [0, 0, 1],
     [0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
    dtype=np.float64,
)  # fmt: skip

MESHES = {
    "sphere": _uv_sphere(),
    "sphere 10 km from the origin": _moved(_uv_sphere(), [1e4, -2e4, 5e3]),
    "sphere, a vertex 2e-3 inwards": _uv_sphere(bump=(40, -2e-3)),
    "sphere, a vertex 2e-5 inwards (within the tolerance)": _uv_sphere(bump=(40, -2e-5)),
    "sphere far away, a vertex 2e-3 inwards": _moved(_uv_sphere(bump=(40, -2e-3)), [1e4, 0, 0]),
    "tetrahedron": TETRAHEDRON,
    "two spheres": np.concatenate([_uv_sphere(), _moved(_uv_sphere(), [3, 0, 0])]),
    "sphere with degenerate triangles": np.concatenate([_uv_sphere(), np.zeros((6, 3))]),
}


@pytest.mark.parametrize("name", MESHES)
@pytest.mark.parametrize("block", [analysis.CONVEXITY_BLOCK, 1000])
def test_is_convex_agrees_with_the_float64_definition(name, block, monkeypatch):
    monkeypatch.setattr(analysis, "CONVEXITY_BLOCK", block)  # many blocks, and one
    corners = MESHES[name]
    assert is_convex(corners) == _reference(corners)


def test_the_cases_go_both_ways():
    """The parametrised agreement is only worth something if the meshes span both answers."""
    answers = {name: _reference(corners) for name, corners in MESHES.items()}
    assert answers["sphere 10 km from the origin"] and answers["tetrahedron"]
    assert answers["sphere, a vertex 2e-5 inwards (within the tolerance)"]
    assert not answers["sphere, a vertex 2e-3 inwards"]
    assert not answers["sphere far away, a vertex 2e-3 inwards"]
    assert not answers["two spheres"]


def test_an_empty_mesh_is_convex():
    assert is_convex(np.zeros((0, 3)))
