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

CLI rows (``--cli alu``): ``python -m btf_addon compress`` at default settings, this tree and
``--baseline-rev`` (the encoder before issue 30 item 18: whole-array copies of the grid
samples, 3.4 GB) side by side in the same run, each in its own process: wall time, the
report's encode time, peak RSS (``wait4``), PSNR and SSIM, and the baseline / this-tree
ratios. The baseline package is read with ``git archive`` (nothing in the checkout changes).

Scaling rows (``--scaling``): the encoder alone on alu's tables tiled to 32², 64², 128² texels
(all of them training texels) and with alu's P2 entries cut to fewer: encode seconds, and
tracemalloc's peak of numpy arrays in a second, traced encode, against ``working_set_bytes``;
and alu read as any other source is (sampled through ``evaluate_angles``, most of that row's
time, into its formed float32 grid samples, 666 MB).

Usage: python benchmarks/bench_compress.py [--real alu wallpaper] [--no-synthetic] [--assign]
       [--cli alu] [--baseline-rev REV] [--scaling]
"""

from __future__ import annotations

import argparse
import io
import json
import os
import re
import subprocess
import sys
import tarfile
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
from common import ROOT, SHARED_BTFBASE, decode_rate, table

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.dense import DenseBTF, tabulate
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.encoders import metrics
from btf_addon.core.encoders import mlvq as mlvq_module
from btf_addon.core.encoders.mlvq import (
    MLVQSettings,
    _mlvq_grid_values,
    encode_mlvq,
    sample_grid,
    working_set_bytes,
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


#: The tree before issue 30 item 18 (79–95 s, 3.4 GB on alu on the 2-core machine).
BASELINE_REV = "8bd667c"

CLI_HEADERS = [
    "compress alu (default settings)",
    "wall s",
    "encode s",
    "peak RSS MB",
    "PSNR dB",
    "SSIM",
]


def run_cli(package_root: Path, src: Path, out: Path) -> dict:
    """One ``python -m btf_addon compress src -o out`` with ``package_root`` first on the path:
    wall seconds, peak RSS (MB, this child alone, from wait4) and its JSON report."""
    env = {**os.environ, "PYTHONPATH": str(package_root)}
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "btf_addon", "compress", str(src), "-o", str(out)],
        cwd=package_root,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    text = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"compress under {package_root} exited {proc.returncode}")
    return {"wall": wall, "rss_mb": usage.ru_maxrss / 1024, "report": json.loads(text)}


def cli_rows(name: str, rev: str) -> list[list]:
    """This tree's CLI and ``rev``'s (extracted with git archive) on one material, then the
    ratios baseline / this tree (above 1: this tree is faster / smaller)."""
    src = SHARED_BTFBASE / name
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "baseline"
        base.mkdir()
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", "--format=tar", rev, "btf_addon"],
            check=True,
            capture_output=True,
        ).stdout
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(base, filter="data")
        runs = {}
        for label, root in ((f"baseline {rev}", base), ("this tree", ROOT)):
            runs[label] = run_cli(root, src, Path(tmp) / f"{label.split()[0]}.btfm")
    rows = []
    for label, r in runs.items():
        rep = r["report"]
        rows.append(
            [label, r["wall"], rep["encode_seconds"], r["rss_mb"], rep["psnr_db"], rep["ssim"]]
        )
    b, t = rows
    rows.append(
        [
            "ratio baseline / this tree",
            b[1] / t[1],
            b[2] / t[2],
            b[3] / t[3],
            b[4] - t[4],
            b[5] - t[5],
        ]
    )
    rows[-1][4] = f"{rows[-1][4]:+.3f} (difference)"
    rows[-1][5] = f"{rows[-1][5]:+.5f} (difference)"
    return rows


SCALING_HEADERS = [
    "texels",
    "P2 entries",
    "encode s",
    "CPU s (2 threads)",
    "traced peak MB",
    "working_set_bytes MB",
    "formed grid MB",
]


def tiled(src: MLVQBTF, reps: int, entries: int | None = None) -> MLVQBTF:
    """``src`` with its texel tables tiled ``reps`` × ``reps`` (or cut to the top-left quarter
    for reps 0), its P2 entries cut to the first ``entries`` (P3 rows pointing at them)."""
    t = src.tables()
    if reps == 0:
        h, w = t["pdf6_slices"].shape
        t["pdf6_slices"] = t["pdf6_slices"][: h // 2, : w // 2].copy()
        t["pdf6_scale"] = t["pdf6_scale"][: h // 2, : w // 2].copy()
    else:
        t["pdf6_slices"] = np.tile(t["pdf6_slices"], (reps, reps))
        t["pdf6_scale"] = np.tile(t["pdf6_scale"], (reps, reps))
    if entries is not None:
        t["pdf2_indices"] = t["pdf2_indices"][:entries].copy()
        t["pdf3_slices"] = t["pdf3_slices"] % entries
    return MLVQBTF(src.p, t, source="scaled")


def scaling_rows(name: str = "alu") -> list[list]:
    """Encode time and traced peak against texels (alu tiled) and P2 entries (alu's cut to
    fewer); every texel trains (train_texels 0)."""
    src = MLVQBTF.from_directory(SHARED_BTFBASE / name)
    s = MLVQSettings(train_texels=0)
    rows = []
    cases = [(0, None, True), (1, None, True), (2, None, True), (1, 430, True), (1, 860, True)]
    cases.append((1, None, False))  # the grid formed, as for a dense source
    for reps, entries, factored in cases:
        btf = tiled(src, reps, entries)
        n = btf.meta.width * btf.meta.height
        used = len(btf.t["pdf2_indices"])
        same_grid = mlvq_module._same_grid
        if not factored:  # read alu as any other source: its grid samples formed in float32
            mlvq_module._same_grid = lambda *_: False
        try:
            t0, c0 = time.perf_counter(), time.process_time()
            encode_mlvq(btf, s)
            seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
            tracemalloc.start()  # a second encode: tracing doubles the time
            encode_mlvq(btf, s)
            _, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
        finally:
            mlvq_module._same_grid = same_grid
        bound = working_set_bytes(n, s, used if factored else None)
        grid = n * s.n_phi * s.n_theta * s.n_alpha * s.n_beta * 3 * 4
        label = n if factored else f"{n} (sampled, grid formed)"
        rows.append([label, used, seconds, cpu, peak / 2**20, bound / 2**20, grid / 2**20])
        print(table(SCALING_HEADERS, rows[-1:]), flush=True)
    return rows


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser()
    parser.add_argument("--real", nargs="*", default=[])
    parser.add_argument("--no-synthetic", action="store_true")
    parser.add_argument("--assign", action="store_true", help="the assign-step speed rows")
    parser.add_argument("--cli", nargs="*", default=[], help="CLI rows against the baseline")
    parser.add_argument("--baseline-rev", default=BASELINE_REV)
    parser.add_argument("--scaling", action="store_true", help="time and memory against size")
    args = parser.parse_args(argv)
    extra = []
    for name in args.cli:
        extra.append(table(CLI_HEADERS, cli_rows(name, args.baseline_rev)))
        print(extra[-1], flush=True)
    if args.scaling:
        extra.append(table(SCALING_HEADERS, scaling_rows()))
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
    for part in extra:
        text += ("\n\n" if text else "") + part
    return text


if __name__ == "__main__":
    print(main())
