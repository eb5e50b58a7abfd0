"""Benchmark helpers: timing, tables, data locations. Benchmarks print; they never assert."""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

SHARED_BTFBASE = ROOT.parent / "shared" / "data" / "btfbase"


def timed(fn, *args, repeat: int = 1, **kwargs):
    """(best wall time in seconds over ``repeat`` runs, last result)."""
    best = float("inf")
    result = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn(*args, **kwargs)
        best = min(best, time.perf_counter() - t0)
    return best, result


def decode_rate(btf, n: int) -> float:
    """Million numpy decodes per second of ``btf`` over ``n`` seeded random queries (uv in the
    tile, θ up to 80°, φ over the circle): the encoders' "decode Mq/s" column."""
    import numpy as np

    rng = np.random.default_rng(1)
    angles = [rng.random(n) * limit for limit in (80, 360, 80, 360)]
    q = np.column_stack([rng.random((n, 2)), *angles])
    t0 = time.perf_counter()
    btf.evaluate_angles(q)
    return n / (time.perf_counter() - t0) / 1e6


def table(headers: list[str], rows: list[list]) -> str:
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v)

    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)
