"""Adaptive sampling (render/adaptive.py, Noise Threshold): samples, time and error per threshold,
side by side in one process.

A GGX 0.3 sphere on a Lambertian 0.7 ground under forest.exr, the World filling the top of the
frame, 160×120, 256 samples, 4 bounces, F12's defaults otherwise (Blender's default film
filter, 4 samples per camera ray), Clamp Indirect off. One CLRenderer renders every threshold
for each seed in turn (0 first: adaptive sampling off); time is the median over the seeds,
error the root mean square of their relative RMSE against an 8192-sample render without
adaptive sampling (its own noise ≈ 0.6 %). The last column is the first row's error scaled to
the row's time by 1/√t: what fewer samples alone would have given in that time.

    python benchmarks/bench_adaptive.py [--quick]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import table

THRESHOLDS = (0.0, 0.005, 0.01, 0.025, 0.05)
SAMPLES = 256
REFERENCE_SAMPLES = 8192
SEEDS = (0, 1, 2)
SIZE = (160, 120)


def _scene():
    from helpers import studiolights_dir

    from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
    from btf_addon.core.formats.imageio import read_exr
    from btf_addon.core.sampling.envmap import Environment
    from btf_addon.scene.primitives import plane, uv_sphere
    from btf_addon.scene.scene import Camera, Material, Scene, look_at

    ground = plane(8.0, material=1)
    ground.world_from_object[2, 3] = -1.0
    return Scene(
        [uv_sphere(0.8, 48, 24), ground],
        [Material(GGXBTF(0.8, 0.3)), Material(LambertianBTF(0.7))],
        Camera(look_at((0.0, -5.0, 0.6), (0, 0, -0.4))),
        Environment(read_exr(studiolights_dir() / "forest.exr")),
    )


def main(quick: bool = False) -> str:
    from btf_addon.cl.context import create_context
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.render.accuracy.ladder import relative_rmse

    samples, reference_samples = (64, 1024) if quick else (SAMPLES, REFERENCE_SAMPLES)
    renderer = CLRenderer(_scene(), *SIZE, create_context(), importance_tables=True)
    renderer.samples_per_camera_ray = 4

    def render(threshold: float, n: int, seed: int) -> tuple[float, np.ndarray]:
        renderer.adaptive_threshold = threshold
        t0 = time.perf_counter()
        image = renderer.render_sampled(n, seed, max_bounces=4)[..., :3]
        return time.perf_counter() - t0, image

    reference = render(0.0, reference_samples, 99)[1]
    render(0.0, 4, 0)  # warm-up: the first launch pays the kernels' first use
    runs = {t: [] for t in THRESHOLDS}
    for seed in SEEDS:
        for threshold in THRESHOLDS:
            seconds, image = render(threshold, samples, seed)
            counts = renderer.sample_counts
            error = relative_rmse(image, reference)
            runs[threshold].append((seconds, error, counts.mean(), (counts < samples).mean()))
    rows = []
    t_off, e_off = (np.median([r[0] for r in runs[0.0]]), _rms([r[1] for r in runs[0.0]]))
    for threshold in THRESHOLDS:
        seconds = float(np.median([r[0] for r in runs[threshold]]))
        error = _rms([r[1] for r in runs[threshold]])
        rows.append(
            [
                "0 (off)" if threshold == 0 else f"{threshold:g}",
                round(float(np.mean([r[2] for r in runs[threshold]])), 1),
                f"{100 * np.mean([r[3] for r in runs[threshold]]):.0f} %",
                round(seconds, 2),
                f"{100 * error:.2f} %",
                f"{100 * e_off * np.sqrt(t_off / seconds):.2f} %",
            ]
        )
    header = [
        "Noise Threshold",
        "samples per pixel (mean)",
        "pixels stopped early",
        "s",
        "relative RMSE",
        "without adaptive sampling in the same time",
    ]
    return table(header, rows)


def _rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    print(main(parser.parse_args().quick))
