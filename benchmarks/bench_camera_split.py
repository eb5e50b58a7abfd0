"""Samples per Camera Ray: error against time, side by side in one process.

Scenes of benchmarks/bench_vs_cycles.py at 48×36 (the demo at 64×48): the lone smooth sphere,
Lambertian 0.8 under forest.exr; the lone sphere, GGX roughness 0.2 under city.exr; the
Lambertian sphere on a ground (2 bounces); the demo (BTFs, 4 bounces). One CLRenderer per
scene (the program compiled before timing), Blender's default film filter, Clamp Indirect off.
Every split k renders the same sample counts with 3 seeds; time is the median, error the mean
relative RMSE against a reference: Cycles at 16384 samples for the spheres (a renderer nobody
here wrote), ours at 16384 samples with a camera ray per sample and another seed for the demo
(Cycles cannot read BTFs). "Gain at equal error" is (t·e²) at k = 1 over (t·e²) at k: Monte
Carlo error falls as 1/√time, so it is how much sooner k reaches the error k = 1 reaches.

    python benchmarks/bench_camera_split.py [--quick]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from common import table

SPLITS = (1, 2, 4, 8, 16)
SAMPLES = (64, 256, 1024)
SEEDS = 3
REFERENCE_SAMPLES = 16384
#: name -> (bench_vs_cycles.build_scene's kind, GGX roughness, World, frame size, ground),
#: and the bounces rendered
SCENES = {
    "sphere, Lambertian 0.8, forest": (("diffuse", 0.3, "forest", (48, 36), False), 0),
    "sphere, GGX 0.2, city": (("glossy", 0.2, "city", (48, 36), False), 0),
    "sphere on ground, 2 bounces": (("diffuse", 0.3, "forest", (48, 36), True), 2),
    "demo (BTFs, 4 bounces)": (("demo", 0.0, "forest", (64, 48), False), 4),
}


def _scene(bpy, name: str, tmp: Path):
    """(exported scene, size, reference image; None for the demo, which Cycles cannot read)."""
    from bench_vs_cycles import build_scene
    from cycles_scenes import cycles_reference

    from btf_addon.blender.export import export_scene

    spec, bounces = SCENES[name]
    scene = build_scene(bpy, tmp, *spec)
    size = spec[3]
    exported = export_scene(bpy.context.evaluated_depsgraph_get(), *size)
    if spec[0] == "demo":
        return exported, size, None
    reference = cycles_reference(bpy, scene, tmp, REFERENCE_SAMPLES, bounces, seed=101)
    return exported, size, reference[..., :3]


def bench_renderers(prefix: str):
    """(scene name, renderer, reference, bounces) for each of SCENES, in this registered
    Blender, the renderer compiled and its tables built; the demo's reference is ours with a
    camera ray per sample. Shared with bench_mis_compensation.py."""
    import bpy

    import btf_addon
    from btf_addon.cl.context import create_context
    from btf_addon.cl.renderer import CLRenderer

    btf_addon.register()
    tmp = Path(tempfile.mkdtemp(prefix=prefix))
    try:
        ctx = create_context()
        for name, (_, bounces) in SCENES.items():
            exported, size, reference = _scene(bpy, name, tmp)
            renderer = CLRenderer(exported, *size, ctx)
            renderer.render_sampled(1)  # compile and build the tables outside the timing
            if reference is None:  # the demo: our own, a camera ray per sample
                reference = renderer.render_sampled(REFERENCE_SAMPLES, 101, None, bounces)
            yield name, renderer, reference[..., :3], bounces
    finally:
        btf_addon.unregister()
        shutil.rmtree(tmp, ignore_errors=True)


def main(quick: bool = False) -> str:
    from cycles_scenes import relative_rmse

    samples = SAMPLES[:2] if quick else SAMPLES
    rows = []
    for name, renderer, reference, bounces in bench_renderers("btf-bench-split-"):
        for n in samples:
            base = None
            for k in SPLITS:
                renderer.samples_per_camera_ray = k
                seconds, errors = [], []
                for seed in range(SEEDS):
                    t0 = time.perf_counter()
                    image = renderer.render_sampled(n, seed, None, bounces)[..., :3]
                    seconds.append(time.perf_counter() - t0)
                    errors.append(relative_rmse(image, reference))
                t, e = float(np.median(seconds)), float(np.mean(errors))
                base = base or t * e * e
                gain = round(base / (t * e * e), 2)
                rows.append([name, n, k, round(t, 3), round(e, 4), gain])
    header = ["scene", "samples", "per camera ray", "s", "relative RMSE", "gain at equal error"]
    return table(header, rows)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="64 and 256 samples only")
    print(main(parser.parse_args().quick))
