"""MLVQ compressor (issue 16): codebook sizes / scale bits against ratio, PSNR, encode time and
numpy decode throughput, on a synthetic BTF and on the shared BTFbase materials re-encoded
from their own grid (``--real alu``; each real run takes minutes: run it alone).

PSNR: RGB, peak 255 on the 8-bit scale, against the input at the UBO2003 81 × 81 directions at
256 seeded texels (all texels of the synthetic one). For a BTFbase material the input is the
decoded original material, not the raw UBO2003 images (not here), so the original tool's own
row has PSNR ∞ by construction; its ratio is read from its quantreport.txt. "grid PSNR" is the
same measure at the encoder's own samples (the onion-slice grid): the quantisation loss alone.

Assign rows (``--assign``): the nearest-codeword step, numpy (float32 BLAS product + argmax)
against the OpenCL kernel (cl/encoder_assign.py) on the default device, same inputs.

Usage: python benchmarks/bench_compress.py [--real alu wallpaper] [--no-synthetic] [--assign]
"""

from __future__ import annotations

import argparse
import re
import time
from collections.abc import Callable

import numpy as np
from common import SHARED_BTFBASE, decode_rate, table

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.dense import DenseBTF, tabulate
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.encoders import metrics
from btf_addon.core.encoders.mlvq import (
    MLVQSettings,
    _mlvq_grid_values,
    encode_mlvq,
    sample_grid,
)

HEADERS = [
    "input",
    "k1/k2/k3/k4",
    "scale bits",
    "stored ratio",
    "packed ratio",
    "PSNR dB",
    "grid PSNR dB",
    "encode s",
    "decode Mq/s",
]


#: Per material: the codebooks at the original tool's sizes (its counts: alu P1 1381, 2D 1723,
#: P3 539, P4 34; wallpaper P1 8735, 2D 34 803, P3 12 108, P4 783) and one at half of them.
#: wallpaper's 2D level trains on 2 rows per codeword (72 000 rows, not 20 000: fewer rows
#: than codewords leaves codewords unused) with 2 Lloyd steps (each ~1.9e12 flops).
REAL_SETTINGS = {
    "alu": [
        MLVQSettings(k1=1400, k2=1700, k3=540, k4=34),
        MLVQSettings(k1=700, k2=850, k3=270, k4=17),
    ],
    "wallpaper": [
        MLVQSettings(k1=8735, k2=36000, k3=12108, k4=783, train_per_code=2, iterations=2),
    ],
}


def synthetic(size: int = 16) -> DenseBTF:
    """A rough GGX (roughness 0.6) tabulated on UBO2003, tinted per texel (two colours, a
    brightness ramp): texel variety without lobes sharper than the MLVQ grid resolves."""
    base = tabulate(GGXBTF(albedo=(0.55, 0.35, 0.2), roughness=0.6), width=1, height=1).data
    y, x = np.mgrid[0:size, 0:size]
    ramp = 0.4 + 0.6 * (x + y) / (2 * size - 2)
    tint = np.where(((x // 4 + y // 4) % 2 == 0)[..., None], [1.0, 1.0, 1.0], [0.6, 0.9, 1.3])
    return DenseBTF(base * (ramp[..., None] * tint)[None, None], name=f"synthetic {size}²")


def stage_log() -> Callable[[float, str], None]:
    """A progress callback printing each stage's start (seconds since the first call): the
    per-stage profile in the docs comes from these lines."""
    start, last = time.perf_counter(), [""]

    def log(fraction: float, what: str) -> None:
        if what != last[0]:
            last[0] = what
            print(f"  {time.perf_counter() - start:8.1f} s  {what}", flush=True)

    return log


def row(name, src, settings: MLVQSettings, texels: int) -> list:
    enc, stats = encode_mlvq(src, settings, stage_log())
    size = metrics.sizes(enc, settings.scale_bits)
    w, h = src.meta.width, src.meta.height
    value = metrics.psnr(src, enc, metrics.texel_subset(w, h, texels))
    # Grid PSNR at every texel up to 64² (alu), else at 4096 seeded texels: wallpaper's whole
    # grid is 10.6 GB of float32 per side.
    cells = metrics.texel_subset(w, h, 0 if w * h <= 4096 else 4096)
    grid = metrics.grid_psnr(sample_grid(src, enc.p, None, cells), _mlvq_grid_values(enc, cells))
    k = f"{settings.k1}/{settings.k2}/{settings.k3}/{settings.k4}"
    return [
        name,
        k,
        settings.scale_bits,
        size.stored_ratio,
        size.packed_ratio,
        value,
        grid,
        stats.seconds,
        decode_rate(enc, 200_000),
    ]


def original_row(name: str, folder) -> list:
    text = (folder / "quantreport.txt").read_text()
    found = re.search(r"compressed quantized = \d+\s+ratio = ([\d.]+)", text)
    plain = re.search(r"uncompressed = \d+ compressed = \d+\s+ratio = ([\d.]+)", text)
    src = MLVQBTF.from_directory(folder)
    c = src.t
    k = f"{len(c['pdf1'])}/{len(c['pdf2_indices'])}/{len(c['pdf3_slices'])}/{len(c['pdf4_slices'])}"
    return [
        f"{name} (original tool)",
        k,
        8,
        float(plain.group(1)) if plain else "?",
        float(found.group(1)) if found else "?",
        "∞ (reference)",
        "∞ (reference)",
        "19–29 h (2009)",
        decode_rate(src, 200_000),
    ]


ASSIGN_HEADERS = [
    "assign step (shape of)",
    "rows × codewords × dims",
    "numpy s",
    "numpy Gflop/s",
    "OpenCL s",
    "OpenCL device",
    "OpenCL / numpy time",
]

#: The encoder's nearest-codeword calls, scaled down so that the CPU OpenCL driver finishes
#: (wallpaper's real ones: level 2 458 752 × 36 000 × 363, level 3 65 536 × 12 108 × 2541,
#: P1 396 000 × 8735 × 11); flops = 2 × rows × codewords × dims.
ASSIGN_SHAPES = [
    ("P1 slices over β", 20_000, 1000, 11),
    ("level 2 (2D functions)", 2048, 4000, 363),
    ("level 3 (θv runs)", 512, 1000, 2541),
]


def assign_rows() -> list[list]:
    """numpy ``nearest`` against the OpenCL step (scale-free, as the levels call it), same
    random data, after one warm-up call each (the kernel build is not timed)."""
    from btf_addon.cl.context import OpenCLUnavailableError, create_context
    from btf_addon.cl.encoder_assign import OpenCLAssign
    from btf_addon.core.encoders.kmeans import nearest

    try:
        device = OpenCLAssign(create_context())
    except OpenCLUnavailableError:
        device = None
    rng = np.random.default_rng(0)
    out = []
    for what, n, k, d in ASSIGN_SHAPES:
        x = rng.random((n, d), dtype=np.float32)
        c = rng.random((k, d), dtype=np.float32)
        timings = []
        for fn in (nearest, device):
            if fn is None:
                timings.append(float("nan"))
                continue
            fn(x[:64], c[:64], True)
            t0 = time.perf_counter()
            fn(x, c, True)
            timings.append(time.perf_counter() - t0)
        flops = 2.0 * n * k * d
        out.append(
            [
                what,
                f"{n} × {k} × {d}",
                timings[0],
                flops / timings[0] / 1e9,
                timings[1],
                device.device_name if device else "none",
                timings[1] / timings[0],
            ]
        )
        print(table(ASSIGN_HEADERS, out[-1:]), flush=True)
    return out


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser()
    parser.add_argument("--real", nargs="*", default=[])
    parser.add_argument("--no-synthetic", action="store_true")
    parser.add_argument("--assign", action="store_true", help="the assign-step speed rows")
    args = parser.parse_args(argv)
    rows = []
    speed = assign_rows() if args.assign else []
    if not args.no_synthetic:
        src = synthetic()
        for k1, k2, k3, k4, bits in (
            (32, 32, 16, 4, 8),
            (128, 128, 32, 8, 8),
            (512, 512, 64, 16, 8),
            (512, 512, 64, 16, 0),
            (512, 512, 64, 16, 6),
        ):
            s = MLVQSettings(k1=k1, k2=k2, k3=k3, k4=k4, scale_bits=bits)
            rows.append(row(src.meta.name, src, s, 0))
            print(table(HEADERS, rows[-1:]), flush=True)
    for name in args.real:
        folder = SHARED_BTFBASE / name
        if not folder.is_dir():
            print(f"skipping {name}: {folder} not found")
            continue
        rows.append(original_row(name, folder))
        src = MLVQBTF.from_directory(folder)
        for s in REAL_SETTINGS.get(name, REAL_SETTINGS["alu"]):
            rows.append(row(f"{name} (ours)", src, s, 256))
            print(table(HEADERS, rows[-1:]), flush=True)
    text = table(HEADERS, rows) if rows else ""
    if speed:
        text += ("\n\n" if text else "") + table(ASSIGN_HEADERS, speed)
    return text


if __name__ == "__main__":
    print(main())
