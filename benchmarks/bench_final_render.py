"""OpenCL final render (deterministic direct lighting) on the device picked by default.

1. Time vs resolution (same scene as bench_viewport): per light in the deterministic mode (64
   lights), per sample in the Sampled mode (16 samples, 2 bounces).
3. The Sampled mode's knobs: samples per pixel and bounce limit — time and relative RMSE against
   a 2048-sample, 8-bounce image of the same view (96×72, sphere on a plane).
2. What "simulate only what the scene needs" saves: a single convex sphere rendered with the
   analysed kernel (no shadow rays) and with the full kernel (shadow rays forced on), side by
   side in the same run, plus the image difference between them.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from bench_viewport import bench_scene
from common import table

from btf_addon.cl.context import create_context
from btf_addon.cl.renderer import CLRenderer
from btf_addon.scene.analysis import analyse
from btf_addon.scene.scene import Scene


def timed_render(renderer: CLRenderer, lights, repeat: int = 2) -> tuple[float, np.ndarray]:
    best, image = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        image = renderer.render_direct(lights).combined[..., :3]
        best = min(best, time.perf_counter() - t0)
    return best, image


def main() -> str:
    ctx = create_context()
    scene = bench_scene()
    lights = scene.environment.virtual_lights(64)
    CLRenderer(scene, 8, 8, ctx).render_direct(lights)  # warm-up: compile (or load) the kernel
    rows = []
    for w, h in ((320, 240), (640, 480), (1280, 720)):
        r = CLRenderer(scene, w, h, ctx)
        t, _ = timed_render(r, lights, repeat=1)
        t0 = time.perf_counter()
        r.render_sampled(16, seed=1, max_bounces=2)
        t_sampled = time.perf_counter() - t0
        rows.append(
            [
                f"{w}×{h}",
                round(t, 2),
                round(t / (w * h * 64) * 1e9, 1),
                round(t_sampled / 16, 3),
                round(t_sampled / (w * h * 16) * 1e9, 1),
            ]
        )
    out = [
        f"device: {ctx.device_name}",
        table(
            [
                "resolution",
                "direct: s (64 lights, shadows)",
                "ns per pixel·light",
                "sampled (2 bounces): s per sample",
                "ns per pixel·sample",
            ],
            rows,
        ),
    ]

    sphere_only = Scene(scene.meshes[:1], scene.materials[:1], scene.camera, scene.environment)
    features = analyse(sphere_only)
    fast = CLRenderer(sphere_only, 640, 480, ctx, features)
    full = CLRenderer(sphere_only, 640, 480, ctx, dataclasses.replace(features, shadows=True))
    t_fast, img_fast = timed_render(fast, lights)
    t_full, img_full = timed_render(full, lights)
    diff = float(np.sqrt(np.mean((img_fast - img_full) ** 2)) / np.sqrt(np.mean(img_full**2)))
    out.append(
        table(
            ["kernel (sphere only, 640×480, 64 lights)", "s", "speed-up", "rel. RMSE"],
            [
                [
                    "analysed: HAS_SHADOWS=0",
                    round(t_fast, 3),
                    round(t_full / t_fast, 2),
                    round(diff, 5),
                ],
                ["full: HAS_SHADOWS=1", round(t_full, 3), 1.0, 0.0],
            ],
        )
    )
    small = CLRenderer(scene, 96, 72, ctx)
    reference = small.render_sampled(2048, seed=99, max_bounces=8)[..., :3]
    rows = []
    for bounces in (0, 2, 4):
        for spp in (16, 64, 256):
            t0 = time.perf_counter()
            image = small.render_sampled(spp, seed=1, max_bounces=bounces)[..., :3]
            seconds = time.perf_counter() - t0
            err = float(np.sqrt(np.mean((image - reference) ** 2)) / np.sqrt(np.mean(reference**2)))
            rows.append([bounces, spp, round(seconds, 2), round(err, 4)])
    out.append(table(["bounces (96×72)", "samples", "s", "rel. RMSE vs 2048 spp, 8 bounces"], rows))
    return "\n\n".join(out)


if __name__ == "__main__":
    print(main())
