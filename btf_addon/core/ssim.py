"""The one structural similarity (SSIM) of the project: Wang, Bovik, Sheikh and Simoncelli 2004,
"Image quality assessment: from error visibility to structural similarity" — a Gaussian window
of σ = 1.5 px (radius 3σ), K1 = 0.01, K2 = 0.03 for the images' dynamic range ``peak``, edges
mirrored (every pixel gets a full window, so small images are not dominated by a border).

Both measures that need one use it: the accuracy report (render/accuracy/ladder.py, on the
displayed luminance, peak 1) and the encoders' report (core/encoders/metrics.py, on texel
images at the 8-bit scale, peak 255). Before there was one, the encoders used 7 × 7 box
windows clipped to the image, so the two "SSIM" numbers of the project did not mean the same.
"""

from __future__ import annotations

import math

import numpy as np

SIGMA = 1.5  # Wang et al. 2004's Gaussian window
K1, K2 = 0.01, 0.03  # their constants, scaled by the dynamic range


def ssim_map(a: np.ndarray, b: np.ndarray, peak: float = 1.0) -> np.ndarray:
    """SSIM per pixel (1 = identical) of two equally shaped stacks of images: the last two
    axes are the image's rows and columns, any leading axes are separate images. float64."""
    x, y = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if x.shape != y.shape or x.ndim < 2:
        raise ValueError(f"SSIM needs two equal stacks of 2D images, got {x.shape} and {y.shape}")
    c1, c2 = (K1 * peak) ** 2, (K2 * peak) ** 2
    mx, my = _blur(x), _blur(y)
    sxx = _blur(x * x) - mx * mx
    syy = _blur(y * y) - my * my
    sxy = _blur(x * y) - mx * my
    return ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))


def _blur(a: np.ndarray) -> np.ndarray:
    """Separable Gaussian over the last two axes with mirrored edges."""
    radius = math.ceil(3 * SIGMA)
    taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / SIGMA) ** 2)
    taps /= taps.sum()
    for axis in (-2, -1):
        n = a.shape[axis]
        index = np.abs(np.arange(-radius, n + radius))  # mirror at 0 …
        index = np.where(index >= n, 2 * (n - 1) - index, index)  # … and at n − 1
        index = np.clip(index, 0, n - 1)  # images narrower than the window
        padded = np.take(a, index, axis=axis)
        out = np.zeros_like(a)
        for i, w in enumerate(taps):
            out += w * np.take(padded, np.arange(i, i + n), axis=axis)
        a = out
    return a
