"""Time to reach the same error as Cycles, side by side in one process.

The comparison scene of tests/blender/test_cycles_compare.py (48×36, smooth sphere on a ground
plane, Lambertian 0.8, forest.exr, 2 bounces on both sides). Reference: Cycles at 4096 samples
with its own seed. Each renderer then renders the full frame from the Blender scene at rising
sample counts — Cycles through bpy.ops.render.render, ours as export + BVH + OpenCL upload +
render_sampled (the program compiled once beforehand, as the disk cache makes it on any second
render) — and is timed. Error: relative RMSE against the reference; it includes the reference's
own noise, which is the same for both. The time to reach an error is interpolated log–log
between the measured points.
"""

from __future__ import annotations

import atexit
import itertools
import math
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from common import table

TARGETS = (0.10, 0.05, 0.02)


def time_to_error(points: list[tuple[float, float]], target: float) -> float:
    """points: (seconds, error) by rising samples → interpolated seconds at ``target``
    (nan outside the measured range)."""
    for (t0, e0), (t1, e1) in itertools.pairwise(points):
        if e0 >= target >= e1 and e0 > e1:
            a = (math.log(e0) - math.log(target)) / (math.log(e0) - math.log(e1))
            return math.exp(math.log(t0) + a * (math.log(t1) - math.log(t0)))
    return float("nan")


def main() -> str:
    import bpy
    from cycles_scenes import SIZE, build, cycles_reference, relative_rmse

    import btf_addon
    from btf_addon.blender.export import export_scene
    from btf_addon.cl.context import create_context
    from btf_addon.cl.renderer import CLRenderer

    btf_addon.register()
    try:
        tmp = Path(tempfile.mkdtemp(prefix="btf-bench-cycles-"))
        atexit.register(shutil.rmtree, tmp, ignore_errors=True)
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        scene = build(bpy, tmp, "diffuse", ground=True)
        bounces = 2
        reference = cycles_reference(bpy, scene, tmp, 4096, bounces, seed=101)[..., :3]
        ctx = create_context()

        def ours(samples: int) -> np.ndarray:
            depsgraph = bpy.context.evaluated_depsgraph_get()
            renderer = CLRenderer(export_scene(depsgraph, *SIZE), *SIZE, ctx)
            return renderer.render_sampled(samples, seed=samples, max_bounces=bounces)[..., :3]

        ours(1)  # compile (and cache) the program, as any render after the first finds it
        rows, curves = [], {"Cycles": [], "ours (OpenCL)": []}
        for samples in (16, 64, 256, 1024):
            for name, render in (
                ("Cycles", lambda s: cycles_reference(bpy, scene, tmp, s, bounces, seed=7)),
                ("ours (OpenCL)", ours),
            ):
                t0 = time.perf_counter()
                image = render(samples)[..., :3]
                seconds = time.perf_counter() - t0
                error = relative_rmse(image, reference)
                curves[name].append((seconds, error))
                rows.append([name, samples, round(seconds, 3), round(error, 4)])
        out = [table(["renderer", "samples", "s", "relative RMSE vs Cycles 4096"], rows), ""]
        ratio_rows = []
        for target in TARGETS:
            t_cycles = time_to_error(curves["Cycles"], target)
            t_ours = time_to_error(curves["ours (OpenCL)"], target)
            ratio_rows.append(
                [f"{target:.0%}", round(t_cycles, 3), round(t_ours, 3), round(t_cycles / t_ours, 2)]
            )
        out.append(
            table(["error", "Cycles s", "ours s", "Cycles ÷ ours (> 1: ours faster)"], ratio_rows)
        )
        return "\n".join(out)
    finally:
        btf_addon.unregister()


if __name__ == "__main__":
    print(main())
