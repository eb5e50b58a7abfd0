"""Low-discrepancy points for virtual lights and progressive sampling.

``sobol_2d``: the first two Sobol dimensions (van der Corput in base 2 and the Pascal-matrix
dimension), randomised by a seeded digital shift (XOR). The unshifted first 2^m points form a
(0, m, 2)-net — one point in every elementary interval of area 2^-m — and an XOR shift keeps
that, so every power-of-two prefix is perfectly stratified and every other prefix nearly so.
"""

from __future__ import annotations

import numpy as np

BITS = 32


def _direction_numbers() -> tuple[np.ndarray, np.ndarray]:
    v1 = np.array([1 << (BITS - 1 - j) for j in range(BITS)], dtype=np.uint64)
    v2 = np.empty(BITS, dtype=np.uint64)
    v2[0] = 1 << (BITS - 1)
    for j in range(1, BITS):
        v2[j] = v2[j - 1] ^ (v2[j - 1] >> np.uint64(1))
    return v1, v2


def sobol_2d(n: int, seed: int | None = 0) -> np.ndarray:
    """(n, 2) float64 points in [0, 1). ``seed=None`` gives the unshifted sequence."""
    if n < 0:
        raise ValueError("n must be non-negative")
    v1, v2 = _direction_numbers()
    index = np.arange(n, dtype=np.uint64)
    x1 = np.zeros(n, dtype=np.uint64)
    x2 = np.zeros(n, dtype=np.uint64)
    for j in range(BITS):
        bit = (index >> np.uint64(j)) & np.uint64(1)
        x1 ^= bit * v1[j]
        x2 ^= bit * v2[j]
    if seed is not None:
        shift = np.random.default_rng(seed).integers(0, 1 << BITS, size=2, dtype=np.uint64)
        x1 ^= shift[0]
        x2 ^= shift[1]
    return np.column_stack([x1, x2]).astype(np.float64) / float(1 << BITS)
