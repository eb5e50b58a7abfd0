"""The film's pixel filter, as Blender Cycles defines it (``scene.cycles.pixel_filter_type`` and
``filter_width``; Cycles ``scene/film.cpp``), and its importance sampling.

A pixel's value is the image convolved with the filter, f(x)·f(y) (separable), over the
pixel's footprint. Each sample's position is drawn with the filter's own distribution, so every
sample has the same weight and the mean converges to the filtered image at no extra cost per
sample (Cycles does the same from a tabulated inverse CDF). The 1D profiles, ``v`` = distance
from the pixel centre in pixels, ``w`` = the filter width:

- BOX: 1 on |v| ≤ w/2;
- GAUSSIAN: exp(−8 v²/w²) (σ = w/4) on |v| ≤ 1.5 w (Cycles: its table spans 3 w);
- BLACKMAN_HARRIS: the 4-term window over |v| ≤ w (Cycles: its table spans 2 w), 1 at the
  centre, 6e−5 at the edge.

The kernels read the inverse CDF as a table made here (``PixelFilter.table``, looked up in
``kernels/include/btf_filter.h``, as Cycles does); this module also gives the viewport's
per-pass jitter and the Virtual Lights mode's subpixel positions (``subpixel_offsets``): the
same low-discrepancy points (R2), so a converged viewport and an F12 with as many subpixels
see the same footprint.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np


class FilterType(enum.Enum):
    """Named as Cycles' ``pixel_filter_type`` identifiers; the values are the kernels'."""

    BOX = 0
    GAUSSIAN = 1
    BLACKMAN_HARRIS = 2


# Blackman-Harris window coefficients (Cycles' filter_func_blackman_harris).
BH = (0.35875, 0.48829, 0.14128, 0.01168)
BISECTION_STEPS = 24  # 2^-24 of the radius: far below a float pixel coordinate's precision
FILTER_TABLE_SIZE = 1025  # entries of the kernels' inverse-CDF table (btf_filter.h)


@dataclass(frozen=True)
class PixelFilter:
    """``type`` as Cycles' identifier, ``width`` in pixels (Blender's default: Blackman-Harris
    1.5 px). A width of 0 (or below Cycles' 0.01 minimum) is a point: the pixel centre."""

    type: str = FilterType.BLACKMAN_HARRIS.name
    width: float = 1.5

    def __post_init__(self) -> None:
        if self.type not in FilterType.__members__:
            raise ValueError(
                f"pixel filter {self.type!r}: expected one of {', '.join(FilterType.__members__)}"
            )
        if not (math.isfinite(self.width) and self.width >= 0.0):
            raise ValueError(f"filter width {self.width!r}: expected a width ≥ 0 pixels")

    @property
    def kind(self) -> FilterType:
        return FilterType[self.type]

    @property
    def radius(self) -> float:
        """Half the support in pixels: no sample lands farther than this from the centre."""
        scale = {FilterType.BOX: 0.5, FilterType.GAUSSIAN: 1.5, FilterType.BLACKMAN_HARRIS: 1.0}
        return scale[self.kind] * self.width

    def profile(self, v: np.ndarray) -> np.ndarray:
        """The 1D filter at distances ``v`` (any shape, pixels), 0 outside the support; peak 1."""
        v = np.abs(np.asarray(v, dtype=np.float64))
        w = max(self.width, 1e-12)
        if self.kind is FilterType.BOX:
            f = np.ones_like(v)
        elif self.kind is FilterType.GAUSSIAN:
            f = np.exp(-8.0 * v**2 / w**2)
        else:
            t = 2.0 * np.pi * (v / (2.0 * w) + 0.5)
            f = BH[0] - BH[1] * np.cos(t) + BH[2] * np.cos(2 * t) - BH[3] * np.cos(3 * t)
        return np.where(v <= self.radius, f, 0.0)

    def cdf(self, x: np.ndarray) -> np.ndarray:
        """∫₀ˣ profile, for 0 ≤ x ≤ radius (closed forms, as in btf_filter.h)."""
        x = np.asarray(x, dtype=np.float64)
        w = max(self.width, 1e-12)
        if self.kind is FilterType.BOX:
            return x
        if self.kind is FilterType.GAUSSIAN:
            k = math.sqrt(8.0) / w
            erf = np.vectorize(math.erf, otypes=[np.float64])
            return math.sqrt(math.pi) / (2.0 * k) * erf(k * x)
        t = 2.0 * np.pi * (x / (2.0 * w) + 0.5)  # sin(kπ) = 0 at x = 0 for k = 1, 2, 3
        return BH[0] * x - (w / np.pi) * (
            BH[1] * np.sin(t) - BH[2] / 2 * np.sin(2 * t) + BH[3] / 3 * np.sin(3 * t)
        )

    def sample(self, u: np.ndarray) -> np.ndarray:
        """Offsets from the pixel centre (pixels) for uniform ``u`` in [0, 1) (any shape),
        distributed as the normalised profile; monotone in ``u`` (u = 0.5 → 0), so stratified
        ``u`` give stratified offsets."""
        u = np.asarray(u, dtype=np.float64)
        r = self.radius
        if r <= 0.0:
            return np.zeros_like(u)
        sign = np.where(u < 0.5, -1.0, 1.0)
        target = np.abs(2.0 * u - 1.0) * self.cdf(r)
        lo, hi = np.zeros_like(u), np.full_like(u, r)
        for _ in range(BISECTION_STEPS):
            mid = 0.5 * (lo + hi)
            below = self.cdf(mid) < target
            lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        return sign * 0.5 * (lo + hi)

    def table(self, size: int = FILTER_TABLE_SIZE) -> np.ndarray:
        """(size,) float32 inverse CDF of the half profile: entry i is the offset (pixels)
        below which i / (size − 1) of its mass lies (0 … radius); the kernels' lookup
        (kernels/include/btf_filter.h), as Cycles' filter table."""
        u = 0.5 + 0.5 * np.linspace(0.0, 1.0, size)
        table = self.sample(np.minimum(u, 1.0 - 1e-12))
        # The last cell holds the tail out to the support's end, where the CDF is flat: spread
        # linearly to the radius it would put its 1/(size − 1) of the samples far out (Cycles'
        # table does). Through its median instead, they stay where the tail's mass is.
        median = float(self.sample(0.5 + 0.5 * (1.0 - 0.5 / (size - 1))))
        table[-1] = min(table[-1], 2.0 * median - table[-2])
        return table.astype(np.float32)


# The R2 sequence's steps (Roberts 2018): 1/φ₂ and 1/φ₂², φ₂ the plastic number.
R2_STEP = (0.7548776662466927, 0.5698402909980532)


def r2_points(count: int) -> np.ndarray:
    """(count, 2) float64: the R2 low-discrepancy sequence started at (½, ½). Every prefix is
    evenly spread (not only powers of two, which a progressive viewport needs: its pass count is
    anything), and point 0, once mapped through ``PixelFilter.sample``, is the pixel centre."""
    return r2_at(np.arange(count))


def r2_at(indices: np.ndarray) -> np.ndarray:
    """(M, 2) float64: points ``indices`` of ``r2_points``' sequence."""
    i = np.asarray(indices, dtype=np.float64).reshape(-1, 1)
    return np.mod(0.5 + i * np.array(R2_STEP), 1.0)


def subpixel_offsets(pixel_filter: PixelFilter | None, count: int) -> np.ndarray:
    """(count, 2) float32 offsets from the pixel centre in pixels (x right, y down): the
    Virtual Lights mode's subpixel positions and the viewport's jitter per pass. Offset 0 is the
    centre; without a filter every offset is the centre."""
    count = max(int(count), 1)
    if pixel_filter is None:
        return np.zeros((count, 2), np.float32)
    return pixel_filter.sample(r2_points(count)).astype(np.float32)


@lru_cache(maxsize=4096)
def subpixel_offset(pixel_filter: PixelFilter | None, index: int) -> tuple[float, float]:
    """Offset ``index`` of ``subpixel_offsets`` alone (the viewport's jitter of one pass).
    Remembered: every pass of every view (each VR eye, every frame) asks for one, and the
    inversion by bisection costs a quarter of a millisecond, more than the rest of a pass's
    host work."""
    if pixel_filter is None:
        return (0.0, 0.0)
    dx, dy = pixel_filter.sample(r2_at([index]))[0]
    return (float(dx), float(dy))
