"""MLVQ encoder: any BTF → the multi-level vector quantisation that ``core/codecs/mlvq.py`` decodes.

Resampling (the parameterisation grid). The input is evaluated at exactly the samples the
decoder interpolates between, so a sample decodes to the stored value:

* view: θv_j = j·90/(n_theta − 1), decoder azimuth φ'_k = k·360/n_phi, i.e. φv = 360 − φ'_k;
* light (onion slices, relative to the view): β_b = the decoder's β positions
  (``MLVQParams.beta_angles_deg``: uniform in sin β), α_a = −90 + a·180/(n_alpha − 1);
  x = sin β, y = sin α cos β, z = cos α cos β → θi = acos z, φ' = atan2(y, x),
  φi = 360 − φ' − 90 − φ'_k (the decoder's relation inverted);
* texels: every texel centre, rows/columns offset 0.

Values are taken on the decoder's 8-bit scale (raw = value / ``LDR_VALUE_SCALE``); an MLVQ
source with the same grid sizes is read straight from its tables (its own samples, exactly).

Levels, bottom up (sizes are knobs, ``MLVQSettings``), trained on the data of up to
``train_texels`` texels (all of alu's 64²); every other texel is then sampled block by block
and only given its P6 entry (memory: the training texels, not W × H):

1. every 2D function (texel, φv, θv) over (α, β), RGB, normalised to a common mean, is vector
   quantised (k-means, ``k2`` entries);
2. each entry is split as the decoder rebuilds it: BT.601 studio YCbCr; per α the luminance
   column over β = scale × a P1 vector (k-means, ``k1``); (Cb, Cr) per sample quantised to
   ``k_colours`` colours; per α the β-run of colours → ``k_index_ab`` index rows; per entry the
   α-run of index rows → ``k_colour_functions`` rows; the entries are then decoded exactly as
   the decoder does (a 2D function's best decoded entry and least-squares scale are computed
   only where level 3 keeps its θv runs as they are: no more lit runs than ``k3``);
3. per (texel, φv) the θv run of (entry, scale) → ``k3`` P3 rows (k-means on the data,
   centroids re-encoded by the decoded entries);
4. per texel the φv run of (P3 row, scale) → ``k4`` P4 rows, likewise; P6 = the texel's P4 row
   (1-based; 0 for an all-black texel) and its least-squares scale.

Scales may then be quantised (``scale_bits``: uniform between each table's min and max, as the
original tool's ``quantreport.txt`` mode 0); the container stores float32 either way, and the
report counts the bits such a packing needs.

Memory and time (``working_set_bytes``). Every pass over the data goes block by block
(``kmeans.ROW_BLOCK`` values, ``kmeans.BLOCK`` scores). An LDR MLVQ source on the same grid
(re-encoding a BTFbase material such as alu) is never formed: each 2D function is a stored
entry times a scale (``kmeans.FactoredRows``), so products, norms and cluster sums go through
the E entries (parts × E × g × K multiply-adds per product instead of rows × parts × g × K),
and memory grows with the 2D functions' indices and scales (12 bytes each), not with their
values (1452 bytes each). Any other source is sampled once into float32 (162 624 bytes a
training texel at the default grid) and read in blocks; a level's normalised training rows are
copied only up to SAMPLE_ELEMENTS values.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..codecs.mlvq import LDR_VALUE_SCALE, MLVQBTF, MLVQParams
from ..colour import ycbcr_to_rgb
from ..errors import BTFFormatError
from ..model import BTF
from .kmeans import (
    Assign,
    FactoredRows,
    LazyRows,
    kmeans,
    nearest,
    row_block,
    row_stats,
    scaled_rows,
)

#: ``progress(fraction 0..1, what)``; may raise (KeyboardInterrupt, a cancel exception) to stop.
Progress = Callable[[float, str], None]

#: Studio-swing BT.601: RGB = M · (Y − 16, Cb − 128, Cr − 128) (core/colour.py ycbcr_to_rgb).
_M = np.array(
    [
        [1.1643828, 0.0, 1.5960273],
        [1.1643828, -0.39176172, -0.81296875],
        [1.1643828, 2.0172344, 0.0],
    ]
)
_M_INV = np.linalg.inv(_M)
_OFFSET = np.array([16.0, 128.0, 128.0])
#: 2D functions are clustered at this mean RGB (8-bit scale): the luminance then sits well
#: above the studio-swing offset of 16, as in the original's tables.
_NORM_MEAN = 100.0
#: A level's normalised training rows are copied (float32) when they hold at most this many
#: values (256 MB: level 3's 20 000 θv runs × 2541 = 51 M at the defaults); more (level 4's
#: 4096 texels × 40 656 = 166 M on alu) are read normalised block by block at every pass.
SAMPLE_ELEMENTS = 1 << 26


@dataclass(frozen=True)
class MLVQSettings:
    """Codebook sizes, grid and scale quantisation. Defaults land near the original tool's
    ratio on alu (64² texels; its counts: P1 1381, 2D 1645/1723, P3 539, P4 34)."""

    k1: int = 1400
    k2: int = 1700
    k3: int = 540
    k4: int = 34
    k_colours: int = 8
    k_index_ab: int = 16
    k_colour_functions: int = 64
    scale_bits: int = 8
    n_beta: int = 11
    n_alpha: int = 11
    n_theta: int = 7
    n_phi: int = 16
    seed: int = 0
    iterations: int = 8
    train: int = 20000
    #: Training rows per codeword at least (0: ``train`` alone): a codebook of 36 000 entries
    #: needs more than 20 000 rows. Rows per k-means = max(train, train_per_code × k).
    train_per_code: int = 0
    #: Texels whose data trains the codebooks (a seeded sample; 0 = all). The rest are only
    #: assigned a P4 row and scale, block by block: memory is bounded by this, not by W × H.
    train_texels: int = 4096
    block_texels: int = 1024

    def train_rows(self, k: int) -> int:
        """Rows a k-means of ``k`` centres trains on."""
        return max(self.train, self.train_per_code * k)

    def __post_init__(self) -> None:
        for name in ("k1", "k2", "k3", "k4", "k_colours", "k_index_ab", "k_colour_functions"):
            if getattr(self, name) < 1:
                raise BTFFormatError(f"MLVQ encoder: {name} must be at least 1")
        if self.iterations < 0 or self.train_per_code < 0:
            raise BTFFormatError("MLVQ encoder: iterations and train_per_code must not be negative")
        if not (self.scale_bits == 0 or 2 <= self.scale_bits <= 16):
            raise BTFFormatError("MLVQ encoder: scale_bits must be 0 (float32) or 2..16")
        if self.n_beta < 3 or self.n_alpha < 2 or self.n_theta < 2 or self.n_phi < 1:
            raise BTFFormatError("MLVQ encoder: grid needs n_beta ≥ 3, n_alpha ≥ 2, n_theta ≥ 2")


@dataclass
class EncodeStats:
    seconds: float
    counts: dict[str, int]


def working_set_bytes(n_texels: int, s: MLVQSettings, n_entries: int | None = None) -> int:
    """A bound on the bytes of numpy arrays ``encode_mlvq`` holds at once (as tracemalloc
    counts them) for ``n_texels`` training texels, from its own block constants.

    ``n_entries``: the source is an LDR MLVQ material on the encoder's grid with that many P2
    entries, read as :class:`FactoredRows` (nothing of size texels × grid is formed); None:
    any other source, whose grid samples are formed (texels × 162 624 bytes at the default
    grid) plus up to SAMPLE_ELEMENTS float32 of one level's training copy; the source's own
    ``evaluate_angles`` temporaries are not counted. Terms, generous: per 2D function (texel ×
    φv × θv) 96 bytes (entry, scale, mean, maximum, weights and their temporaries); the
    entries 64 bytes a value; per level K × D × 48 (centres, unit centres, float64 sums, decoded
    rows: all levels at once); the largest factored product (parts × E × K float32, twice);
    training-row factors and their sort keys (rows × parts × 48); four score blocks of BLOCK
    float32 and four data blocks of ROW_BLOCK float64."""
    from . import kmeans as km

    g2 = s.n_alpha * s.n_beta * 3
    rows2 = n_texels * s.n_phi * s.n_theta
    levels = [  # (rows, parts, k): level 2's 2D functions, level 3's θv runs, level 4's texels
        (rows2, 1, s.k2),
        (n_texels * s.n_phi, s.n_theta, s.k3),
        (n_texels, s.n_phi * s.n_theta, s.k4),
    ]
    entries = n_entries if n_entries is not None else max(s.k2, 1)
    codebooks = sum(min(k, n) * parts * g2 * 48 for n, parts, k in levels)
    codebooks += (s.k1 * s.n_beta + s.k2 * g2) * 8 * 8  # the P1 / colour split (float64)
    products = max(parts * entries * min(k, n) * 4 * 2 for n, parts, k in levels)
    training = max(min(n, s.train_rows(k)) * parts * 48 for n, parts, k in levels)
    blocks = 4 * km.BLOCK * 4 + 4 * km.ROW_BLOCK * 8
    total = rows2 * 96 + entries * g2 * 64 + codebooks + products + training + blocks
    if n_entries is None:
        grid = rows2 * g2 * 4
        sample = max(
            min(min(n, s.train_rows(k)) * parts * g2, SAMPLE_ELEMENTS) for n, parts, k in levels
        )
        total += grid + 2 * sample * 4
    return int(total)


def grid_params(btf: BTF, s: MLVQSettings, name: str | None = None) -> MLVQParams:
    return MLVQParams(
        n_beta=s.n_beta,
        n_alpha=s.n_alpha,
        n_theta=s.n_theta,
        n_phi=s.n_phi,
        use_cos_beta=True,
        rows_offset=0,
        cols_offset=0,
        hdr_value=1.0,
        n_views=btf.meta.n_views or 81,
        n_lights=btf.meta.n_lights or 81,
        name=name or btf.meta.name,
    )


def sample_grid(
    btf: BTF,
    p: MLVQParams,
    progress: Progress | None = None,
    texels: np.ndarray | None = None,
) -> np.ndarray:
    """The input on the MLVQ grid: (T, n_phi, n_theta, n_alpha, n_beta, 3) float32, raw
    8-bit scale, for ``texels`` (row-major indices; default all H·W). Raises BTFFormatError
    for non-finite values."""
    if texels is None:
        texels = np.arange(btf.meta.width * btf.meta.height)
    if _same_grid(btf, p):
        values = _mlvq_grid_values(btf, texels)
    else:
        values = _evaluate_grid(btf, p, progress, texels)
    check_finite(values, btf)
    return np.maximum(values, 0.0, out=values)


def check_finite(values: np.ndarray, btf: BTF) -> None:
    """One clear error for NaN or infinite samples (texels first axis), naming the texel."""
    bad = ~np.isfinite(values)
    if bad.any():
        t = int(np.argwhere(bad)[0][0])
        w = btf.meta.width
        raise BTFFormatError(
            f"{btf.meta.name}: the input has NaN or infinite values (first at texel "
            f"x={t % w}, y={t // w}); fix the source before compressing"
        )


def _same_grid(btf: BTF, p: MLVQParams) -> bool:
    if not isinstance(btf, MLVQBTF) or btf.p.hdr or not btf.p.use_cos_beta:
        return False
    q = btf.p
    return (q.n_beta, q.n_alpha, q.n_theta, q.n_phi) == (p.n_beta, p.n_alpha, p.n_theta, p.n_phi)


def _entry_rgb(t: dict[str, np.ndarray]) -> np.ndarray:
    """Every P2 entry at its own samples: (n_entries, n_alpha, n_beta, 3) float64."""
    lum_fn = t["pdf2_indices"][:, 0]
    col_fn = t["pdf2_indices"][:, 1]
    lum = t["pdf2_scale"][lum_fn][:, :, None] * t["pdf1"][t["pdf2_slices"][lum_fn]]
    ab = t["ab_colors"][t["index_ab"][t["pdf2_colours"][col_fn]]]  # (n, α, β, 2)
    return ycbcr_to_rgb(lum.astype(np.float64), ab[..., 0], ab[..., 1])


def _mlvq_factors(
    btf: MLVQBTF, texels: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An LDR MLVQ material at its own samples as factors: every P2 entry (E, n_alpha,
    n_beta, 3) float32, and per (texel, φv, θv) of ``texels`` (row-major; default all) the
    entry (T, n_phi, n_theta) int64 and its scale (T, n_phi, n_theta) float32; the value is
    entry × scale."""
    t, p = btf.t, btf.p
    h, w = t["pdf6_slices"].shape
    if texels is None:
        texels = np.arange(h * w)
    y = (texels // w - p.rows_offset) % h
    x = (texels % w - p.cols_offset) % w
    slot = t["pdf6_slices"][y, x].ravel().astype(np.int64) - 1
    s6 = t["pdf6_scale"][y, x].ravel() * (slot >= 0)
    slot = np.maximum(slot, 0)
    idx3 = t["pdf4_slices"][slot]  # (T, φ)
    s4 = t["pdf4_scale"][slot]
    idx2 = t["pdf3_slices"][idx3].astype(np.int64)  # (T, φ, θ)
    s3 = t["pdf3_scale"][idx3]
    entries = _entry_rgb(t).astype(np.float32)
    scale = (s6[:, None, None] * s4[:, :, None] * s3).astype(np.float32)
    return entries, idx2, scale


def _mlvq_grid_values(btf: MLVQBTF, texels: np.ndarray | None = None) -> np.ndarray:
    """An LDR MLVQ material's values at its own samples, straight from its tables, for
    ``texels`` (row-major; default all)."""
    entries, idx2, scale = _mlvq_factors(btf, texels)
    return entries[idx2] * scale[..., None, None, None]


#: ``rows(parts)``: the input on the MLVQ grid as (T · n_phi · n_theta / parts, parts · n_alpha ·
#: n_beta · 3) float32 rows, ``parts`` consecutive 2D functions per row (1: level 2's 2D
#: functions, n_theta: level 3's θv runs, n_phi · n_theta: level 4's texels).
GridRows = Callable[[int], "np.ndarray | LazyRows"]


def grid_rows(
    btf: BTF, p: MLVQParams, texels: np.ndarray, progress: Progress | None = None
) -> GridRows:
    """``texels`` of the input on the MLVQ grid, as :data:`GridRows`, equal to
    ``sample_grid(btf, p, progress, texels)`` reshaped.

    An LDR MLVQ source on the same grid stays in its tables: :class:`FactoredRows` (entries
    clamped at 0 times non-negative scales; with a negative scale, :class:`LazyRows` whose
    blocks are formed entry × scale when read), so nothing of size T × n_phi × n_theta ×
    n_alpha × n_beta × 3 is formed. Any other source is sampled once into that float32 array
    (``sample_grid``): 4 × 16 × 7 × 11 × 11 × 3 = 162 624 bytes a texel at the default
    grid."""
    if _same_grid(btf, p):
        entries, idx2, scale = _mlvq_factors(btf, texels)
        flat_entries = entries.reshape(len(entries), -1)
        finite = np.isfinite(flat_entries).all() and np.isfinite(scale).all()
        # A product past float32's range would be infinite where the array is not: refused
        # by the array path (check_finite) with the texel named.
        if finite and float(np.abs(flat_entries).max(initial=0.0)) * float(
            np.abs(scale).max(initial=0.0)
        ) < float(np.finfo(np.float32).max):
            if (scale >= 0).all():  # max(e · s, 0) = max(e, 0) · s: factored rows
                return _factored_rows(np.maximum(flat_entries, 0.0), idx2.ravel(), scale.ravel())
            return _table_rows(flat_entries, idx2.ravel(), scale.ravel())
    values = sample_grid(btf, p, progress, texels)
    g = values[0, 0, 0].size if len(values) else p.n_alpha * p.n_beta * 3

    def rows(parts: int) -> np.ndarray:
        return values.reshape(-1, parts * g)

    return rows


def _factored_rows(entries: np.ndarray, idx: np.ndarray, scale: np.ndarray) -> GridRows:
    """:data:`GridRows` of 2D functions ``entries[idx] * scale`` (entries ≥ 0, scales ≥ 0)
    as :class:`FactoredRows`: products go through the entries, rows are never formed."""

    def rows(parts: int) -> FactoredRows:
        return FactoredRows(entries, idx.reshape(-1, parts), scale.reshape(-1, parts))

    return rows


def _table_rows(entries: np.ndarray, idx: np.ndarray, scale: np.ndarray) -> GridRows:
    """:data:`GridRows` of 2D functions ``entries[idx] * scale`` (clamped at 0, as
    ``sample_grid``), computed on demand."""
    g = entries.shape[1]

    def rows(parts: int) -> LazyRows:
        offsets = np.arange(parts, dtype=np.int64)

        def get(index: np.ndarray) -> np.ndarray:
            flat = (index[:, None] * parts + offsets).reshape(-1)
            out = entries[idx[flat]]
            out *= scale[flat, None]
            np.maximum(out, 0.0, out=out)
            return out.reshape(len(index), parts * g)

        return LazyRows(len(idx) // parts, parts * g, get)

    return rows


def _evaluate_grid(
    btf: BTF, p: MLVQParams, progress: Progress | None, texels: np.ndarray | None = None
) -> np.ndarray:
    w, h = btf.meta.width, btf.meta.height
    if texels is None:
        texels = np.arange(h * w)
    theta_v = np.arange(p.n_theta) * (90.0 / (p.n_theta - 1))
    phi_dec = np.arange(p.n_phi) * (360.0 / p.n_phi)
    beta = np.radians(p.beta_angles_deg())
    alpha = np.radians(-90.0 + np.arange(p.n_alpha) * (180.0 / (p.n_alpha - 1)))
    a, b = np.meshgrid(alpha, beta, indexing="ij")  # (α, β)
    x, y, z = np.sin(b), np.sin(a) * np.cos(b), np.cos(a) * np.cos(b)
    theta_i = np.degrees(np.arccos(np.clip(z, -1.0, 1.0))).ravel()
    light_phi = np.degrees(np.arctan2(y, x)).ravel()
    n_light = len(theta_i)
    uv = np.column_stack([(texels % w + 0.5) / w, (texels // w + 0.5) / h])
    n_tex = len(texels)
    out = np.empty((n_tex, p.n_phi, p.n_theta, p.n_alpha, p.n_beta, 3), dtype=np.float32)
    for k, phi_k in enumerate(phi_dec):
        if progress is not None:
            progress(k / p.n_phi, "sampling the input on the MLVQ grid")
        phi_i = np.mod(360.0 - light_phi - 90.0 - phi_k, 360.0)
        for j, tv in enumerate(theta_v):
            q = np.empty((n_tex * n_light, 6))
            q[:, :2] = np.repeat(uv, n_light, axis=0)
            q[:, 2] = np.tile(theta_i, n_tex)
            q[:, 3] = np.tile(phi_i, n_tex)
            q[:, 4] = tv
            q[:, 5] = np.mod(360.0 - phi_k, 360.0)
            values = btf.evaluate_angles(q) / LDR_VALUE_SCALE
            out[:, k, j] = values.reshape(n_tex, p.n_alpha, p.n_beta, 3)
    return out


def encode_mlvq(
    btf: BTF,
    settings: MLVQSettings = MLVQSettings(),
    progress: Progress | None = None,
    name: str | None = None,
    assign: Assign | None = None,
) -> tuple[MLVQBTF, EncodeStats]:
    """Compress ``btf`` → an ``MLVQBTF`` (LDR, 8-bit scale values) and its statistics.

    ``assign``: the nearest-codeword step of every level (default ``kmeans.nearest``, numpy);
    ``cl.encoder_assign.opencl_assign_or_none()`` gives the OpenCL one.

    Memory (:func:`working_set_bytes`): the grid samples of the training texels (none for an
    MLVQ source on the same grid: :func:`grid_rows`), each level's normalised training copy
    when it has at most SAMPLE_ELEMENTS values (else it is read normalised block by block),
    the codebooks, and blocks of ``kmeans.ROW_BLOCK`` / ``kmeans.BLOCK`` elements."""
    device = nearest if assign is None else assign

    def assign(x, centres, scale_free):
        # Factored rows are cheaper through their table than any product over formed rows.
        if isinstance(x, FactoredRows) and x.factored(len(centres)):
            return nearest(x, centres, scale_free)
        return device(x, centres, scale_free)

    start = time.perf_counter()
    s = settings
    rng = np.random.default_rng(s.seed)
    p = grid_params(btf, s, name)

    last = [0.0, ""]

    def step(fraction: float, what: str) -> None:
        last[:] = [fraction, what]
        if progress is not None:
            progress(fraction, what)

    def cancel() -> None:
        step(*last)  # no new progress: the caller's chance to raise between k-means steps

    h, w = btf.meta.height, btf.meta.width
    if s.train_texels <= 0 or h * w <= s.train_texels:
        train_texels = np.arange(h * w)
    else:
        train_texels = np.sort(rng.choice(h * w, s.train_texels, replace=False))
    grid = grid_rows(btf, p, train_texels, lambda f, w: step(0.25 * f, w))
    x2 = grid(1)  # (T·φ·θ, α·β·3): the 2D functions
    x3 = grid(s.n_theta)  # (T·φ, θ·α·β·3): the θv runs
    x4 = grid(s.n_phi * s.n_theta)  # (T, φ·θ·α·β·3): the texels

    step(0.25, "level 2: clustering 2D functions")
    mean2, _ = row_stats(x2)
    lit = mean2 > 0
    train_rows = np.flatnonzero(lit)
    if len(train_rows) == 0:
        train_rows = np.arange(1)
    norm = np.where(lit, _NORM_MEAN / np.where(lit, mean2, 1.0), 0.0).astype(np.float32)
    sample = train_rows
    if len(sample) > s.train_rows(s.k2):
        sample = np.sort(rng.choice(train_rows, s.train_rows(s.k2), replace=False))
    if isinstance(x2, FactoredRows):
        training = x2.subset(sample, norm[sample])
    else:
        training = np.asarray(x2[sample], dtype=np.float32)
        training *= norm[sample, None]
    del mean2, norm
    centres2, _ = kmeans(
        training, s.k2, rng, s.iterations, s.train_rows(s.k2), cancel, assign, labels=False
    )
    del training
    if not lit.any():
        centres2[:] = 0.0
    del lit

    step(0.45, "level 1: luminance slices and colours")
    t = _split_entries(centres2.reshape(-1, s.n_alpha, s.n_beta, 3), s, rng, cancel, assign)
    decoded2 = _entry_rgb(t).reshape(len(centres2), -1).astype(np.float32)

    # Level 2's assignment of every 2D function is only read where level 3 keeps its
    # instances as they are (no more lit θv runs than k3): encoded there, for those rows.
    step(0.65, "level 3: clustering θv runs")
    p3_idx, p3_scale, decoded3 = _level(x3, s.n_theta, decoded2, s.k3, s, rng, cancel, assign)
    t["pdf3_slices"], t["pdf3_scale"] = p3_idx, p3_scale

    step(0.8, "level 4: clustering φv runs")
    p4_idx, p4_scale, decoded4 = _level(x4, s.n_phi, decoded3, s.k4, s, rng, cancel, assign)
    t["pdf4_slices"], t["pdf4_scale"] = p4_idx, p4_scale
    del decoded3

    step(0.82, "level 6: assigning texels")
    idx4, s6 = assign(x4, decoded4, True)
    _, peak4 = row_stats(x4)
    black = ~(peak4 > 0)
    slots = np.zeros(h * w, dtype=np.int32)
    scales = np.zeros(h * w, dtype=np.float32)
    slots[train_texels] = np.where(black, 0, idx4 + 1)
    scales[train_texels] = np.where(black, 0.0, s6)
    del grid, x2, x3, x4
    rest = np.setdiff1d(np.arange(h * w), train_texels)
    for first in range(0, len(rest), s.block_texels):  # not `start`: that is the clock
        step(0.85 + 0.1 * first / len(rest), "level 6: texels outside the training sample")
        block = rest[first : first + s.block_texels]
        x = grid_rows(btf, p, block)(s.n_phi * s.n_theta)
        idx, scale = assign(x, decoded4, True)
        _, peak = row_stats(x)
        lit = peak > 0
        slots[block] = np.where(lit, idx + 1, 0)
        scales[block] = np.where(lit, scale, 0.0)
        del x
    del decoded4
    t["pdf6_slices"] = slots.reshape(h, w)
    t["pdf6_scale"] = scales.reshape(h, w)

    step(0.95, "quantising scales")
    if s.scale_bits:
        for name_ in ("pdf1", "ab_colors", "pdf2_scale", "pdf3_scale", "pdf4_scale", "pdf6_scale"):
            t[name_] = quantise(t[name_], s.scale_bits)
    # The MLVQ codec has no slot for a tile size (its parameters are the original tool's).
    out = MLVQBTF(p, t, source=f"{p.name} (encoded)")
    counts = {k: int(v.shape[0]) for k, v in t.items() if not k.startswith("pdf6")}
    step(1.0, "done")
    return out, EncodeStats(time.perf_counter() - start, counts)


def _level(x, parts, decoded_below, k, s, rng, cancel, assign):
    """One upper level: instances ``x`` (N, parts·D) (an array or LazyRows). Clusters the
    normalised data, re-encodes each centre part by part on ``decoded_below`` (K_below, D).
    Returns the rows (indices int32, scales float32) and the decoded rows (K, parts·D)
    float32.

    The training rows (lit instances, at most ``train_rows(k)``, each scaled to a mean of
    _NORM_MEAN) are copied when they hold at most SAMPLE_ELEMENTS values, else read through
    ``scaled_rows`` block by block. With no more lit instances than ``k`` they are the
    codebook themselves, encoded part by part on ``decoded_below``."""
    mean, _ = row_stats(x)
    lit = np.flatnonzero(mean > 0)
    if len(lit) == 0:
        lit = np.arange(1)
    n_pick = s.train_rows(k)
    pick = lit if len(lit) <= n_pick else np.sort(rng.choice(lit, n_pick, replace=False))
    norm = (_NORM_MEAN / np.maximum(mean[pick], 1e-30)).astype(np.float32)
    del mean
    if len(lit) <= k:
        # Few instances: their own (already encoded) rows are the codebook, exactly.
        # Identical instances (a constant material) share one row.
        idx_below, scale_below = _encode_parts(x, pick, parts, decoded_below, assign)
        pairs = np.concatenate([idx_below, scale_below.astype(np.float32)], axis=1)
        pairs = np.unique(pairs.astype(np.float64), axis=0)
        rows_idx = pairs[:, :parts].astype(np.int32)
        rows_scale = pairs[:, parts:].astype(np.float32)
    else:
        if not isinstance(x, FactoredRows) and len(pick) * x.shape[1] <= SAMPLE_ELEMENTS:
            sample = np.asarray(x[pick], dtype=np.float32)
            sample *= norm[:, None]
        else:
            sample = scaled_rows(x, pick, norm)
        centres, _ = kmeans(sample, k, rng, s.iterations, n_pick, cancel, assign, labels=False)
        del sample
        parts_c = centres.reshape(len(centres) * parts, -1)
        ri, rs = assign(parts_c, decoded_below, True)
        rows_idx = ri.reshape(len(centres), parts).astype(np.int32)
        rows_scale = rs.reshape(len(centres), parts).astype(np.float32)
    cancel()
    decoded = decoded_below[rows_idx] * rows_scale[..., None]
    decoded = decoded.reshape(len(rows_idx), -1).astype(np.float32)
    return rows_idx, rows_scale, decoded


def _encode_parts(x, rows, parts, decoded_below, assign):
    """Rows ``rows`` of ``x`` (N, parts·D) encoded part by part on ``decoded_below``
    (K, D): (indices (len(rows), parts) int64, least-squares scales float64), a block of
    rows at a time."""
    d = x.shape[1] // parts
    idx = np.empty((len(rows), parts), dtype=np.int64)
    scale = np.empty((len(rows), parts), dtype=np.float64)
    step = row_block(x.shape[1])
    for first in range(0, len(rows), step):
        block = np.asarray(x[rows[first : first + step]], dtype=np.float32).reshape(-1, d)
        i, sc = assign(block, decoded_below, True)
        idx[first : first + step] = i.reshape(-1, parts)
        scale[first : first + step] = sc.reshape(-1, parts)
    return idx, scale


def _split_entries(entries, s: MLVQSettings, rng, cancel, assign: Assign) -> dict[str, np.ndarray]:
    """2D RGB entries (K, α, β, 3) on the 8-bit scale → the P1/colour/P2 tables."""
    k, na, nb, _ = entries.shape

    def km(data: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        return kmeans(data, n, rng, s.iterations, s.train_rows(n), cancel, assign)

    ycc = np.einsum("ij,kabj->kabi", _M_INV, entries.astype(np.float64)) + _OFFSET
    lum = ycc[..., 0].reshape(k * na, nb)
    peak = np.abs(lum).max(axis=1)
    shapes = np.where(peak[:, None] > 0, lum / np.where(peak > 0, peak, 1.0)[:, None], 0.0)
    pdf1, _ = km(shapes.astype(np.float32), s.k1)
    slices, lum_scale = assign(lum.astype(np.float32), pdf1, True)

    ab = ycc[..., 1:].reshape(-1, 2).astype(np.float32)
    colours, _ = km(ab, s.k_colours)
    runs = ycc[..., 1:].reshape(k * na, nb * 2).astype(np.float32)
    run_centres, _ = km(runs, s.k_index_ab)
    index_ab, _ = assign(run_centres.reshape(-1, 2), colours, False)
    index_ab = index_ab.reshape(len(run_centres), nb)
    decoded_runs = colours[index_ab].reshape(len(index_ab), nb * 2)
    run_of, _ = assign(runs, decoded_runs, False)
    colour_rows = run_of.reshape(k, na)
    flat = decoded_runs[colour_rows].reshape(k, -1)
    fn_centres, _ = km(flat, s.k_colour_functions)
    fn_rows, _ = assign(fn_centres.reshape(-1, nb * 2), decoded_runs, False)
    fn_rows = fn_rows.reshape(len(fn_centres), na)
    col_fn, _ = nearest(flat, decoded_runs[fn_rows].reshape(len(fn_rows), -1))
    return {
        "pdf1": pdf1.astype(np.float32),
        "ab_colors": colours.astype(np.float32),
        "index_ab": index_ab.astype(np.int32),
        "pdf2_colours": fn_rows.astype(np.int32),
        "pdf2_slices": slices.reshape(k, na).astype(np.int32),
        "pdf2_scale": lum_scale.reshape(k, na).astype(np.float32),
        "pdf2_indices": np.column_stack([np.arange(k), col_fn]).astype(np.int32),
    }


def quantise(a: np.ndarray, bits: int) -> np.ndarray:
    """Uniform quantisation to 2^bits levels between the table's min and max (float32)."""
    lo, hi = float(a.min()), float(a.max())
    if hi <= lo:
        return a.astype(np.float32)
    step = (hi - lo) / (2**bits - 1)
    return (np.round((a - lo) / step) * step + lo).astype(np.float32)
