"""Meshes built in code: the demo scene and the tests use them (no .blend needed)."""

from __future__ import annotations

import numpy as np

from .scene import Mesh
from .tangents import corner_tangents


def _mesh(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, **kw) -> Mesh:
    positions = positions.astype(np.float32)
    normals = normals.astype(np.float32)
    uvs = uvs.astype(np.float32)
    return Mesh(positions, normals, uvs, corner_tangents(positions, normals, uvs), **kw)


def uv_sphere(radius: float = 1.0, segments: int = 48, rings: int = 24, **kw) -> Mesh:
    """A UV sphere with smooth normals; u runs once around (0 at +X), v from bottom to top."""
    u = np.linspace(0.0, 1.0, segments + 1)
    v = np.linspace(0.0, 1.0, rings + 1)
    uu, vv = np.meshgrid(u, v)
    phi, theta = 2 * np.pi * uu, np.pi * (1.0 - vv)
    normals = np.stack(
        [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1
    )
    grid_uv = np.stack([uu, vv], -1)
    corners = []
    for r in range(rings):
        for s in range(segments):
            a, b, c, d = (r, s), (r, s + 1), (r + 1, s + 1), (r + 1, s)
            corners += [a, b, c, a, c, d]
    idx = np.array(corners)
    n = normals[idx[:, 0], idx[:, 1]]
    keep = np.ones(len(idx) // 3, dtype=bool)  # drop triangles collapsed at the poles
    p = (n * radius).reshape(-1, 3, 3)
    keep &= np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1) > 1e-12
    sel = np.repeat(keep, 3)
    return _mesh((n * radius)[sel], n[sel], grid_uv[idx[:, 0], idx[:, 1]][sel], **kw)


def plane(size: float = 2.0, uv_repeats: float = 1.0, **kw) -> Mesh:
    """A square in the XY plane facing +Z, UVs along +X and +Y."""
    h = size / 2
    p = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, -h, 0], [h, h, 0], [-h, h, 0]], float)
    uv = (p[:, :2] / size + 0.5) * uv_repeats
    return _mesh(p, np.tile([0.0, 0.0, 1.0], (6, 1)), uv, **kw)
