"""Render the user guide's mapping picture (docs/images/mapping-cube.png) with the project's own
OpenCL final render: one synthetic material on Blender's default cube, three ways —
UV 1:1 (one tile per UV square, so a face shows a quarter tile), UV at real-world size, and
Box mapping at real-world size. Synthetic on purpose: pictures in the repository never show
the BTFbase research data.

    python tools/render_mapping_picture.py [--output docs/images/mapping-cube.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from helpers import studiolights_dir  # noqa: E402

from btf_addon.cl.context import create_context  # noqa: E402
from btf_addon.cl.renderer import CLRenderer  # noqa: E402
from btf_addon.core.codecs.dense import tabulate  # noqa: E402
from btf_addon.core.codecs.microgeometry import woven  # noqa: E402
from btf_addon.core.formats.imageio import read_exr, srgb8_from_linear, write_png  # noqa: E402
from btf_addon.core.grid import uniform_ring_grid  # noqa: E402
from btf_addon.core.sampling.envmap import Environment  # noqa: E402
from btf_addon.scene.primitives import cube  # noqa: E402
from btf_addon.scene.scene import Camera, Material, Scene, look_at  # noqa: E402

WIDTH, HEIGHT = 320, 240
TILE_MM = 500.0  # a coarse weave (a rug): 4 tiles across a 2 m face, readable at this size


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=ROOT / "docs/images/mapping-cube.png")
    parser.add_argument("--lights", type=int, default=64)
    args = parser.parse_args()
    grid = uniform_ring_grid(15.0)
    fabric = tabulate(woven(texels=16, tile_size_mm=TILE_MM), grid, grid)
    env = Environment(read_exr(studiolights_dir() / "forest.exr"))
    lights = env.virtual_lights(args.lights, seed=1)
    # Blender's default camera: 50 mm lens on a 36 mm sensor (39.6° across the wider side).
    fov_x = 2 * np.arctan(18.0 / 50.0)
    fov_y = 2 * np.arctan(np.tan(fov_x / 2) * HEIGHT / WIDTH)
    # From the default camera's direction, closer: the cube fills the frame.
    eye = 0.6 * np.array([7.36, -6.93, 4.96])
    camera = Camera(look_at(eye, (0, 0, 0)), fov_y_rad=float(fov_y))
    ctx = create_context()
    panels = []
    for placement in (
        {"mapping": "UV"},
        {"mapping": "UV", "real_world": True},
        {"mapping": "BOX", "real_world": True, "box_blend": 0.2},
    ):
        material = Material(fabric, texel_filter="LINEAR", **placement)
        scene = Scene([cube(2.0)], [material], camera, env)
        image = CLRenderer(scene, WIDTH, HEIGHT, ctx).render_direct(lights).combined[..., :3]
        panels.append(image)
        print(f"rendered {placement}")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    write_png(args.output, srgb8_from_linear(np.hstack(panels)))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
