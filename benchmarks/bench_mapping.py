"""What texel filtering and Box mapping cost: the same scene (bench_viewport's alu sphere on a
wallpaper floor) with every material set to each placement, measured side by side in one run.

Linear filtering decodes 4 texels per lookup (core/mapping.py), Box mapping up to 3
projections (1 away from edges with blend 0.2); the ratios are against nearest UV lookups.
OpenCL: F12's deterministic mode (64 lights, 320×240); GLSL: moderngl, one pass of 16 lights
at 320×240; numpy: 10⁵ reference lookups on alu.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from bench_viewport import bench_scene
from common import table, timed

from btf_addon.core.mapping import filtered_evaluate
from btf_addon.scene.scene import Scene

PLACEMENTS = (
    ("UV, nearest", {"mapping": "UV", "texel_filter": "NEAREST"}),
    ("UV, linear (4 decodes)", {"mapping": "UV", "texel_filter": "LINEAR"}),
    ("Box 0.2, linear", {"mapping": "BOX", "texel_filter": "LINEAR", "box_blend": 0.2}),
)


def with_placement(scene: Scene, **fields) -> Scene:
    materials = [dataclasses.replace(m, **fields) for m in scene.materials]
    return dataclasses.replace(scene, materials=materials)


def cl_time(scene: Scene, lights) -> float | None:
    from btf_addon.cl.context import OpenCLUnavailableError, create_context
    from btf_addon.cl.renderer import CLRenderer

    try:
        ctx = create_context()
    except OpenCLUnavailableError as exc:
        print(f"OpenCL skipped: {exc}")
        return None
    renderer = CLRenderer(scene, 320, 240, ctx)
    renderer.render_direct(lights.prefix(1))  # warm-up: build or load the kernel
    t, _ = timed(renderer.render_direct, lights, repeat=2)
    return t


def gl_time(scene: Scene, lights) -> float:
    from btf_addon.gl.renderer import GLSLRenderer

    renderer = GLSLRenderer(scene, 320, 240)
    renderer.set_lights(lights, 16)
    best = float("inf")
    for _ in range(3):
        renderer.restart()
        t0 = time.perf_counter()
        renderer.render_pass()
        renderer.resolve()
        best = min(best, time.perf_counter() - t0)
    renderer.release()
    return best


def main() -> str:
    base = bench_scene()
    lights = base.environment.virtual_lights(64)
    ball = base.materials[0].btf
    rng = np.random.default_rng(1)
    uv = rng.uniform(-2, 2, size=(100_000, 2))
    d = rng.normal(size=(100_000, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.1
    rows, first = [], None
    for label, fields in PLACEMENTS:
        scene = with_placement(base, **fields)
        t_cl = cl_time(scene, lights)
        t_gl = gl_time(scene, lights.prefix(16))
        # numpy: the filtered lookup alone (Box mapping's projections are not timed there)
        t_np = None
        if fields["mapping"] == "UV":
            t_np, _ = timed(filtered_evaluate, ball, uv, d, d[::-1], fields["texel_filter"])
        now = (t_cl, t_gl, t_np)
        first = first or now
        rows.append(
            [
                label,
                "-" if t_cl is None else round(t_cl, 3),
                "-" if t_cl is None else round(t_cl / first[0], 2),
                round(t_gl * 1e3, 1),
                round(t_gl / first[1], 2),
                "-" if t_np is None else round(t_np, 3),
                "-" if t_np is None else round(t_np / first[2], 2),
            ]
        )
    return table(
        [
            "placement",
            "OpenCL F12 s",
            "× nearest",
            "GLSL pass ms",
            "× nearest",
            "numpy 10⁵ lookups s",
            "× nearest",
        ],
        rows,
    )


if __name__ == "__main__":
    print(main())
