"""Tangent frames for meshes that have UVs but no tangents (per corner, MikkTSpace-style sign).

Per triangle: the tangent is the direction of increasing u in the triangle's plane, from the UV
derivatives; the bitangent sign records mirrored UVs (sign −1 where (dP/du × dP/dv) opposes the
normal). Per-corner tangents are Gram–Schmidt orthogonalised against the corner normal.
Degenerate UVs (zero UV area) or degenerate triangles fall back to any unit vector perpendicular
to the normal, so every corner gets a valid, finite frame.
"""

from __future__ import annotations

import numpy as np


def _any_perpendicular(n: np.ndarray) -> np.ndarray:
    helper = np.where(np.abs(n[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    t = np.cross(helper, n)
    return t / np.linalg.norm(t, axis=1, keepdims=True)


def corner_tangents(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """positions, normals: (C, 3); uvs: (C, 2), C = 3 × triangles → (C, 4) float32."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3, 3)
    uv = np.asarray(uvs, dtype=np.float64).reshape(-1, 3, 2)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    dp_du = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv
    dp_dv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv
    face_n = np.cross(e1, e2)
    sign = np.where(np.sum(np.cross(dp_du, dp_dv) * face_n, axis=1) < 0, -1.0, 1.0)
    t = np.repeat(dp_du, 3, axis=0)
    t = t - n * np.sum(t * n, axis=1, keepdims=True)
    length = np.linalg.norm(t, axis=1, keepdims=True)
    good = np.repeat(ok, 3) & (length[:, 0] > 1e-12) & np.all(np.isfinite(t), axis=1)
    t = np.where(good[:, None], t / np.maximum(length, 1e-30), _any_perpendicular(n))
    return np.column_stack([t, np.repeat(sign, 3)]).astype(np.float32)
