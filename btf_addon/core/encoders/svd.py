"""SVD encoder: any BTF → the ``svd`` codec (core/codecs/svd.py), a truncated SVD per colour
channel.

Input samples (the "measured directions"). Per channel c the input is a matrix M_c with one
row per direction pair p = view·n_lights + light (ring order, as the codec) and one column per
texel t = y·width + x, holding the RGB reflectance factor (value · π) or its YUV transform:

* a dense BTF (tabulated, image sets): its own data on its own grids;
* an svd BTF (UBO2014 decoded, a previous encoding): its own pairs on its own grids and
  azimuths, decoded to RGB (``pair_rgb``), keeping its cosine convention;
* an MLVQ BTF (BTFbase): decoded onto the measured UBO2003 grid (81 × 81). Its value is
  ``max(0, R[slot, p] · scale)`` per texel (``MLVQBTF.decode_raw``: linear in the texel's P6
  scale), so R is decoded once per P4 row (783 rows for wallpaper, not 65 536 texels) and the
  texel blocks are gathers — the same numbers as ``evaluate_angles`` at every texel;
* anything else (analytic, microgeometry): ``evaluate_angles`` at the UBO2003 pairs.

Streaming. The factors come from the Gram matrix of the smaller side, accumulated block by
block and eigendecomposed (float64):

* more texels than pairs (wallpaper: 65 536 > 6561): G_c = Σ_blocks B·Bᵀ (pairs × pairs) over
  texel blocks B = M_c[:, block]; U_c = its top K eigenvectors; a second pass projects each
  block: SV_c[block] = Bᵀ·U_c;
* otherwise (alu: 4096 ≤ 6561, tiny test inputs): G_c = Σ Bᵀ·B (texels × texels) over pair
  blocks; SV_c = V·S from its eigenpairs; the second pass gives U_c[block] = B·V / S.

Memory bound (``memory_bound``), never the whole BTF: while streaming, 3·n² float64 Gram
matrices (n = min(pairs, texels)) and one block of pairs × ``block_texels`` (or
``block_pairs`` × texels) × 3 float64 in three copies (samples, colour transform, channel
planes); while eigendecomposing, the Grams, the eigenvectors and LAPACK's workspace (about
2 n²): 6 n² float64 in all; plus the factors (float64 while built, float32 kept). Wallpaper:
6 · 6561² · 8 B = 2.07 GB at the eigendecomposition (the streaming passes: 1.03 GB of Grams +
3 × 161 MB of blocks), plus the MLVQ sampler's per-row table (6561 × 783 × 3 float64, 123 MB).

The result equals ``svd_build.factorise`` (the in-memory SVD) up to rounding: eigenvalues are
s², so components whose s is below ~1e-7 of the largest lose relative precision, far below
what any PSNR here resolves. Signs are fixed (each U column's largest entry positive), so
the encoding is deterministic (no random numbers at all). A component with s = 0 (a constant or
black input has rank ≤ 1) is stored as zeros: the material stays valid.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from ..codecs.dense import DenseBTF
from ..codecs.mlvq import MLVQBTF
from ..codecs.svd import SVDBTF, SVDParams
from ..codecs.svd_build import _RGB_TO_YUV
from ..errors import BTFFormatError
from ..grid import UBO2003, RingGrid
from ..model import BTF
from .metrics import SizeReport

#: ``progress(fraction 0..1, what)``; may raise (KeyboardInterrupt, a cancel exception) to stop.
Progress = Callable[[float, str], None]

#: Colour space name → the codec's colour model (core/codecs/svd.py COLOUR_MODELS).
COLOUR_SPACES = {"rgb": 0, "yuv": 1}
_TO_CHANNELS = {0: np.eye(3), 1: _RGB_TO_YUV}
#: Components with s ≤ this × the largest s of the channel are stored as zeros (their U = M·V/S
#: would only amplify rounding).
_RELATIVE_ZERO = 1e-9


@dataclass(frozen=True)
class SVDSettings:
    """Rank per channel (one int: the same for all three) and the colour space."""

    ranks: tuple[int, int, int] | int = (16, 8, 8)
    colour_space: str = "yuv"
    #: Block sizes of the streaming passes (texels per block for the pair Gram, pairs per
    #: block for the texel Gram): they bound the working set beside the Gram matrices.
    block_texels: int = 1024
    block_pairs: int = 512
    #: Quantise every factor column (of U and of S·V) uniformly between its min and max to
    #: 2^factor_bits levels, as the original MLVQ tool's mode 0 does its scales; 0 = keep
    #: float32. The .btfm stores float32 either way; ``sizes`` counts the packed bits.
    factor_bits: int = 0

    def __post_init__(self) -> None:
        ranks = self.ranks
        ranks = (ranks,) * 3 if isinstance(ranks, int | np.integer) else tuple(ranks)
        if len(ranks) != 3 or any(int(k) < 1 or int(k) > 4096 for k in ranks):
            raise BTFFormatError(
                f"SVD encoder: rank must be one integer or three (per channel), each 1..4096; "
                f"got {self.ranks!r}"
            )
        object.__setattr__(self, "ranks", tuple(int(k) for k in ranks))
        if self.colour_space not in COLOUR_SPACES:
            raise BTFFormatError(
                f"SVD encoder: colour space {self.colour_space!r} is not one of "
                + ", ".join(COLOUR_SPACES)
            )
        if self.block_texels < 1 or self.block_pairs < 1:
            raise BTFFormatError("SVD encoder: block sizes must be at least 1")
        if not (self.factor_bits == 0 or 2 <= self.factor_bits <= 16):
            raise BTFFormatError("SVD encoder: factor_bits must be 0 (float32) or 2..16")


@dataclass
class SVDStats:
    seconds: float
    ranks: tuple[int, int, int]
    #: Per channel ‖dropped singular values‖ / ‖all‖ (the relative Frobenius error of the fit
    #: in the encoded colour space, as svd_build.factorise reports).
    truncation_error: list[float] = field(default_factory=list)
    gram_side: str = ""
    memory_bound_bytes: int = 0


# --- input samples -----------------------------------------------------------------------------
class _Samples:
    """The input at its measured pairs: ``block(pairs, texels)`` → (len(pairs), len(texels), 3)
    float64 RGB reflectance factors. pairs, texels: int index arrays (ring order, row-major)."""

    view_grid: RingGrid = UBO2003
    light_grid: RingGrid = UBO2003
    view_phi: tuple[float, ...] | None = None
    light_phi: tuple[float, ...] | None = None
    cosine_in_data: bool = True

    def block(self, pairs: np.ndarray, texels: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class _DenseSamples(_Samples):
    def __init__(self, btf: DenseBTF):
        self.view_grid, self.light_grid = btf.view_grid, btf.light_grid
        n_tex = btf.meta.width * btf.meta.height
        self.data = btf.data.reshape(btf.view_grid.size * btf.light_grid.size, n_tex, 3)

    def block(self, pairs, texels):
        return self.data[np.ix_(pairs, texels)].astype(np.float64) * np.pi


class _SVDSamples(_Samples):
    def __init__(self, btf: SVDBTF):
        p = btf.p
        self.btf = btf
        self.view_grid, self.light_grid = p.view_grid, p.light_grid
        self.view_phi, self.light_phi = p.view_phi, p.light_phi
        self.cosine_in_data = p.cosine_in_data

    def block(self, pairs, texels):
        b = self.btf
        y = np.stack(
            [
                b.u[c][pairs].astype(np.float64) @ b.sv[c][texels].T.astype(np.float64)
                for c in range(3)
            ],
            axis=-1,
        )
        return b.colour.apply(y)


class _MLVQSamples(_Samples):
    """R[p, row] decoded once per P4 row at the UBO2003 pairs; a texel is R[:, slot] · scale."""

    def __init__(self, btf: MLVQBTF):
        t = btf.t
        n_rows = len(t["pdf4_slices"])
        h, w = t["pdf6_slices"].shape
        # A 1 × n_rows image whose texel r is P4 row r at scale 1 (offsets 0).
        probe = MLVQBTF(
            _zero_offsets(btf.p),
            {
                **t,
                "pdf6_slices": np.arange(1, n_rows + 1, dtype=t["pdf6_slices"].dtype)[None],
                "pdf6_scale": np.ones((1, n_rows), dtype=t["pdf6_scale"].dtype),
            },
        )
        tv, pv = UBO2003.angles_deg()
        n = UBO2003.size
        uv = np.column_stack([(np.arange(n_rows) + 0.5) / n_rows, np.full(n_rows, 0.5)])
        rows = np.empty((n * n, n_rows, 3))
        for v in range(n):
            m = n * n_rows
            raw = probe.decode_raw(
                np.tile(uv, (n, 1)),
                np.repeat(tv, n_rows),
                np.repeat(pv, n_rows),
                np.full(m, tv[v]),
                np.full(m, pv[v]),
            )
            rows[v * n : (v + 1) * n] = raw.reshape(n, n_rows, 3)
        self.rows = rows * (btf.meta.value_scale * np.pi)
        # Texel t (row-major in the BTF's own uv) reads the table cell the decoder reads.
        y, x = np.divmod(np.arange(h * w), w)
        ty, tx = (y - btf.p.rows_offset) % h, (x - btf.p.cols_offset) % w
        slot = t["pdf6_slices"][ty, tx].astype(np.int64) - 1
        self.scale = t["pdf6_scale"][ty, tx].astype(np.float64) * (slot >= 0)
        self.slot = np.maximum(slot, 0)

    def block(self, pairs, texels):
        values = self.rows[np.ix_(pairs, self.slot[texels])] * self.scale[texels][None, :, None]
        # evaluate_angles' contract (values ≥ 0), applied after the scale as the decoder does.
        return np.maximum(values, 0.0)


def _zero_offsets(p):
    from dataclasses import replace

    return replace(p, rows_offset=0, cols_offset=0)


class _EvaluatedSamples(_Samples):
    def __init__(self, btf: BTF):
        self.btf = btf
        self.w, self.h = btf.meta.width, btf.meta.height
        self.tv, self.pv = UBO2003.angles_deg()

    def block(self, pairs, texels):
        n_l = UBO2003.size
        v, light = np.divmod(pairs, n_l)
        uv = np.column_stack([(texels % self.w + 0.5) / self.w, (texels // self.w + 0.5) / self.h])
        n_p, n_t = len(pairs), len(texels)
        q = np.empty((n_p * n_t, 6))
        q[:, :2] = np.tile(uv, (n_p, 1))
        q[:, 2] = np.repeat(self.tv[light], n_t)
        q[:, 3] = np.repeat(self.pv[light], n_t)
        q[:, 4] = np.repeat(self.tv[v], n_t)
        q[:, 5] = np.repeat(self.pv[v], n_t)
        return self.btf.evaluate_angles(q).astype(np.float64).reshape(n_p, n_t, 3) * np.pi


def samples_of(btf: BTF) -> _Samples:
    """The input's measured-pair sampler (module docstring)."""
    if isinstance(btf, DenseBTF):
        return _DenseSamples(btf)
    if isinstance(btf, SVDBTF):
        return _SVDSamples(btf)
    if isinstance(btf, MLVQBTF):
        return _MLVQSamples(btf)
    return _EvaluatedSamples(btf)


def memory_bound(n_pairs: int, n_texels: int, s: SVDSettings = SVDSettings()) -> int:
    """Peak bytes of ``encode_svd`` beside the input and its sampler (module docstring): the
    larger of the streaming passes (three Gram matrices, three float64 copies of one block) and
    the eigendecomposition (6 n²), plus the factors (float64 and float32)."""
    n = min(n_pairs, n_texels)
    block = (
        n_pairs * min(s.block_texels, n_texels) if n_texels > n_pairs else s.block_pairs * n_texels
    )
    factors = (n_pairs + n_texels) * sum(min(k, n) for k in s.ranks) * 12
    return max(3 * n * n * 8 + 3 * block * 3 * 8, 6 * n * n * 8) + factors


# --- the encoder -------------------------------------------------------------------------------
def encode_svd(
    btf: BTF,
    settings: SVDSettings = SVDSettings(),
    progress: Progress | None = None,
    name: str | None = None,
) -> tuple[SVDBTF, SVDStats]:
    """Compress ``btf`` → an ``SVDBTF`` (rgb_scale 1, colour model 0 or 1) and its statistics.
    Raises BTFFormatError for NaN or infinite input values."""
    start = time.perf_counter()
    s = settings
    src = samples_of(btf)
    w, h = btf.meta.width, btf.meta.height
    n_pairs, n_tex = src.view_grid.size * src.light_grid.size, w * h
    model = COLOUR_SPACES[s.colour_space]
    to_channels = _TO_CHANNELS[model]

    def step(fraction: float, what: str) -> None:
        if progress is not None:
            progress(fraction, what)

    pair_side = n_tex > n_pairs
    n = n_pairs if pair_side else n_tex
    ranks = tuple(min(k, n_pairs, n_tex) for k in s.ranks)
    size = s.block_texels if pair_side else s.block_pairs
    along = n_tex if pair_side else n_pairs

    def blocks(what: str, lo: float, hi: float) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(index range along the streamed axis, channel blocks (3, rows, cols) float64)."""
        for first in range(0, along, size):
            step(lo + (hi - lo) * first / along, what)
            idx = np.arange(first, min(first + size, along))
            rgb = (
                src.block(np.arange(n_pairs), idx)
                if pair_side
                else src.block(idx, np.arange(n_tex))
            )
            _check_finite(rgb, idx, pair_side, btf)
            yield idx, np.ascontiguousarray(np.moveaxis(rgb @ to_channels.T, -1, 0))

    gram = [np.zeros((n, n)) for _ in range(3)]
    for _, ch in blocks("accumulating the Gram matrices", 0.0, 0.45):
        for c in range(3):
            b = ch[c]
            gram[c] += b @ b.T if pair_side else b.T @ b

    vectors, sing, errors = [], [], []
    for c in range(3):
        step(0.45 + 0.05 * c, f"eigendecomposition, channel {c + 1} of 3")
        total = float(np.trace(gram[c]))
        lam, vec = np.linalg.eigh(gram[c])
        gram[c] = None  # released before the next channel's eigh: one n² workspace at a time
        k = ranks[c]
        # Contiguous copy: a reversed view would make every later product skip BLAS.
        lam, vec = np.maximum(lam[::-1][:k], 0.0), np.ascontiguousarray(vec[:, ::-1][:, :k])
        errors.append(float(np.sqrt(max(total - lam.sum(), 0.0) / total)) if total > 0 else 0.0)
        sv = np.sqrt(lam)
        vectors.append(vec)
        sing.append(sv)
    del gram

    u = [np.zeros((n_pairs, k)) for k in ranks]
    svt = [np.zeros((n_tex, k)) for k in ranks]
    live = [sing[c] > _RELATIVE_ZERO * max(float(sing[c][0]), 1e-300) for c in range(3)]
    if pair_side:
        for c in range(3):
            u[c][:] = vectors[c]
        for idx, ch in blocks("projecting texel blocks", 0.6, 1.0):
            for c in range(3):
                svt[c][idx] = ch[c].T @ vectors[c]
    else:
        for c in range(3):
            svt[c][:] = vectors[c] * sing[c]
        inverse = [np.where(live[c], 1.0 / np.where(live[c], sing[c], 1.0), 0.0) for c in range(3)]
        for idx, ch in blocks("projecting direction blocks", 0.6, 1.0):
            for c in range(3):
                u[c][idx] = (ch[c] @ vectors[c]) * inverse[c]
    for c in range(3):
        u[c][:, ~live[c]] = 0.0
        svt[c][:, ~live[c]] = 0.0
        # Deterministic signs: each U column's largest-magnitude entry is positive.
        pick = np.argmax(np.abs(u[c]), axis=0)
        sign = np.where(u[c][pick, np.arange(u[c].shape[1])] < 0, -1.0, 1.0)
        u[c] *= sign
        svt[c] *= sign

    step(1.0, "done")
    tile = btf.meta.tile_size_mm
    params = SVDParams(
        name=name or f"{btf.meta.name} (svd)",
        width=w,
        height=h,
        view_grid=src.view_grid,
        light_grid=src.light_grid,
        colour_model=model,
        pca_matrix=tuple(np.eye(3).ravel()),
        colour_mean=(0.0, 0.0, 0.0),
        rgb_scale=(1.0, 1.0, 1.0),
        cosine_in_data=src.cosine_in_data,
        view_phi=src.view_phi,
        light_phi=src.light_phi,
        **({"tile_size_mm": tuple(tile)} if tile is not None else {}),
    )
    if s.factor_bits:
        u = [quantise_columns(a, s.factor_bits) for a in u]
        svt = [quantise_columns(a, s.factor_bits) for a in svt]
    out = SVDBTF(params, u, svt)
    stats = SVDStats(
        seconds=time.perf_counter() - start,
        ranks=ranks,
        truncation_error=errors,
        gram_side="pairs" if pair_side else "texels",
        memory_bound_bytes=memory_bound(n_pairs, n_tex, s),
    )
    return out, stats


def _check_finite(rgb: np.ndarray, idx: np.ndarray, pair_side: bool, btf: BTF) -> None:
    """One clear error for NaN or infinite input values, naming the first bad texel."""
    bad = ~np.isfinite(rgb)
    if not bad.any():
        return
    _, t, _ = np.argwhere(bad)[0]
    texel = int(idx[t]) if pair_side else int(t)
    w = btf.meta.width
    raise BTFFormatError(
        f"{btf.meta.name}: the input has NaN or infinite values (first at texel "
        f"x={texel % w}, y={texel // w}); fix the source before compressing"
    )


def sizes(btf: SVDBTF, factor_bits: int = 0) -> SizeReport:
    """Stored bytes (the float32 U and S·V tables the .btfm holds) against raw 8-bit data as
    the original tool's quantreport.txt counts it (81 × 81 × W × H × 3 bytes). Packed: what
    the factors take at ``factor_bits`` bits each plus a float32 min and max per column (the
    original's "compressed quantized" figure); = stored when 0 (float32)."""
    tables = btf.tables().values()
    stored = sum(int(a.nbytes) for a in tables)
    raw = 81 * 81 * btf.meta.width * btf.meta.height * 3
    if not factor_bits:
        return SizeReport(raw, stored, stored)
    bits = sum(a.size * factor_bits + a.shape[1] * 64 for a in tables)
    return SizeReport(raw, stored, math.ceil(bits / 8))


def quantise_columns(a: np.ndarray, bits: int) -> np.ndarray:
    """(N, K) → the same with each column rounded to 2^bits uniform levels between its min
    and max (a constant column is kept as it is)."""
    lo, hi = a.min(axis=0), a.max(axis=0)
    step = np.where(hi > lo, (hi - lo) / (2**bits - 1), 1.0)
    return np.round((a - lo) / step) * step + lo


def truncate(btf: SVDBTF, ranks: tuple[int, int, int]) -> SVDBTF:
    """The first ``ranks`` components of an encoding: equal to encoding at those ranks (the
    components are the Gram matrix's eigenvectors in decreasing order, whatever K)."""
    k = [max(1, min(int(r), a.shape[1])) for r, a in zip(ranks, btf.u, strict=True)]
    return SVDBTF(
        btf.p,
        [a[:, :r] for a, r in zip(btf.u, k, strict=True)],
        [a[:, :r] for a, r in zip(btf.sv, k, strict=True)],
    )


def measured_psnr(source: BTF, encoded: SVDBTF, texels: np.ndarray) -> float:
    """``metrics.psnr`` of an encoding of ``source`` at its measured pairs, computed from the
    input's samples and the factor tables (matrix products) instead of 2 × pairs × texels
    ``evaluate_angles`` calls: the same numbers (the decode is exact at the samples; both sides
    clamped at 0 as the decoders do), in seconds instead of minutes on 81 × 81 pairs.
    texels: (T,) row-major indices. RGB, peak 255 on the 8-bit scale (a reflectance factor of
    1 = 255); inf when identical."""
    src = samples_of(source)
    pairs = np.arange(src.view_grid.size * src.light_grid.size)
    e = encoded
    sq, count = 0.0, 0
    for first in range(0, len(texels), 256):
        t = np.asarray(texels[first : first + 256])
        a = np.maximum(src.block(pairs, t), 0.0)
        y = np.stack(
            [e.u[c].astype(np.float64) @ e.sv[c][t].T.astype(np.float64) for c in range(3)], -1
        )
        b = np.maximum(e.colour.apply(y), 0.0)
        if not e.p.cosine_in_data:  # value = RGB · cos θi / π: the cosine is part of the error
            theta_i = np.tile(src.light_grid.angles_deg()[0], src.view_grid.size)
            cos_i = np.cos(np.radians(theta_i))[:, None, None]
            a, b = a * cos_i, b * cos_i
        sq += float(np.sum((255.0 * (a - b)) ** 2))
        count += a.size
    mse = sq / count
    return math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)
