"""Anti-aliasing and F12's default mode: error against supersampled references vs time, side
by side in one run (issue 21). Small images, so it runs in a minute or two on a CPU device.

1. The anti-aliasing knobs on the aliasing case (tests/aa_scenes.py: a checkered plane
   receding to the horizon, 64×48), lit by 64 virtual lights of the forest World:
   - Virtual Lights, ``aa_samples`` subpixels, the 64 lights split over them (the default: the
     converged viewport's image, at the cost of about one ray per pixel) or all 64 at each
     subpixel (``aa_samples`` times the cost); reference: all lights at 256 subpixels.
   - Sampled, samples per pixel through the filter; reference: 512 samples (the World's true
     integral, not the 64 lights'), so its error also holds the lighting noise.
2. F12's default mode on the glossy case (a GGX sphere, roughness 0.15, under the forest World,
   48×36): Virtual Lights (64 and 256 lights, 16 split subpixels: what the old default
   rendered, anti-aliased) against Sampled at 16…256 samples, all against a 1024-sample
   Sampled image.
   The virtual lights' error here is their blotches in the reflection: it does not fall with
   time. The hybrid (glossy lobes sampled, diffuse ones from the virtual lights) is not built:
   see docs/accuracy.md for why Sampled is the default instead.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from common import table
from helpers import studiolights_dir

from btf_addon.cl.context import create_context
from btf_addon.cl.renderer import CLRenderer
from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at


def horizon_scene():
    from aa_scenes import horizon_scene  # tests/ is on the path once common is imported

    return horizon_scene()


def rel_rmse(a, b) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))


def timed(fn):
    t0 = time.perf_counter()
    image = fn()
    return time.perf_counter() - t0, image[..., :3]


def knobs(ctx, env: Environment) -> str:
    scene = horizon_scene()
    scene.environment = env
    renderer = CLRenderer(scene, 64, 48, ctx)
    lights = env.virtual_lights(64, seed=1)
    direct = renderer.render_direct
    reference = direct(lights, aa_samples=256, split_lights=False).combined[..., :3]
    rows = []
    for n in (1, 4, 16, 64):
        for split in (True, False):
            if n == 1 and not split:
                continue
            seconds, image = timed(
                lambda n=n, split=split: direct(lights, aa_samples=n, split_lights=split).combined
            )
            label = "pixel centre" if n == 1 else ("split" if split else "all lights")
            rows.append(["Virtual Lights", n, label, round(seconds, 3), rel_rmse(image, reference)])
    sampled_reference = renderer.render_sampled(512, seed=99)[..., :3]
    for spp in (4, 16, 64, 256):
        seconds, image = timed(lambda spp=spp: renderer.render_sampled(spp, seed=1))
        rows.append(
            ["Sampled", spp, "filter", round(seconds, 3), rel_rmse(image, sampled_reference)]
        )
    return table(
        ["checker to the horizon (64×48)", "samples", "lights", "s", "rel. RMSE vs reference"],
        [[*r[:4], round(r[4], 4)] for r in rows],
    )


def default_mode(ctx, env: Environment) -> str:
    cam = Camera(look_at((0.0, -3.5, 0.8), (0.0, 0.0, 0.0)), fov_y_rad=np.radians(35.0))
    ball = Material(GGXBTF((0.9, 0.7, 0.5), 0.15))
    scene = Scene([uv_sphere(1.0, segments=96, rings=48)], [ball], cam, env)
    renderer = CLRenderer(scene, 48, 36, ctx)
    reference = renderer.render_sampled(1024, seed=99)[..., :3]
    rows = []
    for n in (64, 256):
        lights = env.virtual_lights(n)
        seconds, image = timed(
            lambda lights=lights: renderer.render_direct(lights, aa_samples=16).combined
        )
        rows.append(
            [f"Virtual Lights, {n} lights, 16 AA", round(seconds, 3), rel_rmse(image, reference)]
        )
    for spp in (16, 64, 256):
        seconds, image = timed(lambda spp=spp: renderer.render_sampled(spp, seed=1))
        rows.append([f"Sampled, {spp} samples", round(seconds, 3), rel_rmse(image, reference)])
    return table(
        ["glossy sphere (GGX 0.15, 48×36)", "s", "rel. RMSE vs 1024-sample Sampled"],
        [[*r[:2], round(r[2], 4)] for r in rows],
    )


def main() -> str:
    ctx = create_context()
    env = Environment(read_exr(studiolights_dir() / "forest.exr"))
    CLRenderer(horizon_scene(), 8, 8, ctx).render_direct(env.virtual_lights(1))  # compile
    parts = [f"device: {ctx.device_name}"]
    for part in (knobs, default_mode):
        parts.append(part(ctx, env))
        print(parts[-1], file=sys.stderr, flush=True)  # shown as it finishes
    return "\n\n".join(parts)


if __name__ == "__main__":
    print(main())
