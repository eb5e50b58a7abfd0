"""BTFbase MLVQ codec: the exact reference decoder.

Follows the original BTFbase decoder (Havran, Filip, Myszkowski 2010) level by level:

* light direction re-expressed relative to the view: φv' = 360 − φv,
  φi' = (360 − φi) − (90 + φv'); x = cos φi'·sin θi, y = sin φi'·sin θi;
  β = asin x, α = asin(y / cos β) (α = 0 when cos β < 1e-3);
* P6: nearest texel (wraps, with the material's row/column offsets) → 1-based P4 index × scale;
* P4: φv' linear, 16 slices that wrap; P3: θv linear; P2: α linear, luminance (scale × P1) and
  colour (IndexAB → (Cb, Cr)) each interpolated, then YCbCr → RGB per 2D function;
* P1: cubic Hermite in β (sample positions uniform in sin β), with the original's tangents;
* IndexAB colours: linear in β.

Values are the decoder's 8-bit-scale RGB; ``value_scale`` turns them into the value convention
(docs/conventions.md). ``decode_raw`` returns the original numbers untouched.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..colour import logluv_to_rgb, ycbcr_to_rgb
from ..errors import BTFFormatError
from ..model import BTF, BTFMeta, Queries
from . import btfbase_files as files

#: Decoded 8-bit LDR values are reflectance factors × 255 (white standard = 255), so
#: value = raw / 255 / π = apparent BRDF × cos θi. See docs/conventions.md.
LDR_VALUE_SCALE = 1.0 / (255.0 * np.pi)
#: HDR decodes are already on a unit scale (sRGB-encoded reflectance factor); only 1/π remains.
HDR_VALUE_SCALE = 1.0 / np.pi

TABLE_NAMES = (
    "pdf1",
    "ab_colors",
    "index_ab",
    "pdf2_colours",
    "pdf2_slices",
    "pdf2_scale",
    "pdf2_indices",
    "pdf3_slices",
    "pdf3_scale",
    "pdf4_slices",
    "pdf4_scale",
    "pdf6_slices",
    "pdf6_scale",
)

#: Which tables hold indices and which hold values (float32 on the device; the encoders'
#: report counts their bits by this split too).
INT_TABLES = (
    "index_ab",
    "pdf2_colours",
    "pdf2_slices",
    "pdf2_indices",
    "pdf3_slices",
    "pdf4_slices",
    "pdf6_slices",
)
FLOAT_TABLES = ("pdf1", "ab_colors", "pdf2_scale", "pdf3_scale", "pdf4_scale", "pdf6_scale")


@dataclass(frozen=True)
class MLVQParams:
    n_beta: int
    n_alpha: int
    n_theta: int
    n_phi: int
    use_cos_beta: bool
    rows_offset: int
    cols_offset: int
    hdr_value: float
    n_views: int
    n_lights: int
    name: str

    @property
    def hdr(self) -> bool:
        return not (abs(self.hdr_value - 1.0) < 1e-6 or abs(self.hdr_value) < 1e-6)

    def beta_angles_deg(self) -> np.ndarray:
        """β sample positions: uniform in sin β (or in β), ends and middle pinned exactly."""
        n = self.n_beta
        if self.use_cos_beta:
            angles = np.degrees(np.arcsin(np.clip(-1.0 + 2.0 * np.arange(n) / (n - 1), -1, 1)))
        else:
            angles = np.arange(n) * (180.0 / (n - 1)) - 90.0
        angles[0], angles[(n - 1) // 2], angles[-1] = -90.0, 0.0, 90.0
        return angles


class MLVQBTF(BTF):
    """A BTFbase MLVQ material. ``tables`` hold the 13 arrays named in TABLE_NAMES."""

    def __init__(self, params: MLVQParams, tables: dict[str, np.ndarray], source: str = ""):
        self.p = params
        self.t = {k: np.ascontiguousarray(tables[k]) for k in TABLE_NAMES}
        validate_tables(params, self.t, source or params.name)
        height, width = self.t["pdf6_slices"].shape
        self._beta_angles = params.beta_angles_deg()
        self.meta = BTFMeta(
            codec="mlvq",
            name=params.name,
            width=width,
            height=height,
            n_views=params.n_views,
            n_lights=params.n_lights,
            angular_grid=(
                f"MLVQ beta {params.n_beta} x alpha {params.n_alpha} x "
                f"theta_v {params.n_theta} x phi_v {params.n_phi}"
            ),
            hdr=params.hdr,
            value_scale=HDR_VALUE_SCALE if params.hdr else LDR_VALUE_SCALE,
        )

    # --- loading ---------------------------------------------------------------------------
    @classmethod
    def from_directory(cls, directory: str | Path) -> MLVQBTF:
        directory = Path(directory)
        info = files.read_material_info(directory)
        nb, na, nt, nf = info.n_beta, info.n_alpha, info.n_theta, info.n_phi
        tables = {
            name: files.read_table(directory / file, integer, cols)
            for name, (file, integer, cols) in files.table_files(info).items()
        }
        params = MLVQParams(
            n_beta=nb,
            n_alpha=na,
            n_theta=nt,
            n_phi=nf,
            use_cos_beta=info.use_cos_beta,
            rows_offset=info.rows_offset,
            cols_offset=info.cols_offset,
            hdr_value=info.hdr_value if info.hdr else 1.0,
            n_views=info.n_views,
            n_lights=info.n_lights,
            name=info.name,
        )
        return cls(params, tables, source=str(directory))

    def tables(self) -> dict[str, np.ndarray]:
        return dict(self.t)

    def params(self) -> dict[str, Any]:
        return dict(self.p.__dict__)

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> MLVQBTF:
        return cls(MLVQParams(**params), tables)

    # --- decoding --------------------------------------------------------------------------
    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        raw = self.decode_raw(q.uv, q.theta_i, q.phi_i, q.theta_v, q.phi_v)
        return raw * self.meta.value_scale

    def decode_raw(self, uv, theta_i, phi_i, theta_v, phi_v) -> np.ndarray:
        """The original decoder's output for angles in degrees (θ ≤ 90): (M, 3) float64."""
        p, t = self.p, self.t
        height, width = t["pdf6_slices"].shape
        x = (np.floor(np.mod(uv[:, 0], 1.0) * width).astype(np.int64) - p.cols_offset) % width
        y = (np.floor(np.mod(uv[:, 1], 1.0) * height).astype(np.int64) - p.rows_offset) % height

        view_phi = np.mod(360.0 - phi_v, 360.0)
        light_phi = np.mod((360.0 - phi_i) - (90.0 + view_phi), 360.0)
        beta, alpha = _beta_alpha_deg(theta_i, light_phi)

        ib, wb = self._beta_index(np.clip(beta, -90.0, 90.0))
        ia, wa = _uniform_index(
            np.clip(alpha, -90.0, 90.0) + 90.0, 180.0 / (p.n_alpha - 1), p.n_alpha - 2
        )
        it, wt = _uniform_index(np.clip(theta_v, 0.0, 90.0), 90.0 / (p.n_theta - 1), p.n_theta - 2)
        ip, wp = _uniform_index(np.clip(view_phi, 0.0, 360.0), 360.0 / p.n_phi, p.n_phi - 1)

        slot6 = t["pdf6_slices"][y, x].astype(np.int64) - 1  # 1-based; 0 = texel not stored
        stored = slot6 >= 0
        slot6 = np.maximum(slot6, 0)

        rgb = np.zeros((len(x), 3))
        phis = (ip, (ip + 1) % p.n_phi)  # φ wraps: slice n_phi-1 blends into slice 0
        for k, wk in ((0, 1.0 - wp), (1, wp)):
            idx3 = t["pdf4_slices"][slot6, phis[k]]
            s4 = t["pdf4_scale"][slot6, phis[k]] * wk
            for j, wj in ((it, 1.0 - wt), (it + 1, wt)):
                idx2 = t["pdf3_slices"][idx3, j]
                s3 = t["pdf3_scale"][idx3, j] * wj
                rgb += self._pdf2_rgb(idx2, ia, wa, ib, wb) * (s4 * s3)[:, None]
        rgb *= (t["pdf6_scale"][y, x] * stored)[:, None]
        if p.hdr:
            rgb /= p.hdr_value
        return rgb

    def _beta_index(self, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.p.n_beta
        if self.p.use_cos_beta:
            i = np.clip(
                ((np.sin(np.radians(beta)) + 1.0) / 2.0 * (n - 1)).astype(np.int64), 0, n - 2
            )
            a = self._beta_angles
            return i, (beta - a[i]) / (a[i + 1] - a[i])
        return _uniform_index(beta + 90.0, 180.0 / (n - 1), n - 2)

    def _pdf2_rgb(self, idx2, ia, wa, ib, wb) -> np.ndarray:
        """One 2D function per row at (α, β): luminance and colour, then YCbCr/LogLuv → RGB."""
        t = self.t
        lum_fn = t["pdf2_indices"][idx2, 0]
        col_fn = t["pdf2_indices"][idx2, 1]
        lum = np.zeros(len(idx2))
        cb = np.zeros(len(idx2))
        cr = np.zeros(len(idx2))
        for a, w in ((ia, 1.0 - wa), (ia + 1, wa)):
            lum += w * t["pdf2_scale"][lum_fn, a] * self._pdf1(t["pdf2_slices"][lum_fn, a], ib, wb)
            ab = self._index_ab(t["pdf2_colours"][col_fn, a], ib, wb)
            cb += w * ab[:, 0]
            cr += w * ab[:, 1]
        if self.p.hdr:
            return logluv_to_rgb(lum, cb, cr)
        return ycbcr_to_rgb(lum, cb, cr)

    def _pdf1(self, s: np.ndarray, i: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Cubic Hermite between samples i and i+1, tangents as in the original decoder:
        left 0.5·(p1 − p[i−1]) (p1 − p0 at the first interval); right 0.5·(p1 − p0)
        (p1 − p0 at the last interval) — the original's right tangent, kept for exactness."""
        basis = self.t["pdf1"]
        p0 = basis[s, i].astype(np.float64)
        p1 = basis[s, i + 1].astype(np.float64)
        prev = basis[s, np.maximum(i - 1, 0)]
        m0 = np.where(i == 0, p1 - p0, 0.5 * (p1 - prev))
        m1 = np.where(i == self.p.n_beta - 2, p1 - p0, 0.5 * (p1 - p0))
        t2 = w * w
        t3 = t2 * w
        h01 = -2.0 * t3 + 3.0 * t2
        h00 = 1.0 - h01
        h11 = t3 - t2
        h10 = h11 - t2 + w
        return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1

    def _index_ab(self, c: np.ndarray, i: np.ndarray, w: np.ndarray) -> np.ndarray:
        """(Cb, Cr) of colour slice c at β, linear between samples i and i+1: (M, 2)."""
        colors = self.t["ab_colors"].astype(np.float64)
        ab0 = colors[self.t["index_ab"][c, i]]
        ab1 = colors[self.t["index_ab"][c, i + 1]]
        return ab0 * (1.0 - w)[:, None] + ab1 * w[:, None]


def _beta_alpha_deg(theta_deg: np.ndarray, phi_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Light (θ, φ') → onion-slice (β, α) in degrees, as ConvertThetaPhiToBetaAlpha."""
    theta = np.radians(theta_deg)
    phi = np.radians(phi_deg)
    x = np.cos(phi) * np.sin(theta)
    y = np.sin(phi) * np.sin(theta)
    beta = np.arcsin(np.clip(x, -1.0, 1.0))
    cos_beta = np.cos(beta)
    near_pole = cos_beta < 1e-3
    alpha = np.arcsin(np.clip(y / np.where(near_pole, 1.0, cos_beta), -1.0, 1.0))
    return np.degrees(beta), np.degrees(np.where(near_pole, 0.0, alpha))


def _uniform_index(x: np.ndarray, step: float, max_index: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower sample index (truncated, clamped to [0, max_index]) and weight for uniform steps."""
    i = np.clip((x / step).astype(np.int64), 0, max_index)
    return i, (x - i * step) / step


#: Every index table's target, down the chain P6 → P4 → P3 → P2 → (P1, colours → IndexAB →
#: (Cb, Cr)): (index table, its columns, target table, what it links, 1-based with 0 = none).
INDEX_LINKS = (
    ("index_ab", slice(None), "ab_colors", "all_indexAB → all_colors", False),
    ("pdf2_colours", slice(None), "index_ab", "all_PDF2Dcolours → all_indexAB", False),
    ("pdf2_slices", slice(None), "pdf1", "all_PDF2Dslices → all_PDF1Dslice", False),
    (
        "pdf2_indices",
        slice(0, 1),
        "pdf2_slices",
        "all_PDF2Dindices (luminance) → all_PDF2Dslices",
        False,
    ),
    (
        "pdf2_indices",
        slice(1, 2),
        "pdf2_colours",
        "all_PDF2Dindices (colour) → all_PDF2Dcolours",
        False,
    ),
    ("pdf3_slices", slice(None), "pdf2_indices", "all_PDF3Dslices → all_PDF2Dindices", False),
    ("pdf4_slices", slice(None), "pdf3_slices", "all_PDF4Dslices → all_PDF3Dslices", False),
    (
        "pdf6_slices",
        slice(None),
        "pdf4_slices",
        "PDF6Dslices → all_PDF4Dslices (1-based)",
        True,
    ),
)


def index_range(t: dict[str, np.ndarray], target: str, one_based: bool) -> tuple[int, int]:
    """The inclusive range of valid indices into ``t[target]`` (0 = none when 1-based)."""
    n = len(t[target])
    return (0, n) if one_based else (0, n - 1)


def validate_tables(p: MLVQParams, t: dict[str, np.ndarray], source: str) -> None:
    """Shapes and every index range, so decoding can never read out of bounds."""

    def need(name: str, cols: int | None, integer: bool) -> np.ndarray:
        a = t[name]
        if a.ndim != 2 or a.shape[0] == 0 or (cols is not None and a.shape[1] != cols):
            raise BTFFormatError(
                f"{source}: table {name} has shape {a.shape}, expected (n, {cols})"
            )
        if integer != np.issubdtype(a.dtype, np.integer):
            raise BTFFormatError(f"{source}: table {name} has dtype {a.dtype}")
        if not integer and not np.all(np.isfinite(a)):
            raise BTFFormatError(f"{source}: table {name} contains NaN or infinite values")
        return a

    need("pdf1", p.n_beta, False)
    need("ab_colors", 2, False)
    need("index_ab", p.n_beta, True)
    need("pdf2_colours", p.n_alpha, True)
    p2s = need("pdf2_slices", p.n_alpha, True)
    p2sc = need("pdf2_scale", p.n_alpha, False)
    need("pdf2_indices", 2, True)
    p3 = need("pdf3_slices", p.n_theta, True)
    p3sc = need("pdf3_scale", p.n_theta, False)
    p4 = need("pdf4_slices", p.n_phi, True)
    p4sc = need("pdf4_scale", p.n_phi, False)
    p6 = need("pdf6_slices", None, True)
    p6sc = need("pdf6_scale", None, False)
    pairs = (
        (p2s, p2sc, "pdf2_slices/pdf2_scale"),
        (p3, p3sc, "pdf3_slices/pdf3_scale"),
        (p4, p4sc, "pdf4_slices/pdf4_scale"),
        (p6, p6sc, "pdf6_slices/pdf6_scale"),
    )
    for a, b, what in pairs:
        if a.shape != b.shape:
            raise BTFFormatError(f"{source}: {what} shapes differ: {a.shape} vs {b.shape}")

    for index, cols, target, what, one_based in INDEX_LINKS:
        low, high = index_range(t, target, one_based)
        files.check_index_range(t[index][:, cols], low, high, Path(source), what)
