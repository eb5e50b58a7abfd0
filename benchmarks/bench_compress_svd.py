"""SVD encoder (issue 16): rank against ratio, PSNR, SSIM, encode time and numpy decode
throughput, on a synthetic BTF and on the shared BTFbase materials decoded onto their measured
UBO2003 grid (81 × 81 pairs) and re-encoded (``--real alu wallpaper``; wallpaper takes many
minutes and about 2 GB: run it alone, once).

One encode per input at the largest rank; the smaller ranks are its leading components
(``encoders.svd.truncate``: exactly what an encode at that rank stores, since the components
are the Gram matrix's eigenvectors in decreasing order). The encode time is therefore the same
for every rank of an input (the full eigendecomposition dominates, not K); one real encode at
the smallest rank is timed beside it to show so.

PSNR: RGB, peak 255 on the 8-bit scale, input against encoding at the 81 × 81 measured pairs,
at every texel (synthetic) or 256 seeded texels (real), computed from the input's samples and
the factor tables (``encoders.svd.measured_psnr``: ``metrics.psnr``'s number, tested equal,
without 2 × 1.7 M numpy decodes per row). SSIM: ``metrics.ssim`` (32 seeded
pairs, the top-left 64 × 64 texels, 7 × 7 windows). Ratio: raw 8-bit = 81 × 81 × W × H × 3
bytes as the original tool's quantreport.txt, against the float32 tables the .btfm stores
("stored") and against 8-bit factors with a float32 min/max per column ("8-bit packed", what
``--factor-bits 8`` gives; the original's "compressed quantized" figure, 1002 for alu).
For a BTFbase material the input is the decoded original material, not the raw UBO2003 images.

Usage: python benchmarks/bench_compress_svd.py [--real alu wallpaper] [--no-synthetic]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import SHARED_BTFBASE, decode_rate, table

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.dense import DenseBTF, tabulate
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.svd import SVDBTF
from btf_addon.core.encoders import metrics
from btf_addon.core.encoders.svd import (
    SVDSettings,
    encode_svd,
    measured_psnr,
    quantise_columns,
    sizes,
    truncate,
)

HEADERS = [
    "input",
    "colour",
    "ranks",
    "stored ratio",
    "PSNR dB",
    "8-bit packed ratio",
    "8-bit PSNR dB",
    "SSIM",
    "encode s",
    "decode Mq/s",
]
RANKS = ((1, 1, 1), (2, 1, 1), (4, 2, 2), (8, 4, 4), (16, 8, 8), (32, 16, 16), (64, 32, 32))


def synthetic(size: int = 16) -> DenseBTF:
    """GGX on UBO2003 whose roughness varies along x (0.15…0.6, one per column) with a tinted
    brightness ramp along y: a spectrum that decays over many components, unlike the MLVQ
    benchmark's single tinted BRDF (rank 1 per RGB channel)."""
    ys = np.arange(size)
    columns = [
        tabulate(GGXBTF(albedo=(0.55, 0.35, 0.2), roughness=r), width=1, height=1).data[
            ..., 0, 0, :
        ]
        for r in np.linspace(0.15, 0.6, size)
    ]
    base = np.stack(columns, axis=2)[:, :, None]  # (81, 81, 1, size, 3)
    ramp = (0.4 + 0.6 * ys / (size - 1))[:, None, None] * np.array([1.0, 0.9, 1.2])
    return DenseBTF(base * ramp[None, None], name=f"synthetic {size}²")


def rows_for(name: str, src, colour: str, ranks_list, texels: int, time_low: bool = True):
    top = ranks_list[-1]
    enc, stats = encode_svd(src, SVDSettings(ranks=top, colour_space=colour))
    print(f"{name}: encode at {top} in {stats.seconds:.1f} s ({stats.gram_side} Gram)", flush=True)
    subset = metrics.texel_subset(src.meta.width, src.meta.height, texels)
    out = []
    for ranks in ranks_list:
        e = truncate(enc, ranks)
        # --factor-bits 8 quantises each column after the fit: the same as quantising here.
        e8 = SVDBTF(e.p, *([quantise_columns(a, 8) for a in f] for f in (e.u, e.sv)))
        out.append(
            [
                name,
                colour,
                "/".join(str(k) for k in e.ranks),
                sizes(e).stored_ratio,
                measured_psnr(src, e, subset),
                sizes(e8, 8).packed_ratio,
                measured_psnr(src, e8, subset),
                metrics.ssim(src, e),
                stats.seconds,
                decode_rate(e, 100_000),
            ]
        )
        print(table(HEADERS, out[-1:]), flush=True)
    if not time_low:
        return out
    low = ranks_list[0]
    t0 = time.perf_counter()
    encode_svd(src, SVDSettings(ranks=low, colour_space=colour))
    print(f"{name}: a real encode at {low}: {time.perf_counter() - t0:.1f} s", flush=True)
    return out


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser()
    parser.add_argument("--real", nargs="*", default=[])
    parser.add_argument("--no-synthetic", action="store_true")
    args = parser.parse_args(argv)
    rows = []
    if not args.no_synthetic:
        src = synthetic()
        for colour in ("yuv", "rgb"):
            rows += rows_for(src.meta.name, src, colour, RANKS[:5], 0)
    for name in args.real:
        folder = SHARED_BTFBASE / name
        if not folder.is_dir():
            print(f"skipping {name}: {folder} not found")
            continue
        src = MLVQBTF.from_directory(folder)
        rows += rows_for(f"{name} (UBO2003 grid)", src, "yuv", RANKS, 256, name != "wallpaper")
    return table(HEADERS, rows)


if __name__ == "__main__":
    print(main())
