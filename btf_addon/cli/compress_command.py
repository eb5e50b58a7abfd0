"""``compress INPUT -o OUT.btfm --codec mlvq|svd``: any BTF → our own MLVQ or svd encoding
(issue 16; svd: ``--rank N[,N,N] --colour-space rgb|yuv``, core/encoders/svd.py).

Prints one JSON report on stdout: sizes and ratios (raw = 81 × 81 × W × H × 3 bytes, as the
original tool's quantreport.txt), RGB PSNR against the input at the UBO2003 measured directions
(at ``--psnr-texels`` seeded texels; 0 = all), an SSIM of the texel images at 32 seeded
directions (``metrics.ssim``), encode time, codebook sizes or ranks. A progress bar goes
to stderr. The output is written once, atomically, after encoding: Ctrl-C at any point leaves
no file (and no temporary) behind.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import asdict
from pathlib import Path

from ..cl.encoder_assign import opencl_assign_or_none
from ..core import memory
from ..core.encoders import metrics
from ..core.encoders.mlvq import MLVQSettings, encode_mlvq
from ..core.encoders.svd import COLOUR_SPACES, SVDSettings, encode_svd, memory_bound
from ..core.encoders.svd import sizes as svd_sizes
from ..core.errors import BTFError
from ..core.fileio import check_output
from ..core.formats.container import SUFFIX, write_container
from ..core.formats.load import load_btf
from .accuracy_command import ProgressBar

#: Bytes per texel at the encoder's peak: the grid samples (16 × 7 × 11 × 11 × 3 float32 at
#: the default grid), a normalised training copy and the per-level assignment buffers.
_GRID_VALUES = 16 * 7 * 11 * 11 * 3 * 4


def add_parser(sub) -> None:
    p = sub.add_parser("compress", help="compress a BTF to MLVQ or svd (.btfm), report size/PSNR")
    p.add_argument("src", help="input: BTFbase material folder or .btfm container (any codec)")
    p.add_argument("-o", "--out", required=True, type=Path, help="output .btfm")
    p.add_argument("--codec", choices=["mlvq", "svd"], default="mlvq", help="target codec")
    p.add_argument(
        "--rank",
        default=",".join(str(k) for k in SVDSettings().ranks),
        help="svd: components kept, one for every channel or three (N,N,N); default 16,8,8",
    )
    p.add_argument(
        "--colour-space",
        choices=list(COLOUR_SPACES),
        default=SVDSettings().colour_space,
        help="svd: factorise R, G, B or decorrelated Y, U, V (the codec's colour models 0/1)",
    )
    p.add_argument(
        "--factor-bits",
        type=int,
        default=0,
        help="svd: quantise each factor column to this many bits (0: float32); the report's "
        "packed ratio counts them so",
    )
    d = MLVQSettings()
    for flag, field, what in (
        ("--k1", "k1", "P1 luminance slices over beta"),
        ("--k2", "k2", "2D functions over (alpha, beta)"),
        ("--k3", "k3", "P3 rows over theta_v"),
        ("--k4", "k4", "P4 rows over phi_v"),
        ("--colours", "k_colours", "(Cb, Cr) colours"),
        ("--index-ab", "k_index_ab", "colour runs over beta"),
        ("--colour-functions", "k_colour_functions", "colour runs over alpha"),
        ("--scale-bits", "scale_bits", "bits per stored scale (0: float32, unquantised)"),
        ("--seed", "seed", "random seed (the encoding is deterministic for a seed)"),
        (
            "--train-texels",
            "train_texels",
            "texels that train the codebooks (0: all); the "
            "rest are assigned block by block, so memory follows this, not the texel count",
        ),
        (
            "--train-per-code",
            "train_per_code",
            "k-means training rows per codeword at least (0: the fixed training subsample)",
        ),
        ("--iterations", "iterations", "Lloyd steps per k-means"),
    ):
        p.add_argument(flag, dest=field, type=int, default=getattr(d, field), help=f"{what}")
    p.add_argument(
        "--psnr-texels",
        type=int,
        default=256,
        help="texels at which PSNR is measured (seeded sample; 0 = all, slow on large BTFs)",
    )
    p.add_argument("--no-psnr", action="store_true", help="skip the PSNR measurement")
    p.set_defaults(func=cmd_compress)


def estimate(width: int, height: int) -> memory.Estimate:
    """The encoder's peak for ``width × height`` training texels."""
    return memory.Estimate(
        f"compressing with {width * height} training texels",
        3 * width * height * _GRID_VALUES,
        "train on fewer texels (--train-texels)",
    )


def _ranks(text: str) -> tuple[int, ...]:
    """``N`` or ``N,N,N`` → ranks (SVDSettings checks their values)."""
    try:
        ranks = tuple(int(v) for v in text.split(","))
    except ValueError:
        ranks = ()
    if len(ranks) not in (1, 3):
        raise BTFError(f"--rank {text!r}: give one integer or three, N,N,N")
    return ranks * 3 if len(ranks) == 1 else ranks


def cmd_compress(args) -> int:
    out = args.out if args.out.suffix else args.out.with_suffix(SUFFIX)
    check_output(out)  # before an encode of minutes, not after it
    memory.require(memory.btf_load(args.src))
    src = load_btf(args.src)
    if args.codec == "svd":
        return _compress_svd(args, src, out)
    n_train = src.meta.width * src.meta.height
    if args.train_texels > 0:
        n_train = min(n_train, args.train_texels)
    memory.require(estimate(n_train, 1) + memory.btf_load(args.src))
    settings = MLVQSettings(
        **{
            k: getattr(args, k)
            for k in (
                "k1",
                "k2",
                "k3",
                "k4",
                "k_colours",
                "k_index_ab",
                "k_colour_functions",
                "scale_bits",
                "seed",
                "train_texels",
                "train_per_code",
                "iterations",
            )
        }
    )
    bar = ProgressBar()
    try:
        assign = opencl_assign_or_none()  # a GPU's OpenCL step, else numpy
        encoded, stats = encode_mlvq(src, settings, bar, assign=assign)
        if not args.no_psnr:
            bar(1.0, "measuring PSNR")
    finally:
        bar.close()
    return write_and_report(out, encoded, report_json(src, encoded, stats, settings, args))


def write_and_report(out: Path, encoded, report: dict) -> int:
    """Write the encoding (atomically: Ctrl-C before this leaves no file) and print the
    report with the file's name and size."""
    write_container(out, encoded)
    report["output"] = str(out)
    report["file_bytes"] = out.stat().st_size
    # The ratio that means the file on disk (the compact .btfm): the measured data at 8 bits
    # (BTFbase's count, raw_bytes) over the file's bytes. stored_ratio counts the tables in
    # memory, packed_ratio what the original tool's quantreport.txt counts.
    report["file_ratio"] = round(report["raw_bytes"] / report["file_bytes"], 3)
    json.dump(report, sys.stdout, indent=1)
    sys.stdout.write("\n")
    return 0


def report_json(src, encoded, stats, settings: MLVQSettings, args) -> dict:
    size = metrics.sizes(encoded, settings.scale_bits)
    report = {
        "input": str(args.src),
        "codec": "mlvq",
        "texels": [src.meta.width, src.meta.height],
        "settings": asdict(settings),
        "codebooks": stats.counts,
        "encode_seconds": round(stats.seconds, 3),
        "raw_bytes": size.raw_bytes,
        "stored_bytes": size.stored_bytes,
        "stored_ratio": round(size.stored_ratio, 3),
        "packed_bytes": size.packed_bytes,
        "packed_ratio": round(size.packed_ratio, 3),
    }
    if not args.no_psnr:
        texels = metrics.texel_subset(src.meta.width, src.meta.height, args.psnr_texels)
        t0 = time.perf_counter()
        value = metrics.psnr(src, encoded, texels)
        if math.isnan(value):
            raise BTFError("PSNR could not be measured (the input evaluates to NaN)")
        report["psnr_db"] = None if math.isinf(value) else round(value, 3)
        report["psnr_texels"] = len(texels)
        report["psnr_seconds"] = round(time.perf_counter() - t0, 3)
        report["ssim"] = round(metrics.ssim(src, encoded), 5)
    return report


def _compress_svd(args, src, out: Path) -> int:
    settings = SVDSettings(
        ranks=_ranks(args.rank), colour_space=args.colour_space, factor_bits=args.factor_bits
    )
    n_views, n_lights = src.meta.n_views or 81, src.meta.n_lights or 81
    n_tex = src.meta.width * src.meta.height
    memory.require(
        memory.Estimate(
            f"the svd encoder's Gram matrices and blocks ({n_views * n_lights} pairs, "
            f"{n_tex} texels)",
            memory_bound(n_views * n_lights, n_tex, settings),
            "lower --rank, or compress a reduced copy of the material",
        )
        + memory.btf_load(args.src)
    )
    bar = ProgressBar()
    try:
        encoded, stats = encode_svd(src, settings, bar)
        if not args.no_psnr:
            bar(1.0, "measuring PSNR and SSIM")
        report = svd_report_json(src, encoded, stats, settings, args)
    finally:
        bar.close()
    return write_and_report(out, encoded, report)


def svd_report_json(src, encoded, stats, settings: SVDSettings, args) -> dict:
    """The MLVQ report's fields for an svd encoding: sizes against raw 8-bit (81 × 81 × W × H
    × 3 bytes, as quantreport.txt) and float32 data, PSNR and SSIM at the measured pairs (the
    encoding's grids), ranks and truncation error, encode time."""
    size = svd_sizes(encoded, settings.factor_bits)
    report = {
        "input": str(args.src),
        "codec": "svd",
        "texels": [src.meta.width, src.meta.height],
        "settings": asdict(settings),
        "ranks": list(stats.ranks),
        "truncation_error": [round(e, 6) for e in stats.truncation_error],
        "gram_side": stats.gram_side,
        "memory_bound_bytes": stats.memory_bound_bytes,
        "encode_seconds": round(stats.seconds, 3),
        "raw_bytes": size.raw_bytes,
        "raw_float32_bytes": 4 * size.raw_bytes,
        "stored_bytes": size.stored_bytes,
        "stored_ratio": round(size.stored_ratio, 3),
        "float32_ratio": round(4 * size.stored_ratio, 3),
        "packed_bytes": size.packed_bytes,
        "packed_ratio": round(size.packed_ratio, 3),
    }
    if not args.no_psnr:
        grids = {"view_grid": encoded.p.view_grid, "light_grid": encoded.p.light_grid}
        texels = metrics.texel_subset(src.meta.width, src.meta.height, args.psnr_texels)
        t0 = time.perf_counter()
        value = metrics.psnr(src, encoded, texels, **grids)
        if math.isnan(value):
            raise BTFError("PSNR could not be measured (the input evaluates to NaN)")
        report["psnr_db"] = None if math.isinf(value) else round(value, 3)
        report["psnr_texels"] = len(texels)
        report["ssim"] = round(metrics.ssim(src, encoded, **grids), 5)
        report["psnr_seconds"] = round(time.perf_counter() - t0, 3)
    return report
