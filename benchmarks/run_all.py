"""Run every benchmark and print its table (the numbers quoted in docs/accuracy.md)."""

from __future__ import annotations

import platform

import bench_aa
import bench_accuracy
import bench_bridge
import bench_btf_importance
import bench_compress_svd
import bench_decode
import bench_envmap
import bench_final_render
import bench_formats
import bench_interpolation
import bench_mapping
import bench_specialise
import bench_viewport
import bench_vr
import bench_wiimote

if __name__ == "__main__":
    print(
        f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}"
    )
    for module in (
        bench_decode,
        bench_interpolation,
        bench_envmap,
        bench_viewport,
        bench_vr,
        bench_bridge,
        bench_final_render,
        bench_mapping,
        bench_aa,
        bench_specialise,
        bench_btf_importance,
        bench_wiimote,
        bench_formats,
        bench_compress_svd,  # synthetic only; --real alu wallpaper by hand
        bench_accuracy,  # last: it rewrites its section of docs/accuracy.md
    ):
        print(f"\n## {module.__name__}\n{module.__doc__.strip()}\n")
        print(module.main())
