"""Importance sampling of measured BTFs (core/sampling/btf_importance.py) against cosine sampling.

One scene per material and World: a sphere of a real BTFbase material (alu: the sharpest
lobe we have; wallpaper) or of a GGX of roughness 0.25 tabulated on a 6° ring grid (a dense
codec with a sharp lobe, as measured data of a glossier material would be), under Blender's
bundled forest.exr or a uniform World (Blender's default grey: the environment's own sample
is uniform, so the BTF's sample carries the MIS weight), rendered in the Sampled mode
(render_env_mis: one environment sample and one BTF sample per pixel and sample, MIS) at pixel
centres, 64 × 48. The reference is the mean of both samplers at REFERENCE samples each (both
are unbiased, so their mean is too, with the noise of 2 × REFERENCE samples). For each sampler
and sample count: relative RMSE over the sphere's pixels and the render's wall time; then the
samples and the time the table needs to reach cosine sampling's error at each rung (log-log
interpolation of its own curve), as ratios (> 1: the table is faster); times are the best of 3
runs. Also the table's build time and size.

Usage: ``python benchmarks/bench_btf_importance.py``.
"""

from __future__ import annotations

import itertools
import time

import numpy as np
from common import SHARED_BTFBASE, table

W, H = 64, 48
LADDER = (4, 16, 64, 256)
REFERENCE = 2048
MATERIALS = ("alu", "wallpaper")


def scene(btf, env):
    from btf_addon.scene.primitives import uv_sphere
    from btf_addon.scene.scene import Camera, Material, Scene, look_at

    return Scene(
        [uv_sphere(1.0, segments=64, rings=32)],
        [Material(btf, uv_scale=2.0)],
        Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0))),
        env,
    )


def samples_for_error(spp: np.ndarray, err: np.ndarray, target: float) -> float:
    """Samples at which a curve (spp, err) reaches ``target`` (log-log interpolation; beyond
    its ends, the end segments' slopes)."""
    x, y = np.log(spp), np.log(err)
    i = int(np.clip(np.searchsorted(-y, -np.log(target)), 1, len(x) - 1))
    slope = (y[i] - y[i - 1]) / (x[i] - x[i - 1])
    return float(np.exp(x[i - 1] + (np.log(target) - y[i - 1]) / slope))


def render(renderer, importance: bool, spp: int, seed: int, repeat: int = 1):
    """(h, w, 3) Sampled image and its best wall time over ``repeat`` renders."""
    renderer.importance_sampling = importance
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        image = renderer.render_sampled(spp, seed=seed)[..., :3]
        best = min(best, time.perf_counter() - t0)
    return image, best


def main() -> str:
    from helpers import studiolights_dir

    from btf_addon.cl.context import create_context
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.core.codecs.analytic import GGXBTF
    from btf_addon.core.codecs.dense import tabulate
    from btf_addon.core.codecs.mlvq import MLVQBTF
    from btf_addon.core.formats.imageio import read_exr
    from btf_addon.core.grid import uniform_ring_grid
    from btf_addon.core.sampling import btf_importance
    from btf_addon.core.sampling.envmap import Environment

    ctx = create_context()
    worlds = {
        "forest": Environment(read_exr(studiolights_dir() / "forest.exr")),
        "uniform": Environment.constant((0.05, 0.05, 0.05)),
    }
    curves, ratios, builds = [], [], []
    materials = {name: MLVQBTF.from_directory(SHARED_BTFBASE / name) for name in MATERIALS}
    # A measured-style material with a sharp lobe: GGX (roughness 0.25) tabulated on a 6° ring
    # grid, a dense codec, sampled by its table like any measured one.
    grid = uniform_ring_grid(6.0)
    materials["ggx-dense"] = tabulate(GGXBTF((0.9, 0.6, 0.3), 0.25), grid, grid)
    for name, btf in materials.items():
        built = btf_importance.build(btf)
        builds.append([name, built.build_seconds, built.nbytes / 1024, built.grid, built.views])
    for (world, env), (name, btf) in itertools.product(worlds.items(), materials.items()):
        renderer = CLRenderer(scene(btf, env), W, H, ctx, film=None)
        renderer.fixed_launch_split = True
        renderer.importance_sampling = True
        renderer.render_sampled(1, seed=99)  # table built (and cached), program warm
        sphere = renderer.render_direct(env.virtual_lights(1)).depth < 1e9

        reference = 0.5 * (
            render(renderer, True, REFERENCE, 7)[0] + render(renderer, False, REFERENCE, 8)[0]
        )
        ref = reference[sphere]
        results = {}
        for importance in (False, True):
            errs, times = [], []
            for spp in LADDER:
                image, seconds = render(renderer, importance, spp, 1, repeat=3)
                err = np.sqrt(np.mean((image[sphere] - ref) ** 2)) / np.sqrt(np.mean(ref**2))
                errs.append(err), times.append(seconds)
            results[importance] = (np.array(errs), np.array(times))
        (e_cos, t_cos), (e_is, t_is) = results[False], results[True]
        for k, spp in enumerate(LADDER):
            curves.append([name, world, spp, e_cos[k], e_is[k], t_cos[k], t_is[k]])
            need = samples_for_error(np.array(LADDER, float), e_is, e_cos[k])
            time_need = np.interp(np.log(need), np.log(LADDER), np.log(t_is))
            ratios.append(
                [name, world, spp, e_cos[k], need, spp / need, t_cos[k] / np.exp(time_need)]
            )
    return "\n\n".join(
        [
            table(
                [
                    "material",
                    "World",
                    "samples",
                    "RMSE cosine",
                    "RMSE table",
                    "s cosine",
                    "s table",
                ],
                curves,
            ),
            table(
                [
                    "material",
                    "World",
                    "cosine samples",
                    "its RMSE",
                    "table samples for it",
                    "samples ratio",
                    "time ratio",
                ],
                ratios,
            ),
            table(["material", "build s", "table KiB", "grid", "view bins"], builds),
        ]
    )


if __name__ == "__main__":
    print(main())
