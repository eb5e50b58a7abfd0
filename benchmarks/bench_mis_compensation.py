"""MIS compensation of the World's next-event draws, the sun's draws of its own and the lobe
window: error against time, side by side in one process (core/sampling/envmap.py
``Environment.mis_tables``, ``Environment.sun_tables``, ``Environment.lobe_window``).

The scenes and references of benchmarks/bench_camera_split.py ``bench_renderers`` (Cycles at
16384 samples for the spheres, ours at 16384 for the demo), F12's defaults (Blender's default
film filter, 4 samples per camera ray), Clamp Indirect off. One CLRenderer per scene renders
with the plain tables (draws ∝ luminance · sin θ, as before), the compensated ones
(∝ max(L − L̄, 0) · sin θ), the compensated ones with the map's sun drawn on its own
(forest.exr and city.exr both have one), and those with the lobe window at glossy camera
vertices (F12's default; forest.exr has one, city.exr not) alternately, the same seeds for all;
time is the median, error the root mean square of the seeds' relative RMSE. "Gain at equal
error" is (t·e²) plain over (t·e²) of the row: how much sooner it reaches the plain one's error.

    python benchmarks/bench_mis_compensation.py [--quick]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from bench_camera_split import bench_renderers
from common import table

SAMPLES = (64, 256, 1024)
SEEDS = 6
#: (label, compensated tables, the sun's own draws, the lobe window); the first is what the
#: gains are against
CONFIGS = (
    ("plain", False, False, False),
    ("compensated", True, False, False),
    ("compensated + sun", True, True, False),
    ("compensated + sun + window", True, True, True),
)


def main(quick: bool = False) -> str:
    from cycles_scenes import relative_rmse

    samples = SAMPLES[:2] if quick else SAMPLES
    rows = []
    for name, renderer, reference, bounces in bench_renderers("btf-bench-mis-"):
        renderer.samples_per_camera_ray = 4  # F12's default
        for config in CONFIGS:  # every table uploaded outside the timing
            _, renderer.mis_compensation, renderer.sun_sampling, renderer.lobe_window = config
            renderer.render_sampled(1)
        for n in samples:
            seconds = {config: [] for config in CONFIGS}
            errors = {config: [] for config in CONFIGS}
            for seed in range(SEEDS):
                for config in CONFIGS:  # alternating: all meet the same load
                    _, renderer.mis_compensation, renderer.sun_sampling, renderer.lobe_window = (
                        config
                    )
                    t0 = time.perf_counter()
                    image = renderer.render_sampled(n, seed, None, bounces)[..., :3]
                    seconds[config].append(time.perf_counter() - t0)
                    errors[config].append(relative_rmse(image, reference))
            base = None
            for config in CONFIGS:
                t = float(np.median(seconds[config]))
                e = float(np.sqrt(np.mean(np.square(errors[config]))))
                base = base or t * e * e
                gain = round(base / (t * e * e), 2) if config is not CONFIGS[0] else ""
                rows.append([name, n, config[0], round(t, 3), round(e, 4), gain])
    header = ["scene", "samples", "tables", "s", "relative RMSE", "gain at equal error"]
    return table(header, rows)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="64 and 256 samples only")
    print(main(parser.parse_args().quick))
