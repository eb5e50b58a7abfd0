"""Directions and angles in the surface's tangent frame.

Tangent frame: +x along the texture's u axis (tangent), +y along v (bitangent), +z the normal.
Angles: theta from +z, phi = atan2(y, x) counter-clockwise from +x, both in degrees wherever a
name says ``_deg``. BTF queries use the same (theta, phi) numbers as BTFbase's ``GetValDeg``.
"""

from __future__ import annotations

import numpy as np


def directions_from_angles_deg(theta_deg: np.ndarray, phi_deg: np.ndarray) -> np.ndarray:
    """(N,) theta, phi in degrees → (N, 3) float64 unit vectors."""
    theta = np.radians(np.asarray(theta_deg, dtype=np.float64))
    phi = np.radians(np.asarray(phi_deg, dtype=np.float64))
    sin_t = np.sin(theta)
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), np.cos(theta)], axis=-1)


def angles_deg_from_directions(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) unit vectors → theta in [0, 180], phi in [0, 360) degrees (float64)."""
    d = np.asarray(d, dtype=np.float64)
    theta = np.degrees(np.arccos(np.clip(d[..., 2], -1.0, 1.0)))
    phi = np.degrees(np.arctan2(d[..., 1], d[..., 0])) % 360.0
    return theta, phi


def normalize_directions(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) → (unit vectors, valid mask).

    Rows with NaN/Inf components or (near) zero length are invalid: they come back as +z with
    ``valid`` False, so callers can zero their results without any warning being raised.
    """
    d = np.asarray(d, dtype=np.float64)
    finite = np.all(np.isfinite(d), axis=-1)
    safe = np.where(finite[..., None], d, 0.0)
    length = np.sqrt(np.sum(safe * safe, axis=-1))
    valid = finite & (length > 1e-12)
    unit = np.where(valid[..., None], safe / np.where(valid, length, 1.0)[..., None], [0, 0, 1])
    return unit, valid
