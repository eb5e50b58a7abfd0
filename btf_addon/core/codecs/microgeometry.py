"""Microgeometry BTFs: a virtual gonioreflectometer over a height field.

A tile of fine height samples (heights in tile widths) with a spatially varying Lambertian
albedo. A BTF texel's value for (ωi, ωo) is the mean, over a fixed stratified set of points in
the texel, of what a camera looking along −ωo sees there: the view ray is marched through the
periodic height field (masking), and the hit point is lit by ρ/π·max(0, n·ωi) times its light
visibility (self-shadowing, from a horizon map with a narrow soft penumbra so the value stays
continuous in ωi). A flat field reproduces the Lambertian preset exactly.

The procedure evaluates at any direction, so it is its own ground truth when tabulated.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..model import BTF, BTFMeta, Queries, tile_size_from_params, tile_size_param, wrap_texel
from .packed import register_codec

#: Horizon-map azimuth bins; the soft shadow edge width in tan(elevation).
N_AZIMUTH = 32
PENUMBRA_TAN = 0.05
#: Views are marched as if no more grazing than this cos θo (≈ 88.9°), keeping ray lengths finite.
MIN_VIEW_COS = 0.02
SUBSAMPLES = 2  # per axis inside a texel: 4 points


def _bilinear(field: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Periodic bilinear lookup; x, y in fine-sample units. field: (F, F) or (F, F, C)."""
    f = field.shape[0]
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = x - x0
    fy = y - y0
    x0 = x0.astype(np.int64) % f
    y0 = y0.astype(np.int64) % f
    x1 = (x0 + 1) % f
    y1 = (y0 + 1) % f
    if field.ndim == 3:
        fx = fx[:, None]
        fy = fy[:, None]
    top = field[y0, x0] * (1 - fx) + field[y0, x1] * fx
    bottom = field[y1, x0] * (1 - fx) + field[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


class MicrogeometryBTF(BTF):
    def __init__(
        self,
        height: np.ndarray,
        albedo: np.ndarray,
        texels: int,
        name: str,
        tile_size_mm: tuple[float, float] | None = None,
        tile_size_source: str = "synthetic",
    ):
        # Stored as float32, the container's precision, so a saved preset evaluates identically.
        height = np.asarray(height, dtype=np.float32).astype(np.float64)
        albedo = np.asarray(albedo, dtype=np.float32).astype(np.float64)
        f = height.shape[0]
        if height.shape != (f, f) or albedo.shape != (f, f, 3) or f % texels:
            raise ValueError("height (F, F), albedo (F, F, 3) with F a multiple of texels needed")
        self.height = height
        self.albedo = albedo
        self.fine = f
        # Normals from central differences (heights are in tile widths, one step = 1/F tile).
        dx = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) * f / 2.0
        dy = (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) * f / 2.0
        n = np.stack([-dx, -dy, np.ones_like(height)], axis=-1)
        self.normals = n / np.linalg.norm(n, axis=-1, keepdims=True)
        self.horizon = self._horizon_map()
        self.meta = BTFMeta(
            codec="microgeometry",
            name=name,
            width=texels,
            height=texels,
            n_views=0,
            n_lights=0,
            angular_grid="procedural (ray cast)",
            tile_size_mm=tile_size_mm,
            tile_size_source=tile_size_source,
        )

    def _horizon_map(self) -> np.ndarray:
        """(F, F, N_AZIMUTH) tangent of the highest occluder elevation per azimuth.

        Occluders within half a tile, looked up at whole-sample offsets (np.roll): a horizon map
        needs the skyline, not sub-sample precision, and this keeps construction well under 1 s.
        """
        f = self.fine
        horizon = np.full((f, f, N_AZIMUTH), -np.inf)
        for k in range(N_AZIMUTH):
            phi = 2 * np.pi * k / N_AZIMUTH
            for step in range(1, f // 2 + 1):
                ox, oy = round(np.cos(phi) * step), round(np.sin(phi) * step)
                distance = np.hypot(ox, oy) / f
                if distance == 0:
                    continue
                occluder = np.roll(self.height, (-oy, -ox), axis=(0, 1))
                np.maximum(
                    horizon[..., k], (occluder - self.height) / distance, out=horizon[..., k]
                )
        return horizon

    def _march(self, px: np.ndarray, py: np.ndarray, wo: np.ndarray):
        """Rays through macro points (px, py) in fine units along −wo → hit (x, y) fine units."""
        f = self.fine
        cos_o = np.maximum(wo[:, 2], MIN_VIEW_COS)
        sin_o = np.sqrt(np.maximum(1.0 - cos_o * cos_o, 0.0))
        horiz = np.hypot(wo[:, 0], wo[:, 1])
        ux = np.where(horiz > 1e-12, wo[:, 0] / np.maximum(horiz, 1e-12), 0.0)
        uy = np.where(horiz > 1e-12, wo[:, 1] / np.maximum(horiz, 1e-12), 0.0)
        slope = cos_o / np.maximum(sin_o, 1e-12)  # height drop per unit horizontal (tile) travel
        h_max, h_min = self.height.max(), self.height.min()
        # Start above the field where the ray crosses z = h_max; travel in tile units s ≥ 0.
        s0 = -(h_max - 0.0) / slope  # negative: back along the view direction
        travel = (h_max - h_min) / slope + 1e-9
        step = 0.5 / f
        n_steps = int(np.ceil(travel.max() / step)) + 2 if len(px) else 0
        x = px.copy()
        y = py.copy()
        hit = np.zeros(len(px), dtype=bool)
        prev_s = s0.copy()
        prev_gap = np.full(len(px), h_max - h_max + 1e-12)
        for i in range(n_steps + 1):
            s = np.minimum(s0 + i * step, s0 + travel)
            sx = px - ux * s * f
            sy = py - uy * s * f
            z = -s * slope  # z along the ray relative to the z = 0 plane
            gap = z - _bilinear(self.height, sx, sy)
            newly = (~hit) & (gap <= 0)
            if newly.any():
                # Secant step between the last point above and the first below the surface.
                t = prev_gap[newly] / np.maximum(prev_gap[newly] - gap[newly], 1e-12)
                s_hit = prev_s[newly] + t * (s[newly] - prev_s[newly])
                x[newly] = px[newly] - ux[newly] * s_hit * f
                y[newly] = py[newly] - uy[newly] * s_hit * f
                hit |= newly
            prev_s, prev_gap = s, gap
            if hit.all():
                break
        # Rays that never went below (numerically) land where they left the slab.
        x[~hit] = (px - ux * (s0 + travel) * f)[~hit]
        y[~hit] = (py - uy * (s0 + travel) * f)[~hit]
        return x, y

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        f, texels = self.fine, self.meta.width
        tx, ty = wrap_texel(q.uv, texels, texels)
        per_texel = f // texels
        out = np.zeros((len(tx), 3))
        offsets = (np.arange(SUBSAMPLES) + 0.5) / SUBSAMPLES * per_texel
        # March each distinct (texel, view) once: tabulation asks many lights per view.
        key = np.column_stack([tx, ty, q.wo])
        uniq, inverse = np.unique(key, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        u_wo = uniq[:, 2:5]
        for oy in offsets:
            for ox in offsets:
                px = uniq[:, 0] * per_texel + ox
                py = uniq[:, 1] * per_texel + oy
                hx, hy = self._march(px, py, u_wo)
                hx, hy = hx[inverse], hy[inverse]
                out += self._shade(hx, hy, q.wi)
        return out / (SUBSAMPLES * SUBSAMPLES)

    def _shade(self, x: np.ndarray, y: np.ndarray, wi: np.ndarray) -> np.ndarray:
        n = _bilinear(self.normals, x, y)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        albedo = _bilinear(self.albedo, x, y)
        cos = np.maximum(np.sum(n * wi, axis=1), 0.0)
        # Light visibility from the horizon map, linear between azimuth bins.
        light_tan = wi[:, 2] / np.maximum(np.hypot(wi[:, 0], wi[:, 1]), 1e-9)
        az = np.mod(np.arctan2(wi[:, 1], wi[:, 0]), 2 * np.pi) / (2 * np.pi) * N_AZIMUTH
        k0 = np.floor(az).astype(np.int64) % N_AZIMUTH
        w = az - np.floor(az)
        xi = np.round(x).astype(np.int64) % self.fine
        yi = np.round(y).astype(np.int64) % self.fine
        horizon = (
            self.horizon[yi, xi, k0] * (1 - w) + self.horizon[yi, xi, (k0 + 1) % N_AZIMUTH] * w
        )
        visible = np.clip((light_tan - horizon) / PENUMBRA_TAN + 0.5, 0.0, 1.0)
        return albedo / np.pi * (cos * visible)[:, None]

    def tables(self) -> dict[str, np.ndarray]:
        return {"height": self.height.astype(np.float32), "albedo": self.albedo.astype(np.float32)}

    def params(self) -> dict[str, Any]:
        return {
            "texels": self.meta.width,
            "name": self.meta.name,
            "tile_size_mm": tile_size_param(self.meta.tile_size_mm),
            "tile_size_source": self.meta.tile_size_source,
        }

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> MicrogeometryBTF:
        return cls(
            tables["height"],
            tables["albedo"],
            params["texels"],
            params["name"],
            *tile_size_from_params(params, "synthetic"),
        )


def woven(
    texels: int = 16,
    threads: int = 4,
    fine_per_texel: int = 8,
    warp_rgb=(0.75, 0.18, 0.12),
    weft_rgb=(0.85, 0.8, 0.65),
    relief: float = 0.04,
    tile_size_mm: float = 4.0,
) -> MicrogeometryBTF:
    """Plain weave: warp threads along v and weft along u pass over and under each other."""
    f = texels * fine_per_texel
    c = (np.arange(f) + 0.5) / f
    u, v = np.meshgrid(c, c)  # u varies along columns (x), v along rows (y)
    # Across a thread: a rounded profile; along it: up and down once per two crossings.
    across_warp = np.cos(np.pi * ((u * threads) % 1.0 - 0.5))
    across_weft = np.cos(np.pi * ((v * threads) % 1.0 - 0.5))
    parity_warp = np.floor(u * threads) % 2
    parity_weft = np.floor(v * threads) % 2
    warp = relief * (0.5 * across_warp + 0.5 * np.cos(np.pi * (v * threads + parity_warp)))
    weft = relief * (0.5 * across_weft + 0.5 * np.cos(np.pi * (u * threads + parity_weft + 1)))
    height = np.maximum(warp, weft)
    on_top = (warp >= weft)[..., None]
    albedo = np.where(on_top, np.asarray(warp_rgb), np.asarray(weft_rgb))
    # Fibres: a little darker in the valleys between threads.
    albedo = albedo * (0.75 + 0.25 * (height - height.min()) / np.ptp(height))[..., None]
    return MicrogeometryBTF(height, albedo, texels, "woven", (tile_size_mm, tile_size_mm))


def leather(
    texels: int = 16,
    fine_per_texel: int = 8,
    seed: int = 7,
    base_rgb=(0.36, 0.2, 0.11),
    relief: float = 0.03,
    tile_size_mm: float = 6.0,
) -> MicrogeometryBTF:
    """Bumpy leather: periodic Gaussian bumps of random size (seeded), dark creases."""
    rng = np.random.default_rng(seed)
    f = texels * fine_per_texel
    c = (np.arange(f) + 0.5) / f
    u, v = np.meshgrid(c, c)
    height = np.zeros((f, f))
    for _ in range(40):
        cx, cy = rng.random(2)
        r = rng.uniform(0.04, 0.12)
        du = (u - cx + 0.5) % 1.0 - 0.5  # periodic distance: the tile repeats seamlessly
        dv = (v - cy + 0.5) % 1.0 - 0.5
        height = np.maximum(height, np.exp(-(du * du + dv * dv) / (2 * r * r)))
    height = relief * height
    shade = 0.55 + 0.45 * (height - height.min()) / np.ptp(height)
    albedo = np.asarray(base_rgb)[None, None, :] * shade[..., None]
    return MicrogeometryBTF(height, albedo, texels, "leather", (tile_size_mm, tile_size_mm))


register_codec("microgeometry", MicrogeometryBTF)  # numpy only: no device decode
