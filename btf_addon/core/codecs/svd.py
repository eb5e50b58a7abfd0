"""The ``svd`` codec: a BTF stored as one truncated SVD per colour channel (UBO2014's "DFMF").

Per channel c the measurement is a matrix whose rows are direction pairs and whose columns are
texels; the file keeps its first K_c components: ``U_c`` (n_views·n_lights, K_c) and
``SV_c`` (height·width, K_c) = S·V. For a measured pair p and texel t the channel value is

    y_c = Σ_k U_c[p, k] · SV_c[t, k]

and the colour transform turns (y_0, y_1, y_2) into RGB (``colour_transform``: an optional
``exp(y) − ε`` on the first or on every channel, then ``A·y + b``). Rows are in ring order,
view-major: p = view·n_lights + light, with both direction sets on a ``RingGrid`` whose samples
may carry their own azimuths (``SVDParams.view_phi``/``light_phi``: rotated or uneven rings).

Between the measured directions the codec interpolates like the dense codec (core/codecs/dense.py):
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

from ..errors import BTFFormatError, UnsupportedBTFError
from ..grid import RingGrid
from ..model import BTF, BTFMeta, Queries, wrap_texel
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
    #: Azimuth (degrees) of every sample in ring order when a file's rings are not k·360°/n
    #: from 0° (rotated or uneven rings); None: the RingGrid's own azimuths.
    view_phi: tuple[float, ...] | None = None
    light_phi: tuple[float, ...] | None = None

    def phis(self, which: str) -> np.ndarray:
        """(size,) azimuths in degrees of the view or light samples, ring order."""
        grid, phi = (
            (self.view_grid, self.view_phi)
            if which == "view"
            else (self.light_grid, self.light_phi)
        )
        return np.asarray(phi, dtype=np.float64) if phi is not None else grid.angles_deg()[1]

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
        view_phi, light_phi = p.phis("view"), p.phis("light")
        vi, vw = ring_weights(p.view_grid, view_phi, q.theta_v, q.phi_v)
        out = np.zeros((len(x), 3))
        n_lights = p.light_grid.size
        for a in range(4):
            light_az = q.phi_i - q.phi_v + view_phi[vi[:, a]]
            li, lw = ring_weights(p.light_grid, light_phi, q.theta_i, light_az)
            for b in range(4):
                w = vw[:, a] * lw[:, b]
                used = w > 0
                if not np.any(used):
                    continue
                rgb = self.pair_rgb((vi[used, a] * n_lights + li[used, b]), texel[used])
                out[used] += w[used, None] * rgb
        return out * self._angular_factor(q.theta_i)[:, None] * self.meta.value_scale

    def raw_units(self, values: np.ndarray, theta_i_deg: np.ndarray) -> np.ndarray:
        """The decoded RGB: without ``value_scale`` and without the angular factor (× cos θi
        for a file whose data lacks the cosine, the fade past the last light ring). Where that
        factor is 0 (θi = 90° without the cosine) the value holds nothing to recover: 0."""
        factor = self._angular_factor(np.abs(np.asarray(theta_i_deg, dtype=np.float64)))
        scaled = np.asarray(values, dtype=np.float64) / self.meta.value_scale
        safe = np.where(factor > 0, factor, 1.0)
        return np.where(factor[:, None] > 0, scaled / safe[:, None], 0.0)

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
            "view_phi": None if p.view_phi is None else list(p.view_phi),
            "light_phi": None if p.light_phi is None else list(p.light_phi),
        }

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> SVDBTF:
        try:
            p = _params_from_json(params)
            u = [tables[f"u{c}"] for c in range(3)]
            sv = [tables[f"sv{c}"] for c in range(3)]
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise BTFFormatError(f"svd parameters or tables are malformed ({exc!r})") from None
        return cls(p, u, sv)


def _params_from_json(params: dict[str, Any]) -> SVDParams:
    grids = {
        k: RingGrid(tuple(float(t) for t in params[k][0]), tuple(int(n) for n in params[k][1]))
        for k in ("view_grid", "light_grid")
    }
    p = SVDParams(
        name=str(params["name"]),
        width=int(params["width"]),
        height=int(params["height"]),
        view_grid=grids["view_grid"],
        light_grid=grids["light_grid"],
        colour_model=int(params["colour_model"]),
        pca_matrix=tuple(float(v) for v in params["pca_matrix"]),
        colour_mean=tuple(float(v) for v in params["colour_mean"]),
        rgb_scale=tuple(float(v) for v in params["rgb_scale"]),
        cosine_in_data=bool(params["cosine_in_data"]),
        tile_size_mm=tuple(float(v) for v in params["tile_size_mm"]),
        view_phi=_optional_tuple(params.get("view_phi")),
        light_phi=_optional_tuple(params.get("light_phi")),
    )
    if len(p.pca_matrix) != 9 or len(p.colour_mean) != 3 or len(p.rgb_scale) != 3:
        raise ValueError("colour matrix/mean/scale sizes")
    for phi, grid in ((p.view_phi, p.view_grid), (p.light_phi, p.light_grid)):
        if phi is not None and len(phi) != grid.size:
            raise ValueError("azimuth table size differs from its grid")
    if p.width < 1 or p.height < 1:
        raise ValueError("texture size")
    return p


def _optional_tuple(values) -> tuple[float, ...] | None:
    return None if values is None else tuple(float(v) for v in values)


def ring_weights(
    grid: RingGrid, phis: np.ndarray, theta_deg: np.ndarray, phi_deg: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """core/grid.py's ring-bilinear interpolation with each sample's own azimuth (``phis``,
    ring order, increasing within a ring): linear in θ between the bracketing rings, within a
    ring linear in φ between the neighbouring samples (wrapping). Equals ``grid.weights`` when
    the azimuths are k·360°/n. Returns indices (M, 4) int64 and weights (M, 4) float64."""
    counts = np.asarray(grid.counts)
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
    r0, r1, wt = grid.ring_pair(theta_deg)
    pos = np.mod(phi_deg, 360.0)
    idx = np.empty((len(wt), 4), dtype=np.int64)
    w = np.empty((len(wt), 4))
    for slot, ring, ring_w in ((0, r0, 1.0 - wt), (2, r1, wt)):
        k0 = np.zeros(len(wt), dtype=np.int64)
        wp = np.zeros(len(wt))
        for r in np.unique(ring):
            m = ring == r
            n = counts[r]
            ph = phis[offsets[r] : offsets[r] + n]
            j = np.searchsorted(ph, pos[m], side="right") - 1
            j = np.where(j < 0, n - 1, j)
            span = np.mod(ph[(j + 1) % n] - ph[j], 360.0)
            span = np.where(span <= 0.0, 360.0, span)
            k0[m] = j
            wp[m] = np.mod(pos[m] - ph[j], 360.0) / span
        n = counts[ring]
        idx[:, slot] = offsets[ring] + k0
        idx[:, slot + 1] = offsets[ring] + (k0 + 1) % n
        w[:, slot] = ring_w * (1.0 - wp)
        w[:, slot + 1] = ring_w * wp
    return idx, w


# --- GPU tables (core/codecs/packed.py; read by svd_evaluate in kernels/include/btf_svd.h and
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
    # Entries 9 and 10: every sample's azimuth (view, light), read by svd_ring_weights.
    channels += [out.float_table(p.phis("view")), out.float_table(p.phis("light"))]
    colour = btf.colour.packed()
    colour[2] = float(p.cosine_in_data)
    out.set(svd_channels=out.int_table(np.asarray(channels)), f_svd_colour=out.float_table(colour))


register_codec("svd", SVDBTF, 7, _pack)
