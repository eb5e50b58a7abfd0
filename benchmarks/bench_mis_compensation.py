"""MIS compensation of the World's next-event draws: error against time, side by side in one
process (core/sampling/envmap.py ``Environment.mis_tables``).

The scenes and references of benchmarks/bench_camera_split.py ``bench_renderers`` (Cycles at
16384 samples for the spheres, ours at 16384 for the demo), F12's defaults (Blender's default
film filter, 4 samples per camera ray), Clamp Indirect off. One CLRenderer per scene renders
with the plain tables (draws ∝ luminance · sin θ, as before) and the compensated ones
(∝ max(L − L̄, 0) · sin θ) alternately, the same seeds for both; time is the median, error
the root mean square of the seeds' relative RMSE. "Gain at equal error" is (t·e²) plain over
(t·e²) compensated: how much sooner the compensated render reaches the plain one's error.

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


def main(quick: bool = False) -> str:
    from cycles_scenes import relative_rmse

    samples = SAMPLES[:2] if quick else SAMPLES
    rows = []
    for name, renderer, reference, bounces in bench_renderers("btf-bench-mis-"):
        renderer.samples_per_camera_ray = 4  # F12's default
        renderer.mis_compensation = False  # the plain tables too, outside the timing
        renderer.render_sampled(1)
        for n in samples:
            seconds = {False: [], True: []}
            errors = {False: [], True: []}
            for seed in range(SEEDS):
                for compensated in (False, True):  # alternating: both meet the same load
                    renderer.mis_compensation = compensated
                    t0 = time.perf_counter()
                    image = renderer.render_sampled(n, seed, None, bounces)[..., :3]
                    seconds[compensated].append(time.perf_counter() - t0)
                    errors[compensated].append(relative_rmse(image, reference))
            cost = {}
            for compensated in (False, True):
                t = float(np.median(seconds[compensated]))
                e = float(np.sqrt(np.mean(np.square(errors[compensated]))))
                cost[compensated] = t * e * e
                rows.append([name, n, "compensated" if compensated else "plain"])
                rows[-1] += [round(t, 3), round(e, 4)]
            rows[-1].append(round(cost[False] / cost[True], 2))
            rows[-2].append("")
    header = ["scene", "samples", "tables", "s", "relative RMSE", "gain at equal error"]
    return table(header, rows)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="64 and 256 samples only")
    print(main(parser.parse_args().quick))
