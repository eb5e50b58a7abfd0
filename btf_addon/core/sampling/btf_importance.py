"""Importance sampling of measured BTFs: a tabulated distribution of incoming directions per
view bin, built from the codec's own values, and the maps it is defined over.

Directions live on a square: s ∈ [0, 1]² → the unit disk by Shirley and Chiu's concentric map
(area-preserving up to the factor π) → the hemisphere by Malley's projection
(x, y, √(1 − x² − y²)). A uniform point of the square is therefore cosine-distributed, and a
density D(s) on the square (∫ D ds = 1) is the solid-angle pdf

    pdf(ωi | ωo) = D(s(ωi)) · cos θi / π.

D is piecewise constant on GRID × GRID cells of the square, one table per view bin (VIEWS ×
VIEWS cells of the same map, nearest bin: the bin of ωo's own square point). In a cell, the
ideal D for an integrand value(ωi) · L is ∝ ∫cell value dω / ∫cell cos θi dω (the value
convention already holds the cosine: value = BRDF · cos θi), averaged over a stratified subset
of texels, each texel at its own jittered point of the cell (the texel average and the cell
integral in one pass of evaluations). Mixed with the uniform square (= cosine sampling) at the
fixed DEFENSIVE fraction, so the pdf is never 0 where cos θi > 0 and value / pdf stays bounded
by π · BRDF / DEFENSIVE where the table misses a lobe.

Device layout (``packed()``, appended to the material's float stream at H_F_IMPORTANCE; read by
kernels/include/btf_sampling.h): per view bin, in order, its GRID² densities (row-major, row =
cell of s.y), the GRID + 1 marginal CDF over rows, then each row's GRID + 1 conditional CDF.
"""

from __future__ import annotations

import math
import sys
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..model import BTF, innermost
from . import table_cache
from .envmap import LUMINANCE

GRID = 24  # cells per side of the incoming-direction square (576 cells)
VIEWS = 7  # view bins per side (odd: one bin is centred on the normal view)
TEXELS = 9  # texels averaged (3 × 3 stratified over the texture)
DEFENSIVE = 0.25  # fraction of cosine (uniform square) sampling in the mixture
#: codecs sampled by the table (the analytic ones have their own lobe sampling)
MEASURED_CODECS = ("mlvq", "dense", "svd")


def sampled_by_table(btf: BTF) -> bool:
    """Whether ``btf``'s codec (under any device wrapper) is sampled by a table."""
    return innermost(btf).meta.codec in MEASURED_CODECS


def square_to_disk(s: np.ndarray) -> np.ndarray:
    """(N, 2) points of [0, 1]² → (N, 2) points of the unit disk (concentric map)."""
    a = 2.0 * np.asarray(s, dtype=np.float64)[:, 0] - 1.0
    b = 2.0 * np.asarray(s, dtype=np.float64)[:, 1] - 1.0
    first = np.abs(a) > np.abs(b)
    r = np.where(first, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(first, math.pi / 4 * b / a, math.pi / 2 - math.pi / 4 * np.nan_to_num(a / b))
    phi = np.where(r == 0.0, 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)


def disk_to_square(d: np.ndarray) -> np.ndarray:
    """(N, 2) points of the unit disk → (N, 2) points of [0, 1]² (the inverse of
    ``square_to_disk``)."""
    x, y = np.asarray(d, dtype=np.float64)[:, 0], np.asarray(d, dtype=np.float64)[:, 1]
    r = np.hypot(x, y)
    first = np.abs(x) > np.abs(y)
    a1 = np.sign(x) * r
    b1 = a1 * (4 / math.pi) * np.arctan2(y * np.sign(x), np.abs(x))
    b2 = np.sign(y) * r
    a2 = b2 * (4 / math.pi) * np.arctan2(x * np.sign(y), np.abs(y))
    a, b = np.where(first, a1, a2), np.where(first, b1, b2)
    return np.clip(np.stack([(a + 1.0) / 2.0, (b + 1.0) / 2.0], axis=-1), 0.0, 1.0)


def square_to_hemisphere(s: np.ndarray) -> np.ndarray:
    """(N, 2) points of [0, 1]² → (N, 3) unit directions, z ≥ 0 (cosine-distributed for
    uniform s)."""
    d = square_to_disk(s)
    z = np.sqrt(np.maximum(1.0 - np.sum(d * d, axis=-1), 0.0))
    return np.concatenate([d, z[:, None]], axis=-1)


def hemisphere_to_square(w: np.ndarray) -> np.ndarray:
    """(N, 3) directions (z > 0, need not be unit) → (N, 2) points of [0, 1]²."""
    w = np.asarray(w, dtype=np.float64)
    w = w / np.linalg.norm(w, axis=-1, keepdims=True)
    return disk_to_square(w[:, :2])


@dataclass
class ImportanceTable:
    """density: (views², grid, grid) float32, the density on the square per view bin (mean 1
    over a bin's cells, ≥ defensive); build_seconds: the build's wall time."""

    density: np.ndarray
    grid: int
    views: int
    defensive: float
    build_seconds: float = 0.0

    def view_bin(self, wo: np.ndarray) -> np.ndarray:
        """(N, 3) view directions → (N,) int view-bin index."""
        s = hemisphere_to_square(wo)
        cell = np.minimum((s * self.views).astype(int), self.views - 1)
        return cell[:, 1] * self.views + cell[:, 0]

    def pdf(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """(N, 3) wi, wo in the tangent frame → (N,) solid-angle pdf of sampling wi (0 below
        the horizon): the numpy reference of the kernel's ``bsdf_pdf``."""
        wi = np.asarray(wi, dtype=np.float64)
        wi = wi / np.linalg.norm(wi, axis=-1, keepdims=True)
        cell = np.minimum((hemisphere_to_square(wi) * self.grid).astype(int), self.grid - 1)
        d = self.density[self.view_bin(wo), cell[:, 1], cell[:, 0]]
        return np.where(wi[:, 2] > 0.0, d * np.maximum(wi[:, 2], 0.0) / math.pi, 0.0)

    def packed(self) -> np.ndarray:
        """The device layout (module docstring), flat float32."""
        g = self.grid
        cell = self.density.astype(np.float64) / (g * g)  # probability per cell
        rows = cell.sum(axis=2)  # (views², g)
        row_cdf = np.concatenate([np.zeros((len(cell), 1)), np.cumsum(rows, axis=1)], axis=1)
        row_cdf /= row_cdf[:, -1:]
        col = np.cumsum(cell, axis=2) / np.maximum(rows[:, :, None], 1e-300)
        col_cdf = np.concatenate([np.zeros((*cell.shape[:2], 1)), col], axis=2)
        row_cdf[:, -1] = col_cdf[:, :, -1] = 1.0  # exact ends: a draw never runs past them
        blocks = [self.density.reshape(len(cell), -1), row_cdf, col_cdf.reshape(len(cell), -1)]
        return np.concatenate(blocks, axis=1).astype(np.float32).ravel()

    @property
    def floats_per_view(self) -> int:
        return 2 * self.grid * self.grid + 2 * self.grid + 1

    @property
    def nbytes(self) -> int:
        """Bytes the device layout takes."""
        return 4 * self.views * self.views * self.floats_per_view


def build(
    btf: BTF,
    grid: int = GRID,
    views: int = VIEWS,
    texels: int = TEXELS,
    defensive: float = DEFENSIVE,
    seed: int = 0,
    uv: np.ndarray | None = None,
) -> ImportanceTable:
    """The table of ``btf`` (any codec: it is evaluated through ``BTF.evaluate``, views² ·
    grid² · texels evaluations). ``texels`` is rounded down to a square k × k stratified over
    the texture (k ≥ 1); ``uv``: (T, 2) texture coordinates to average instead (a cluster's
    texels)."""
    t0 = time.perf_counter()
    btf = innermost(btf)  # the numpy codec under a device wrapper
    rng = np.random.default_rng(seed)
    k = max(math.isqrt(max(texels, 1)), 1)
    strata = (np.stack(np.meshgrid(np.arange(k), np.arange(k)), -1).reshape(-1, 2) + 0.5) / k
    if uv is None:
        uv = strata + rng.uniform(-0.5, 0.5, strata.shape) / k  # (T, 2) jittered texels
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    n_t, n_c = len(uv), grid * grid
    cells = np.stack(np.meshgrid(np.arange(grid), np.arange(grid)), -1).reshape(-1, 2)  # (col, row)
    view_centres = np.stack(np.meshgrid(np.arange(views), np.arange(views)), -1).reshape(-1, 2)
    wo_bins = square_to_hemisphere((view_centres + 0.5) / views)
    density = np.empty((views * views, grid, grid), dtype=np.float64)
    for v, wo in enumerate(wo_bins):
        # each texel at its own jittered point of every cell: (T, C) queries
        s = (cells[None, :, :] + rng.uniform(size=(n_t, n_c, 2))) / grid
        wi = square_to_hemisphere(s.reshape(-1, 2))
        values = btf.evaluate(
            np.repeat(uv, n_c, axis=0), wi, np.broadcast_to(wo, wi.shape)
        ).reshape(n_t, n_c, 3)
        lum = np.maximum(values.astype(np.float64) @ LUMINANCE, 0.0).mean(axis=0)
        cos = np.maximum(wi[:, 2].reshape(n_t, n_c), 1e-9).mean(axis=0)
        brdf = lum / cos  # ∫cell value dω / ∫cell cos dω, up to the same constant
        mean = brdf.mean()
        q = brdf / mean if mean > 0.0 and np.isfinite(mean) else np.ones_like(brdf)
        density[v] = ((1.0 - defensive) * q + defensive).reshape(grid, grid)
    return ImportanceTable(
        density.astype(np.float32), grid, views, defensive, time.perf_counter() - t0
    )


_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def importance_table(
    btf: BTF, content: Callable[[], list[np.ndarray]] | None = None
) -> ImportanceTable:
    """``build(btf)`` with the defaults, built once per BTF object: on the first Sampled render
    of a loaded material (0.4–1.6 s on 2 cores); later renders of the session share it.
    ``content``: the material's data as arrays (its packed tables), called only when this
    object has no table yet: the table is then looked up on disk under their digest, and
    stored there once built (table_cache.py), so a new session of the same material skips
    the build."""
    try:
        table = _CACHE.get(btf)
    except TypeError:  # not weak-referenceable: no cache
        return _built_or_stored(btf, content)
    if table is None:
        table = _CACHE[btf] = _built_or_stored(btf, content)
    return table


def _built_or_stored(btf: BTF, content) -> ImportanceTable:
    if content is None:
        return build(btf)
    params = {"grid": GRID, "views": VIEWS, "texels": TEXELS, "defensive": DEFENSIVE, "seed": 0}
    key = table_cache.table_key(content(), params, (sys.modules[__name__], type(innermost(btf))))
    t0 = time.perf_counter()
    density = table_cache.load(key, (VIEWS * VIEWS, GRID, GRID), DEFENSIVE)
    if density is not None:
        return ImportanceTable(density, GRID, VIEWS, DEFENSIVE, time.perf_counter() - t0)
    table = build(btf)
    table_cache.store(key, table.density)
    return table
