"""Dense (tabulated) BTFs: values stored per (view sample, light sample, texel).

data: (n_views, n_lights, height, width, 3) float32 in the value convention, on one RingGrid
for views and one for lights (UBO2003 81×81 by default). Evaluation: nearest texel (wraps),
ring-bilinear interpolation (core/grid.py) in view and in light: 16 weighted samples.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import BTFFormatError
from ..grid import UBO2003, RingGrid
from ..model import (
    BTF,
    CHUNK,
    BTFMeta,
    Queries,
    tile_size_from_params,
    tile_size_param,
    wrap_texel,
)
from .packed import TableWriter, register_codec


class DenseBTF(BTF):
    def __init__(
        self,
        data: np.ndarray,
        view_grid: RingGrid = UBO2003,
        light_grid: RingGrid = UBO2003,
        name: str = "dense",
        tile_size_mm: tuple[float, float] | None = None,
        tile_size_source: str = "unknown",
    ):
        data = np.asarray(data, dtype=np.float32)
        expected = (view_grid.size, light_grid.size)
        if data.ndim != 5 or data.shape[:2] != expected or data.shape[4] != 3:
            raise BTFFormatError(
                f"dense BTF {name!r}: data shape {data.shape}, expected {expected} + (h, w, 3)"
            )
        if not np.all(np.isfinite(data)) or data.min() < 0:
            raise BTFFormatError(f"dense BTF {name!r}: values must be finite and non-negative")
        self.data = data
        self.view_grid = view_grid
        self.light_grid = light_grid
        self.meta = BTFMeta(
            codec="dense",
            name=name,
            width=data.shape[3],
            height=data.shape[2],
            n_views=view_grid.size,
            n_lights=light_grid.size,
            angular_grid=f"rings view {view_grid.size} x light {light_grid.size}",
            tile_size_mm=tile_size_mm,
            tile_size_source=tile_size_source,
        )

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        x, y = wrap_texel(q.uv, self.meta.width, self.meta.height)
        vi, vw = self.view_grid.weights(q.theta_v, q.phi_v)
        _, view_phi = self.view_grid.angles_deg()
        out = np.zeros((len(x), 3))
        for a in range(4):
            # Azimuth-aligned: for the view sample at φa, read the light at φi − φv + φa, i.e.
            # the same light azimuth relative to the view. Exact for isotropic reflectance under
            # rotation, it keeps specular lobes sharp where independent blending would smear
            # two displaced copies of a lobe (docs/accuracy.md has the numbers).
            light_phi = q.phi_i - q.phi_v + view_phi[vi[:, a]]
            li, lw = self.light_grid.weights(q.theta_i, light_phi)
            for b in range(4):
                out += (vw[:, a] * lw[:, b])[:, None] * self.data[vi[:, a], li[:, b], y, x]
        # Past the last measured light ring: fade with the cosine that the values contain.
        t_max = self.light_grid.theta_max_deg
        fade = np.where(
            q.theta_i > t_max, np.cos(np.radians(q.theta_i)) / np.cos(np.radians(t_max)), 1.0
        )
        return out * fade[:, None]

    def tables(self) -> dict[str, np.ndarray]:
        return {"data": self.data}

    def params(self) -> dict[str, Any]:
        return {
            "view_grid": [list(self.view_grid.theta_deg), list(self.view_grid.counts)],
            "light_grid": [list(self.light_grid.theta_deg), list(self.light_grid.counts)],
            "name": self.meta.name,
            "tile_size_mm": tile_size_param(self.meta.tile_size_mm),
            "tile_size_source": self.meta.tile_size_source,
        }

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> DenseBTF:
        vg = RingGrid(tuple(params["view_grid"][0]), tuple(params["view_grid"][1]))
        lg = RingGrid(tuple(params["light_grid"][0]), tuple(params["light_grid"][1]))
        size, source = tile_size_from_params(params, "stated by the source")
        return cls(tables["data"], vg, lg, params["name"], size, source)


def tabulate(
    btf: BTF,
    view_grid: RingGrid = UBO2003,
    light_grid: RingGrid = UBO2003,
    width: int | None = None,
    height: int | None = None,
) -> DenseBTF:
    """Sample any BTF at the grid directions and texel centres → a DenseBTF."""
    width = width or btf.meta.width
    height = height or btf.meta.height
    v_dirs = view_grid.directions()
    l_dirs = light_grid.directions()
    ys, xs = np.meshgrid(
        (np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij"
    )
    uv = np.column_stack([xs.ravel(), ys.ravel()])
    data = np.empty((len(v_dirs), len(l_dirs), height, width, 3), dtype=np.float32)
    n_tex = len(uv)
    # Lights in blocks of about CHUNK query rows: the working set stays bounded whatever the
    # grid (the same evaluations as one call per view, so the same values).
    step = max(1, CHUNK // n_tex)
    for v, wo in enumerate(v_dirs):
        for first in range(0, len(l_dirs), step):
            block = l_dirs[first : first + step]
            wi = np.repeat(block, n_tex, axis=0)
            values = btf.evaluate(np.tile(uv, (len(block), 1)), wi, np.broadcast_to(wo, wi.shape))
            data[v, first : first + len(block)] = values.reshape(len(block), height, width, 3)
    return DenseBTF(
        data,
        view_grid,
        light_grid,
        name=f"{btf.meta.name} (tabulated)",
        tile_size_mm=btf.meta.tile_size_mm,
        tile_size_source=btf.meta.tile_size_source,
    )


def _pack(btf: DenseBTF, out: TableWriter) -> None:
    """GPU tables (core/codecs/packed.py; read by dense_evaluate in kernels/include/btf_packed.h and
    shaders/btf_dense_lib.glsl)."""
    out.set(width=btf.meta.width, height=btf.meta.height, n_lights=btf.light_grid.size)
    out.set(f_data=out.float_table(btf.data))
    for prefix, grid in (("view", btf.view_grid), ("light", btf.light_grid)):
        out.set(
            **{
                f"n_{prefix}_rings": len(grid.counts),
                f"f_{prefix}_theta": out.float_table(np.asarray(grid.theta_deg)),
                f"{prefix}_offsets": out.int_table(np.concatenate([[0], np.cumsum(grid.counts)])),
            }
        )


register_codec("dense", DenseBTF, 4, _pack)
