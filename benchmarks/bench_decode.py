"""Decode throughput on the shared BTFbase materials, every back end side by side in one run.

An evaluation is one decode at one texel. Columns (M evaluations/s, and × numpy measured in the
same run): the numpy reference (``evaluate_angles``: host sanitising included); the OpenCL
decode kernel alone (``eval_mlvq`` or ``eval_dense``, the one ``device_btf`` launches: tables and
queries already on the device, program cached: enqueue to finish); OpenCL end to end
(``device_btf(...).evaluate_angles``: host sanitising, transfers); the GLSL query shader on the
moderngl context (llvmpipe here) end to end. Two query sets: ``random`` (uniform uv and angles:
every evaluation a different texel and angle cell, the worst case for caches) and ``coherent``
(as a render issues them: a scan-line grid of uv that steps about one texel per query, one
light direction, a view direction varying smoothly).
Filtered lookups (bilinear: four evaluations each) are a row of their own, counted in lookups/s.
A third material, wallpaper tabulated (``materials()``), times the dense decoder.

Usage: ``python benchmarks/bench_decode.py [N]`` (default 10⁶ queries; the scalar decoder of the
tests runs on 2,000).
"""

from __future__ import annotations

import sys

import numpy as np
from common import SHARED_BTFBASE, table, timed
from helpers import random_queries

from btf_addon.core.codecs.mlvq import MLVQBTF

N = 1_000_000
N_SCALAR = 2_000


def coherent_queries(n: int, width: int, height: int) -> np.ndarray:
    """(n, 6) queries in scan-line order over a square image that maps the tile once per
    ``width`` columns (≈ one texel per query), one light, a view direction varying smoothly
    across the image (a camera looking at a plane)."""
    side = int(np.ceil(np.sqrt(n)))
    j, i = np.divmod(np.arange(n), side)
    u, v = (i + 0.5) / width, (j + 0.5) / height
    x, y = i / side - 0.5, j / side - 0.5
    theta_v = np.degrees(np.arctan(np.hypot(x, y) * 1.5))
    phi_v = np.degrees(np.arctan2(y, x)) % 360.0
    return np.column_stack([u, v, np.full(n, 40.0), np.full(n, 30.0), theta_v, phi_v])


class KernelOnly:
    """The evaluator's kernel (``eval_mlvq``/``eval_dense``, batched on a CPU) or
    ``eval_btf_filtered`` on device-resident queries: enqueue → finish."""

    def __init__(self, btf, ctx, q: np.ndarray, filtered: bool = False):
        import pyopencl as cl

        from btf_addon.cl.evaluate import KernelEvaluator
        from btf_addon.core.angles import directions_from_angles_deg

        ev = KernelEvaluator(btf, ctx)
        self.cl, self.ctx, self.n = cl, ctx, len(q)
        if filtered:
            self.kernel, self.size = cl.Kernel(ev.program, "eval_btf_filtered"), ((self.n,), None)
        else:
            self.kernel, self.size = ev.kernel, ev.launch_size(self.n)
        wi = directions_from_angles_deg(q[:, 2], q[:, 3])
        wo = directions_from_angles_deg(q[:, 4], q[:, 5])
        self.args = [
            ev._buffer(q),
            ev._buffer(np.stack([wi, wo], axis=1).reshape(-1, 3)),
            np.int32(self.n),
            ev._ints,
            ev._floats,
            cl.Buffer(ctx.context, cl.mem_flags.WRITE_ONLY, self.n * 12),
        ]
        self()  # first launch: PoCL specialises the work-group function

    def __call__(self) -> None:
        self.kernel(self.ctx.queue, *self.size, *self.args)
        self.ctx.queue.finish()

    def result(self) -> np.ndarray:
        self()
        out = np.empty((self.n, 3), np.float32)
        self.cl.enqueue_copy(self.ctx.queue, out, self.args[-1])
        return out


def materials():
    """(name, BTF): the two MLVQ materials, then wallpaper tabulated on the UBO2003 grid at
    16² texels (a dense codec: 81 × 81 × 256 RGB, 20 MB of tables, as much larger than the
    caches as wallpaper's MLVQ tables are)."""
    from btf_addon.core.codecs.dense import tabulate
    from btf_addon.core.grid import UBO2003

    loaded = {}
    for name in ("alu", "wallpaper"):
        path = SHARED_BTFBASE / name
        if not path.is_dir():
            print(f"skipping {name}: {path} not found")
            continue
        loaded[name] = MLVQBTF.from_directory(path)
        yield name, loaded[name]
    if "wallpaper" in loaded:
        dense = tabulate(loaded["wallpaper"], UBO2003, UBO2003, width=16, height=16)
        yield "wallpaper (dense 16²)", dense


def _rate(n: int, seconds: float) -> float:
    return n / seconds / 1e6


def main(n: int = N) -> str:
    from btf_addon.cl.context import OpenCLUnavailableError, create_context
    from btf_addon.cl.evaluate import device_btf
    from btf_addon.core.angles import directions_from_angles_deg
    from btf_addon.core.mapping import filtered_evaluate

    try:
        ctx = create_context()
    except OpenCLUnavailableError as exc:  # a kernel that fails to compile is not skipped
        print(f"OpenCL skipped: {exc}")
        ctx = None
    try:
        from btf_addon.gl.query import create_gl_context, glsl_btf

        gl = create_gl_context()
        gl_name = gl.info["GL_RENDERER"]
    except Exception as exc:
        print(f"GLSL skipped: {exc}")
        gl, gl_name = None, "-"
    rows = []
    for name, btf in materials():
        sets = {
            "random": random_queries(np.random.default_rng(1), n),
            "coherent": coherent_queries(n, btf.meta.width, btf.meta.height),
        }
        for kind, q in sets.items():
            t_np, _ = timed(btf.evaluate_angles, q, repeat=2)
            row = [name, kind, "1 eval", f"{_rate(n, t_np):.2f}"]
            if ctx is not None:
                kernel = KernelOnly(btf, ctx, q)
                t_k, _ = timed(kernel, repeat=7)  # 0.1 s each: best of more, less noise
                t_e, _ = timed(device_btf(btf, ctx).evaluate_angles, q, repeat=2)
                row += [
                    f"{_rate(n, t_k):.2f} ({t_np / t_k:.1f}×)",
                    f"{_rate(n, t_e):.2f} ({t_np / t_e:.1f}×)",
                ]
            else:
                row += ["-", "-"]
            if gl is not None:
                t_g, _ = timed(glsl_btf(btf, gl).evaluate_angles, q, repeat=2)
                row.append(f"{_rate(n, t_g):.2f} ({t_np / t_g:.1f}×)")
            else:
                row.append("-")
            rows.append(row)
            # Filtered (bilinear) lookups: four evaluations each, counted in lookups/s.
            m = n // 4
            wi = directions_from_angles_deg(q[:m, 2], q[:m, 3])
            wo = directions_from_angles_deg(q[:m, 4], q[:m, 5])
            t_fn, _ = timed(filtered_evaluate, btf, q[:m, :2], wi, wo, "LINEAR")
            row = [name, kind, "bilinear lookup", f"{_rate(m, t_fn):.2f}"]
            if ctx is not None:
                kernel = KernelOnly(btf, ctx, q[:m], filtered=True)
                t_fk, _ = timed(kernel, repeat=7)
                row += [f"{_rate(m, t_fk):.2f} ({t_fn / t_fk:.1f}×)", "-", "-"]
            else:
                row += ["-", "-", "-"]
            rows.append(row)
    device = ctx.device_name if ctx is not None else "-"
    return table(
        [
            "material",
            "queries",
            "unit",
            "numpy M/s",
            "OpenCL kernel M/s",
            "OpenCL end-to-end M/s",
            "GLSL end-to-end M/s",
        ],
        rows,
    ) + (f"\n\nOpenCL device: {device}; GL renderer: {gl_name}; {n:,} queries per set.")


if __name__ == "__main__":
    print(main(int(sys.argv[1]) if len(sys.argv) > 1 else N))
