"""The ``svd`` codec: a BTF stored as one truncated SVD per colour channel (UBO2014's "DFMF").

Per channel c the measurement is a matrix whose rows are direction pairs and whose columns are
texels; the file keeps its first K_c components: ``U_c`` (n_views·n_lights, K_c) and
``SV_c`` (height·width, K_c) = S·V. For a measured pair p and texel t the channel value is

    y_c = Σ_k U_c[p, k] · SV_c[t, k]

and the colour transform turns (y_0, y_1, y_2) into RGB (``colour_transform``: an optional
``exp(y) − ε`` on the first or on every channel, then ``A·y + b``). Rows are in ring order,
view-major: p = view·n_lights + light, with both direction sets on a ``RingGrid``.

Between the measured directions the codec interpolates like the dense codec (core/dense.py):
ring-bilinear in the view, and for each of its (up to) four view samples ring-bilinear in the
light at the same azimuth relative to the view — at most 16 pairs, weights ≥ 0 summing to 1,
continuous in both directions and exact at the samples. Each pair is decoded and transformed
to RGB before weighting, so the blend is linear in radiance whatever the colour model. Past the
last light ring the value fades with cos θi / cos θlast when the data contains the cosine, and
is multiplied by cos θi when it does not (UBO2014's ``cosine`` flag); views clamp to the last
ring. Texels: nearest, wrapping.

Values: the decoded RGB times ``rgb_scale`` is a reflectance factor (1 = white standard), so
value = RGB · rgb_scale / π (× cos θi when the file's data lacks it): docs/formats.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import BTFFormatError, UnsupportedBTFError
from .grid import UBO2003, RingGrid
from .model import BTF, BTFMeta, Queries, wrap_texel
from .packed import TableWriter, register_codec

#: UBO2014 colour models (btflib's ``undecorrelate``) → name; the ones evaluated here.
COLOUR_MODELS = {
    0: "RGB",
    1: "YUV",
    3: "PCA",
    4: "YCoCg",
    9: "Ylog-UV",
    12: "log-RGB",
}
_YUV_TO_RGB = np.array([[1.0, 0.0, 1.13983], [1.0, -0.39465, -0.5806], [1.0, 2.03211, 0.0]])
_YCOCG_TO_RGB = np.array([[1.0, 1.0, -1.0], [1.0, 0.0, 1.0], [1.0, -1.0, -1.0]])
#: Pre-step before the linear part: none, exp(y0) − ε, exp(y) − ε for every channel.
PRE_NONE, PRE_EXP_FIRST, PRE_EXP_ALL = 0, 1, 2


@dataclass(frozen=True)
class ColourTransform:
    """y (3,) → RGB: ``pre`` (PRE_*), then ``matrix @ y + offset``; ``eps`` for the exp step."""

    pre: int
    matrix: np.ndarray  # (3, 3) float64
    offset: np.ndarray  # (3,) float64
    eps: float

    def apply(self, y: np.ndarray) -> np.ndarray:
        """y: (..., 3) channel values → (..., 3) RGB."""
        y = np.asarray(y, dtype=np.float64)
        if self.pre == PRE_EXP_FIRST:
            y = np.concatenate([np.exp(y[..., :1]) - self.eps, y[..., 1:]], axis=-1)
        elif self.pre == PRE_EXP_ALL:
            y = np.exp(y) - self.eps
        return y @ self.matrix.T + self.offset

    def packed(self) -> np.ndarray:
        """(15,) float32: pre, eps, 0 (reserved), matrix row-major, offset — the device form."""
        return np.concatenate([[self.pre, self.eps, 0.0], self.matrix.ravel(), self.offset]).astype(
            np.float32
        )


def colour_transform(
    model: int,
    pca_matrix: np.ndarray | None = None,
    mean: np.ndarray | None = None,
    rgb_scale: np.ndarray | None = None,
    eps: float = 1e-5,
) -> ColourTransform:
    """btflib's undecorrelation for ``model`` with the file's PCA matrix and mean, followed by
    the per-channel ``rgb_scale``. PCA: rgb = y·M + mean (row vector times M, as btflib)."""
    scale = np.diag(np.ones(3) if rgb_scale is None else np.asarray(rgb_scale, np.float64))
    pre, offset = PRE_NONE, np.zeros(3)
    if model == 0:
        matrix = np.eye(3)
    elif model == 1:
        matrix = _YUV_TO_RGB
    elif model == 3:
        if pca_matrix is None or mean is None:
            raise BTFFormatError("PCA colour model needs its matrix and mean")
        matrix = np.asarray(pca_matrix, np.float64).T
        offset = np.asarray(mean, np.float64)
    elif model == 4:
        matrix = _YCOCG_TO_RGB
    elif model == 9:
        pre, matrix = PRE_EXP_FIRST, _YUV_TO_RGB
    elif model == 12:
        pre, matrix = PRE_EXP_ALL, np.eye(3)
    else:
        raise UnsupportedBTFError(
            f"UBO colour model {model} is not supported (supported: "
            + ", ".join(f"{k} {v}" for k, v in COLOUR_MODELS.items())
            + ")"
        )
    if not (np.all(np.isfinite(matrix)) and np.all(np.isfinite(offset))):
        raise BTFFormatError("the colour transform contains NaN or infinite values")
    return ColourTransform(pre, scale @ matrix, scale @ offset, float(eps))


@dataclass(frozen=True)
class SVDParams:
    """What rebuilds an SVDBTF beside its factor tables (JSON-serialisable)."""

    name: str
    width: int
    height: int
    view_grid: RingGrid
    light_grid: RingGrid
    colour_model: int
    pca_matrix: tuple[float, ...]  # 9, row-major, as stored in the file
    colour_mean: tuple[float, float, float]
    rgb_scale: tuple[float, float, float]
    cosine_in_data: bool
    tile_size_mm: tuple[float, float] = (10.0, 10.0)

    def transform(self) -> ColourTransform:
        return colour_transform(
            self.colour_model,
            np.asarray(self.pca_matrix).reshape(3, 3),
            np.asarray(self.colour_mean),
            np.asarray(self.rgb_scale),
        )


class SVDBTF(BTF):
    """u[c]: (n_views·n_lights, K_c) float32; sv[c]: (height·width, K_c) float32, texel
    t = y·width + x; K_c ≥ 1 may differ per channel."""

    def __init__(self, params: SVDParams, u: list[np.ndarray], sv: list[np.ndarray]):
        self.p = params
        self.u = [np.ascontiguousarray(a, dtype=np.float32) for a in u]
        self.sv = [np.ascontiguousarray(a, dtype=np.float32) for a in sv]
        pairs = params.view_grid.size * params.light_grid.size
        texels = params.width * params.height
        if len(self.u) != 3 or len(self.sv) != 3:
            raise BTFFormatError(f"{params.name}: the svd codec needs 3 channels")
        for c, (uc, svc) in enumerate(zip(self.u, self.sv, strict=True)):
            if uc.ndim != 2 or svc.ndim != 2 or uc.shape[1] != svc.shape[1] or uc.shape[1] < 1:
                raise BTFFormatError(
                    f"{params.name}: channel {c}: U {uc.shape} and SV {svc.shape} must be "
                    "2-D with the same number (≥ 1) of components"
                )
            if uc.shape[0] != pairs or svc.shape[0] != texels:
                raise BTFFormatError(
                    f"{params.name}: channel {c}: U has {uc.shape[0]} rows (expected "
                    f"{pairs} direction pairs), SV {svc.shape[0]} (expected {texels} texels)"
                )
            if not (np.all(np.isfinite(uc)) and np.all(np.isfinite(svc))):
                raise BTFFormatError(f"{params.name}: channel {c}: NaN or infinite factors")
        self.colour = params.transform()
        self.meta = BTFMeta(
            codec="svd",
            name=params.name,
            width=params.width,
            height=params.height,
            n_views=params.view_grid.size,
            n_lights=params.light_grid.size,
            angular_grid=(
                f"rings view {params.view_grid.size} x light {params.light_grid.size}, "
                f"rank {'/'.join(str(a.shape[1]) for a in self.u)} "
                f"({COLOUR_MODELS[params.colour_model]})"
            ),
            hdr=True,
            tile_size_mm=tuple(params.tile_size_mm),
            value_scale=1.0 / np.pi,
        )

    @property
    def ranks(self) -> tuple[int, ...]:
        return tuple(a.shape[1] for a in self.u)

    # --- evaluation --------------------------------------------------------------------------
    def pair_rgb(self, pair: np.ndarray, texel: np.ndarray) -> np.ndarray:
        """Decoded RGB (before value_scale and the cosine rule) of measured pairs at texels:
        (M,) int, (M,) int → (M, 3) float64."""
        y = np.empty((len(pair), 3))
        for c in range(3):
            y[:, c] = np.einsum("mk,mk->m", self.u[c][pair].astype(np.float64), self.sv[c][texel])
        return self.colour.apply(y)

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        p = self.p
        x, y = wrap_texel(q.uv, p.width, p.height)
        texel = y * p.width + x
        vi, vw = p.view_grid.weights(q.theta_v, q.phi_v)
        _, view_phi = p.view_grid.angles_deg()
        out = np.zeros((len(x), 3))
        n_lights = p.light_grid.size
        for a in range(4):
            li, lw = p.light_grid.weights(q.theta_i, q.phi_i - q.phi_v + view_phi[vi[:, a]])
            for b in range(4):
                w = vw[:, a] * lw[:, b]
                used = w > 0
                if not np.any(used):
                    continue
                rgb = self.pair_rgb((vi[used, a] * n_lights + li[used, b]), texel[used])
                out[used] += w[used, None] * rgb
        return out * self._angular_factor(q.theta_i)[:, None] * self.meta.value_scale

    def _angular_factor(self, theta_i: np.ndarray) -> np.ndarray:
        cos_i = np.cos(np.radians(theta_i))
        if not self.p.cosine_in_data:
            return cos_i
        last = self.p.light_grid.theta_max_deg
        return np.where(theta_i > last, cos_i / np.cos(np.radians(last)), 1.0)

    # --- container -------------------------------------------------------------------------
    def tables(self) -> dict[str, np.ndarray]:
        out = {f"u{c}": self.u[c] for c in range(3)}
        out.update({f"sv{c}": self.sv[c] for c in range(3)})
        return out

    def params(self) -> dict[str, Any]:
        p = self.p
        return {
            "name": p.name,
            "width": p.width,
            "height": p.height,
            "view_grid": [list(p.view_grid.theta_deg), list(p.view_grid.counts)],
            "light_grid": [list(p.light_grid.theta_deg), list(p.light_grid.counts)],
            "colour_model": p.colour_model,
            "pca_matrix": list(p.pca_matrix),
            "colour_mean": list(p.colour_mean),
            "rgb_scale": list(p.rgb_scale),
            "cosine_in_data": p.cosine_in_data,
            "tile_size_mm": list(p.tile_size_mm),
        }

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> SVDBTF:
        grids = {
            k: RingGrid(tuple(params[k][0]), tuple(int(n) for n in params[k][1]))
            for k in ("view_grid", "light_grid")
        }
        p = SVDParams(
            name=params["name"],
            width=int(params["width"]),
            height=int(params["height"]),
            view_grid=grids["view_grid"],
            light_grid=grids["light_grid"],
            colour_model=int(params["colour_model"]),
            pca_matrix=tuple(params["pca_matrix"]),
            colour_mean=tuple(params["colour_mean"]),
            rgb_scale=tuple(params["rgb_scale"]),
            cosine_in_data=bool(params["cosine_in_data"]),
            tile_size_mm=tuple(params["tile_size_mm"]),
        )
        return cls(p, [tables[f"u{c}"] for c in range(3)], [tables[f"sv{c}"] for c in range(3)])


# --- building from measured (dense) data ----------------------------------------------------
_RGB_TO_YUV = np.linalg.inv(_YUV_TO_RGB)


def factorise(
    data: np.ndarray,
    view_grid: RingGrid = UBO2003,
    light_grid: RingGrid = UBO2003,
    ranks: tuple[int, int, int] = (8, 8, 8),
    colour_model: int = 1,
    name: str = "svd",
    cosine_in_data: bool = True,
) -> tuple[SVDBTF, np.ndarray]:
    """Truncated per-channel SVD of measured values → (SVDBTF, relative truncation error per
    channel (3,): ‖dropped singular values‖ / ‖all‖, the Frobenius error of the rank-K fit).

    data: (n_views, n_lights, height, width, 3) RGB as reflectance factors (rgb_scale 1:
    value = data/π). colour_model: 0 (RGB) or 1 (YUV)."""
    data = np.asarray(data, dtype=np.float64)
    nv, nl, h, w, _ = data.shape
    if colour_model == 0:
        channels = data
    elif colour_model == 1:
        channels = data @ _RGB_TO_YUV.T
    else:
        raise UnsupportedBTFError("factorise writes the RGB (0) or YUV (1) colour models only")
    u, sv, errors = [], [], np.zeros(3)
    for c in range(3):
        m = channels[..., c].reshape(nv * nl, h * w)
        uu, s, vt = np.linalg.svd(m, full_matrices=False)
        k = max(1, min(ranks[c], len(s)))
        u.append(uu[:, :k])
        sv.append((s[:k, None] * vt[:k]).T)
        total = float(np.sqrt(np.sum(s**2)))
        errors[c] = float(np.sqrt(np.sum(s[k:] ** 2))) / total if total > 0 else 0.0
    params = SVDParams(
        name=name,
        width=w,
        height=h,
        view_grid=view_grid,
        light_grid=light_grid,
        colour_model=colour_model,
        pca_matrix=tuple(np.eye(3).ravel()),
        colour_mean=(0.0, 0.0, 0.0),
        rgb_scale=(1.0, 1.0, 1.0),
        cosine_in_data=cosine_in_data,
    )
    return SVDBTF(params, u, sv), errors


def reduce_resolution(btf: SVDBTF, factor: int) -> SVDBTF:
    """Texels averaged over factor × factor blocks (SV rows are linear in the value, so this is
    the box-filtered BTF for the linear colour models): the GPU fallback when a BTF is too large.
    Sizes not divisible by ``factor`` drop their last partial block."""
    p = btf.p
    h, w = p.height // factor, p.width // factor
    if h < 1 or w < 1:
        raise UnsupportedBTFError(f"{p.name}: cannot reduce {p.width}×{p.height} by {factor}")
    sv = []
    for a in btf.sv:
        grid = a.reshape(p.height, p.width, -1)[: h * factor, : w * factor]
        sv.append(grid.reshape(h, factor, w, factor, -1).mean(axis=(1, 3)).reshape(h * w, -1))
    from dataclasses import replace

    return SVDBTF(replace(p, width=w, height=h, name=f"{p.name} (1/{factor})"), btf.u, sv)


# --- GPU tables (core/packed.py; read by svd_evaluate in kernels/include/btf_svd.h and
# shaders/btf_svd_lib.glsl) -------------------------------------------------------------------
def _pack(btf: SVDBTF, out: TableWriter) -> None:
    p = btf.p
    out.set(width=p.width, height=p.height, n_lights=p.light_grid.size)
    for prefix, grid in (("view", p.view_grid), ("light", p.light_grid)):
        out.set(
            **{
                f"n_{prefix}_rings": len(grid.counts),
                f"f_{prefix}_theta": out.float_table(np.asarray(grid.theta_deg)),
                f"{prefix}_offsets": out.int_table(np.concatenate([[0], np.cumsum(grid.counts)])),
            }
        )
    channels = []
    for c in range(3):
        channels += [btf.u[c].shape[1], out.float_table(btf.u[c]), out.float_table(btf.sv[c])]
    colour = btf.colour.packed()
    colour[2] = float(p.cosine_in_data)
    out.set(svd_channels=out.int_table(np.asarray(channels)), f_svd_colour=out.float_table(colour))


register_codec("svd", 7, _pack)
