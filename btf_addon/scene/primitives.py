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


def cube(size: float = 2.0, **kw) -> Mesh:
    """A flat-shaded cube centred on the origin, unwrapped as Blender's default cube is: each
    face a quarter-wide square of a cross in the UV square (so one UV tile spans 4 faces)."""
    h = size / 2
    offsets = ((0.375, 0.0), (0.375, 0.25), (0.375, 0.5), (0.375, 0.75), (0.125, 0.5), (0.625, 0.5))
    axes = np.eye(3)
    faces = []  # (normal, u direction, v direction) with u × v = normal
    for a in range(3):
        for s in (1.0, -1.0):
            n = s * axes[a]
            u = axes[(a + 1) % 3] * s
            faces.append((n, u, np.cross(n, u)))
    p, nrm, uv = [], [], []
    corners = ((-1, -1), (1, -1), (1, 1), (-1, -1), (1, 1), (-1, 1))  # two triangles
    for (n, u, v), (ou, ov) in zip(faces, offsets, strict=True):
        for x, y in corners:
            p.append(h * (n + x * u + y * v))
            nrm.append(n)
            uv.append((ou + (x + 1) / 2 * 0.25, ov + (y + 1) / 2 * 0.25))
    return _mesh(np.array(p), np.array(nrm), np.array(uv), **kw)
