"""The inverse of a 4 × 4 matrix without LAPACK, for the per-frame paths (the viewport, the VR
eyes, the bridge).

``numpy.linalg.inv`` of a 4 × 4 costs 2–6 µs in a plain process, but 160–580 µs once a
threaded OpenGL driver (Mesa llvmpipe in background Blender) runs beside OpenBLAS's threads:
five of them per VR eye were more than the eye's whole budget outside drawing. This closed
form (cofactors, in Python floats) takes about 10 µs anywhere and agrees with LAPACK to
rounding (tests/core/test_mat4.py)."""

from __future__ import annotations

import numpy as np


def inverse(matrix) -> np.ndarray:
    """The inverse of a 4 × 4 matrix, float64. A singular matrix raises
    ``numpy.linalg.LinAlgError`` as ``numpy.linalg.inv`` does; so does one holding NaN (whose
    inverse LAPACK would fill with NaN)."""
    (a, b, c, d), (e, f, g, h), (i, j, k, l_), (m, n, o, p) = np.asarray(
        matrix, dtype=np.float64
    ).tolist()
    s0, s1, s2 = a * f - e * b, a * g - e * c, a * h - e * d
    s3, s4, s5 = b * g - f * c, b * h - f * d, c * h - g * d
    c5, c4, c3 = k * p - o * l_, j * p - n * l_, j * o - n * k
    c2, c1, c0 = i * p - m * l_, i * o - m * k, i * n - m * j
    det = s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0
    if det == 0.0 or det != det:
        raise np.linalg.LinAlgError("Singular matrix")
    r = 1.0 / det
    return np.array(
        [
            [
                (f * c5 - g * c4 + h * c3) * r,
                (-b * c5 + c * c4 - d * c3) * r,
                (n * s5 - o * s4 + p * s3) * r,
                (-j * s5 + k * s4 - l_ * s3) * r,
            ],
            [
                (-e * c5 + g * c2 - h * c1) * r,
                (a * c5 - c * c2 + d * c1) * r,
                (-m * s5 + o * s2 - p * s1) * r,
                (i * s5 - k * s2 + l_ * s1) * r,
            ],
            [
                (e * c4 - f * c2 + h * c0) * r,
                (-a * c4 + b * c2 - d * c0) * r,
                (m * s4 - n * s2 + p * s0) * r,
                (-i * s4 + j * s2 - l_ * s0) * r,
            ],
            [
                (-e * c3 + f * c1 - g * c0) * r,
                (a * c3 - b * c1 + c * c0) * r,
                (-m * s3 + n * s1 - o * s0) * r,
                (i * s3 - j * s1 + k * s0) * r,
            ],
        ]
    )
