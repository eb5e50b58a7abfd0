"""What an encoding costs and what it loses: sizes, ratios, RGB PSNR, SSIM, time.

Ratios follow the original tool's ``quantreport.txt``: raw = 81 × 81 × W × H × 3 bytes (one
8-bit value per channel at every UBO2003 view/light pair). Two compressed sizes:

* ``stored_bytes``: the tables as the ``.btfm`` holds them (int32 / float32);
* ``packed_bytes``: what the original's quantised form would take: each index table at
  ceil(log2(largest index + 1)) bits per entry, each float table at ``scale_bits`` bits (32 when
  scales are not quantised) — its "compressed quantized" figure.

PSNR: RGB, on the 8-bit scale (peak 255), between the input and the encoding evaluated at the
UBO2003 81 × 81 measured directions, at every texel or a fixed, seeded subset of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..codecs.mlvq import FLOAT_TABLES, LDR_VALUE_SCALE
from ..grid import UBO2003, RingGrid
from ..model import BTF
from ..ssim import ssim_map


@dataclass
class SizeReport:
    raw_bytes: int
    stored_bytes: int
    packed_bytes: int

    @property
    def stored_ratio(self) -> float:
        return self.raw_bytes / self.stored_bytes

    @property
    def packed_ratio(self) -> float:
        return self.raw_bytes / self.packed_bytes


def sizes(btf: BTF, scale_bits: int) -> SizeReport:
    """Sizes of an MLVQ encoding (``btf.tables()``) against raw 8-bit data."""
    tables = btf.tables()
    raw = 81 * 81 * btf.meta.width * btf.meta.height * 3
    stored = sum(int(a.nbytes) for a in tables.values())
    bits = 0
    for name, a in tables.items():
        if name in FLOAT_TABLES:
            bits += a.size * (scale_bits or 32)
        else:
            bits += a.size * max(1, math.ceil(math.log2(int(a.max()) + 1)))
    return SizeReport(raw, stored, math.ceil(bits / 8))


def texel_subset(width: int, height: int, most: int, seed: int = 0) -> np.ndarray:
    """Texel indices (row-major) used for PSNR: all when at most ``most`` (0 = all), else a
    seeded sample of ``most``, sorted."""
    n = width * height
    if most <= 0 or n <= most:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, most, replace=False))


def psnr(
    reference: BTF,
    encoded: BTF,
    texels: np.ndarray,
    view_grid: RingGrid = UBO2003,
    light_grid: RingGrid = UBO2003,
) -> float:
    """RGB PSNR in dB (peak 255 on the 8-bit scale) over ``texels`` × every view × light
    direction of the grids; inf when identical."""
    w, h = reference.meta.width, reference.meta.height
    tv, pv = view_grid.angles_deg()
    ti, pi = light_grid.angles_deg()
    n_dir = len(ti)
    uv = np.column_stack([(texels % w + 0.5) / w, (texels // w + 0.5) / h])
    sq = 0.0
    count = 0
    for v in range(len(tv)):
        q = np.empty((len(uv) * n_dir, 6))
        q[:, :2] = np.repeat(uv, n_dir, axis=0)
        q[:, 2] = np.tile(ti, len(uv))
        q[:, 3] = np.tile(pi, len(uv))
        q[:, 4] = tv[v]
        q[:, 5] = pv[v]
        a = reference.evaluate_angles(q).astype(np.float64) / LDR_VALUE_SCALE
        b = encoded.evaluate_angles(q).astype(np.float64) / LDR_VALUE_SCALE
        sq += float(np.sum((a - b) ** 2))
        count += a.size
    mse = sq / count
    return math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def grid_psnr(samples: np.ndarray, decoded: np.ndarray) -> float:
    """RGB PSNR (peak 255) between the input's samples on the MLVQ grid and the encoding's
    values at the same samples (``encoders.mlvq.sample_grid`` / ``_mlvq_grid_values``): the
    quantisation loss alone, without the resampling between the UBO2003 directions and the
    onion-slice grid."""
    mse = float(np.mean((samples.astype(np.float64) - decoded) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def ssim(
    reference: BTF,
    encoded: BTF,
    n_pairs: int = 32,
    crop: int = 64,
    seed: int = 0,
    view_grid: RingGrid = UBO2003,
    light_grid: RingGrid = UBO2003,
) -> float:
    """Similarity (1 = identical) of the texel images per direction: mean SSIM (core/ssim.py:
    the project's one SSIM, Gaussian windows with mirrored edges) over ``n_pairs`` seeded
    view × light pairs of the grids (all when fewer), the R, G and B images on the 8-bit scale
    (peak 255, values above it kept: HDR highlights count), each image the top-left
    ``crop`` × ``crop`` texels (0 = whole tile) at texel centres (a 1-texel image compares
    means only). Measures what PSNR does not: whether the spatial structure of the texture
    survives (blur or blockiness lowers it even at equal mean squared error)."""
    w, h = reference.meta.width, reference.meta.height
    cw, ch = (w, h) if crop <= 0 else (min(w, crop), min(h, crop))
    tv, pv = view_grid.angles_deg()
    ti, pi = light_grid.angles_deg()
    n_all = len(tv) * len(ti)
    pairs = np.arange(n_all)
    if 0 < n_pairs < n_all:
        pairs = np.sort(np.random.default_rng(seed).choice(n_all, n_pairs, replace=False))
    ys, xs = np.mgrid[0:ch, 0:cw]
    uv = np.column_stack([(xs.ravel() + 0.5) / w, (ys.ravel() + 0.5) / h])
    n_t = len(uv)
    v, light = np.divmod(pairs, len(ti))
    q = np.empty((len(pairs) * n_t, 6))
    q[:, :2] = np.tile(uv, (len(pairs), 1))
    for col, values in ((2, ti[light]), (3, pi[light]), (4, tv[v]), (5, pv[v])):
        q[:, col] = np.repeat(values, n_t)
    shape = (len(pairs), ch, cw, 3)
    a = reference.evaluate_angles(q).astype(np.float64).reshape(shape) / LDR_VALUE_SCALE
    b = encoded.evaluate_angles(q).astype(np.float64).reshape(shape) / LDR_VALUE_SCALE

    # SSIM per colour image: the images' rows and columns last.
    s = ssim_map(a.transpose(0, 3, 1, 2), b.transpose(0, 3, 1, 2), peak=255.0)
    return float(np.mean(s))
