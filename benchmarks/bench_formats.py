"""Formats of issue 15: load time and memory per format against the text tables; svd decode
throughput (numpy, OpenCL, GLSL) against MLVQ at equal texel count; rank vs error vs time.

Memory is tracemalloc's peak during the load (numpy's buffers included). The svd material is
the real alu (MLVQ text tables) tabulated on the UBO2003 grid at 32×32 texels and factorised
per channel (YUV), so the ranks' errors are those of real measured reflectance. Decode times
are for random queries with programs already built; OpenCL and GLSL include transfers.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
from common import SHARED_BTFBASE, table, timed
from helpers import random_queries

from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.formats.btfbase_binary import load_binary
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.load import load_btf
from btf_addon.core.formats.ubo2014_writer import write_ubo2014
from btf_addon.core.grid import UBO2003

N = 200_000
RANKS = (1, 2, 4, 8, 16, 32)


def _load(fn, *args):
    tracemalloc.start()
    t0 = time.perf_counter()
    result = fn(*args)
    seconds = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return seconds, peak / 2**20, result


def _size(path: Path) -> int:
    if path.is_dir():
        return sum(f.stat().st_size for f in path.iterdir() if f.suffix == ".txt")
    return path.stat().st_size


def load_table(tmp: Path, alu_dense) -> str:
    rows = []
    for name in ("alu", "wallpaper"):
        folder = SHARED_BTFBASE / name
        if not folder.is_dir():
            continue
        for form, fn, path in (
            ("text tables", MLVQBTF.from_directory, folder),
            ("binary.btf", load_binary, folder / "binary.btf"),
        ):
            seconds, mib, _ = _load(fn, path)
            rows.append(
                [name, form, f"{_size(path) / 2**20:.2f}", round(seconds, 3), round(mib, 1)]
            )
    svd, _ = factorise(alu_dense.data * np.pi, UBO2003, UBO2003, ranks=(16, 8, 8))
    for form, path, write in (
        ("UBO2014 .btf (half)", tmp / "alu.btf", lambda p: write_ubo2014(p, svd)),
        (".btfm (svd, float)", tmp / "alu_svd.btfm", lambda p: write_container(p, svd)),
        (".btfm (dense)", tmp / "alu_dense.btfm", lambda p: write_container(p, alu_dense)),
    ):
        write(path)
        seconds, mib, _ = _load(load_btf, path)
        rows.append(
            [
                "alu 32² ranks 16/8/8",
                form,
                f"{_size(path) / 2**20:.2f}",
                round(seconds, 3),
                round(mib, 1),
            ]
        )
    return table(["material", "form", "MiB on disk", "load s", "peak MiB"], rows)


def _rates(btf, q) -> list:
    t_np, _ = timed(btf.evaluate_angles, q)
    out = [f"{len(q) / t_np:,.0f}"]
    try:
        from btf_addon.cl.context import create_context
        from btf_addon.cl.evaluate import device_btf

        dev = device_btf(btf, create_context())
        dev.evaluate_angles(q[:10])
        t_cl, _ = timed(dev.evaluate_angles, q)
        out.append(f"{len(q) / t_cl:,.0f}")
    except Exception as exc:
        out.append(f"- ({type(exc).__name__})")
    try:
        from btf_addon.gl.query import glsl_btf

        gl = glsl_btf(btf)
        gl.evaluate_angles(q[:10])
        t_gl, _ = timed(gl.evaluate_angles, q)
        out.append(f"{len(q) / t_gl:,.0f}")
    except Exception as exc:
        out.append(f"- ({type(exc).__name__})")
    return out


def throughput_table(alu_mlvq) -> str:
    """At MLVQ alu's own texel count (64²): decode cost does not depend on the factors'
    values, so the svd BTFs here hold random factors of the UBO2003 pair count."""
    from btf_addon.core.codecs.svd import SVDBTF

    q = random_queries(np.random.default_rng(2), N)
    rows = [["MLVQ alu (64² texels)", *_rates(alu_mlvq, q)]]
    rng = np.random.default_rng(4)
    base, _ = factorise(np.ones((UBO2003.size, UBO2003.size, 1, 1, 3)), ranks=(1, 1, 1))
    pairs, texels = UBO2003.size**2, alu_mlvq.meta.width * alu_mlvq.meta.height
    params = dataclasses.replace(base.p, width=alu_mlvq.meta.width, height=alu_mlvq.meta.height)
    for ranks in ((8, 4, 4), (16, 8, 8), (32, 16, 16)):
        u = [rng.random((pairs, k)).astype(np.float32) * 0.1 for k in ranks]
        sv = [rng.random((texels, k)).astype(np.float32) for k in ranks]
        rows.append(
            [f"svd 64², ranks {'/'.join(map(str, ranks))}", *_rates(SVDBTF(params, u, sv), q)]
        )
    return table(["BTF", "numpy q/s", "OpenCL q/s", "GLSL q/s"], rows)


def rank_table(alu_dense) -> str:
    """One factorisation at the largest rank; a rank-k BTF is its first k components (SVD
    truncations are nested), so every row is the optimal rank-k fit per channel."""
    from btf_addon.core.codecs.svd import SVDBTF

    data = alu_dense.data.astype(np.float64) * np.pi
    nv, nl, h, w, _ = data.shape
    pair = np.repeat(np.arange(nv * nl), h * w)
    texel = np.tile(np.arange(h * w), nv * nl)
    q = random_queries(np.random.default_rng(3), N)
    t_fac, (full, _) = timed(factorise, data, UBO2003, UBO2003, ranks=(max(RANKS),) * 3)
    rows = []
    for k in RANKS:
        svd = SVDBTF(full.p, [a[:, :k] for a in full.u], [a[:, :k] for a in full.sv])
        got = svd.pair_rgb(pair, texel).reshape(data.shape)
        rel = float(np.linalg.norm(got - data) / np.linalg.norm(data))
        rms_8bit = float(np.sqrt(np.mean((got - data) ** 2))) * 255
        max_8bit = float(np.abs(got - data).max()) * 255
        t_np, _ = timed(svd.evaluate_angles, q)
        rows.append([k, f"{rel:.4f}", round(rms_8bit, 2), round(max_8bit, 1), f"{N / t_np:,.0f}"])
    return f"(one factorisation at rank {max(RANKS)}: {t_fac:.1f} s)\n\n" + table(
        ["rank per channel", "relative RGB error", "RMS error /255", "max error /255", "numpy q/s"],
        rows,
    )


def _load_seconds(path: Path) -> float:
    """One ``load_btf`` in CPU seconds of this process (the machine is shared: other work
    must not count); the caller takes the best of runs interleaved with the other version's."""
    t0 = time.process_time()
    load_btf(path)
    return time.process_time() - t0


def _mlvq_encoding(tmp: Path) -> MLVQBTF | None:
    """Our MLVQ encoding of alu at default settings: the file in $BTF_BENCH_ALU_MLVQ (written
    by ``python -m btf_addon compress``) or, when $BTF_BENCH_ENCODE=1, encoded here (minutes)."""
    given = os.environ.get("BTF_BENCH_ALU_MLVQ")
    if given and Path(given).is_file():
        return load_btf(given)
    if os.environ.get("BTF_BENCH_ENCODE") != "1":
        return None
    from btf_addon.core.encoders.mlvq import MLVQSettings, encode_mlvq

    encoded, _ = encode_mlvq(MLVQBTF.from_directory(SHARED_BTFBASE / "alu"), MLVQSettings())
    return encoded


def container_table(tmp: Path, alu_dense) -> str:
    """.btfm version 1 (raw arrays, the writer before issue 31) against version 2 (compact):
    bytes on disk against the material's binary.btf, and load time (``load_btf``, CPU time,
    best of interleaved runs, so both versions meet the same machine load)."""
    sources: list[tuple[str, object, int | None]] = []
    for name in ("alu", "wallpaper"):
        folder = SHARED_BTFBASE / name
        if folder.is_dir():
            binary = (folder / "binary.btf").stat().st_size
            sources.append((f"{name} (text tables)", load_btf(folder), binary))
            sources.append(
                (f"{name} (binary.btf, restored)", load_btf(folder, prefer_binary=True), binary)
            )
    encoded = _mlvq_encoding(tmp)
    if encoded is not None:
        sources.append(("alu, our MLVQ encoding (defaults)", encoded, None))
    sources.append(("alu 32² dense (float32)", alu_dense, None))
    rows = []
    for label, btf, binary in sources:
        v1 = write_container(tmp / "v1.btfm", btf, compact=False)
        t0 = time.perf_counter()
        v2 = write_container(tmp / "v2.btfm", btf)
        write_s = time.perf_counter() - t0
        repeat = 300 if v1.stat().st_size < 1 << 20 else 30 if v1.stat().st_size < 1 << 24 else 5
        t1, t2 = np.inf, np.inf
        for _ in range(repeat):
            t1, t2 = min(t1, _load_seconds(v1)), min(t2, _load_seconds(v2))
        rows.append(
            [
                label,
                f"{v1.stat().st_size:,}",
                f"{v2.stat().st_size:,}",
                "-" if binary is None else f"{binary:,}",
                f"{t1 * 1e3:.2f}",
                f"{t2 * 1e3:.2f}",
                f"{t2 / t1:.2f}",
                f"{write_s:.2f}",
            ]
        )
    return table(
        [
            "material",
            "v1 bytes",
            "v2 bytes",
            "binary.btf bytes",
            "v1 load ms",
            "v2 load ms",
            "v2/v1 load",
            "v2 write s",
        ],
        rows,
    )


def main() -> str:
    folder = SHARED_BTFBASE / "alu"
    if not folder.is_dir():
        return f"skipped: {folder} not found"
    alu = MLVQBTF.from_directory(folder)
    alu_dense = tabulate(alu, UBO2003, UBO2003, width=32, height=32)
    with tempfile.TemporaryDirectory() as tmp:
        parts = [
            "### .btfm version 1 vs 2 (issue 31)\n" + container_table(Path(tmp), alu_dense),
            "### Load time and memory\n" + load_table(Path(tmp), alu_dense),
            "### svd decode throughput against MLVQ\n" + throughput_table(alu),
            "### Rank vs error vs time (alu, 32² texels, UBO2003 81 × 81)\n"
            + rank_table(alu_dense),
        ]
    return "\n\n".join(parts)


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["container"]:  # only the version 1 vs 2 table
        alu = MLVQBTF.from_directory(SHARED_BTFBASE / "alu")
        with tempfile.TemporaryDirectory() as tmp:
            print(container_table(Path(tmp), tabulate(alu, UBO2003, UBO2003, width=32, height=32)))
    else:
        print(main())
