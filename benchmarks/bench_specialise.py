"""What each kernel specialisation (btf_addon/scene/analysis.py) saves in the final render.

One scene: an alu MLVQ sphere on an alu ground plane (shadows and bounces on), one sun light,
a black World. The Sampled mode (render_env_mis, 1 bounce) renders it with the program that
compiles every path (the unspecialised one) and with programs leaving out one thing the scene
lacks at a time, then all of them (what ``analyse`` picks). Launches use the fixed split so the
images compare bit for bit. Compile times are measured with empty caches (PoCL's own cache off).

Usage: ``python benchmarks/bench_specialise.py``.
"""

from __future__ import annotations

import atexit
import dataclasses
import os
import shutil
import tempfile
import time

import numpy as np
from common import SHARED_BTFBASE, table, timed

W, H, SAMPLES, BOUNCES, ROUNDS = 96, 72, 24, 1, 3


def scene():
    from btf_addon.core.codecs.mlvq import MLVQBTF
    from btf_addon.core.sampling.envmap import Environment
    from btf_addon.scene.lights import SunLight
    from btf_addon.scene.primitives import plane, uv_sphere
    from btf_addon.scene.scene import Camera, Material, Scene, look_at

    ground = plane(6.0, material=0)
    ground.world_from_object = np.eye(4)
    ground.world_from_object[2, 3] = -1.0
    sun = SunLight(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), np.ones(3) * 3)
    return Scene(
        [uv_sphere(1.0, 48, 24), ground],
        [Material(MLVQBTF.from_directory(SHARED_BTFBASE / "alu"), uv_scale=2.0)],
        Camera(np.asarray(look_at((0.0, -4.0, 1.0), (0, 0, 0)))),
        Environment.constant((0.0, 0.0, 0.0)),
        lights=[sun],
    )


def main() -> str:
    os.environ.setdefault("POCL_KERNEL_CACHE", "0")  # compile times without PoCL's own cache
    from btf_addon.cl import programs
    from btf_addon.cl.context import create_context
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.scene.analysis import SceneFeatures, analyse

    cache = tempfile.mkdtemp(prefix="bench-specialise-")
    atexit.register(shutil.rmtree, cache, ignore_errors=True)
    programs.set_cache_dir(cache)
    ctx = create_context()
    s = scene()
    full = SceneFeatures(shadows=True, environment_texture=False)
    fast = analyse(s)
    variants = {
        "every path (unspecialised)": full,
        "codecs: MLVQ only": dataclasses.replace(full, codecs=fast.codecs),
        "lights: sun only": dataclasses.replace(full, point_lights=False, area_lights=False),
        "black World: no environment sampling": dataclasses.replace(full, environment=False),
        "all of the above (analyse)": fast,
    }
    built = {}
    for name, features in variants.items():
        t0 = time.perf_counter()
        renderer = CLRenderer(s, W, H, ctx, features)
        built[name] = (renderer, time.perf_counter() - t0)
        renderer.fixed_launch_split = True
        renderer.render_sampled(1)  # warm-up: PoCL specialises the work-group function
    best = dict.fromkeys(variants, float("inf"))
    images = {}
    for _ in range(ROUNDS):  # interleaved rounds: the machine's load drifts alike for all
        for name, (renderer, _) in built.items():
            t, images[name] = timed(renderer.render_sampled, SAMPLES, seed=1, max_bounces=BOUNCES)
            best[name] = min(best[name], t)
    ref_name = next(iter(variants))
    rows = [
        [
            name,
            round(built[name][1], 2),
            round(best[name], 3),
            f"{best[ref_name] / best[name]:.2f}×",
            f"{float(np.abs(images[name] - images[ref_name]).max()):.3g}",
        ]
        for name in variants
    ]
    return (
        table(
            [
                "program",
                "build s (empty caches)",
                "render s",
                "speed × unspecialised",
                "max |Δ| vs unspecialised",
            ],
            rows,
        )
        + f"\n\n{W}×{H}, {SAMPLES} samples, {BOUNCES} bounce, best of {ROUNDS} interleaved"
        f" rounds, device {ctx.device_name}."
    )


if __name__ == "__main__":
    print(main())
