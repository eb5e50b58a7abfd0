"""The light bake (issue 34): how close the baked drawer comes to F12, and what the bake costs.

Two scenes under forest.exr, F12's defaults (4 bounces, Clamp Indirect 10, Blackman-Harris
1.5 px): the demo (woven BTF on Suzanne, a glossy sphere beside it; bpy builds and exports it as
F12 does) and "ground": a woven BTF sphere resting on a woven BTF ground next to a glossy cube.

The reference is a Sampled F12 of SAMPLES_REF paths per pixel through the same camera and film.
Each image is compared by relative RMSE (render/accuracy/ladder.py) over the pixels where a
surface is seen:
- the unbaked drawer: its converged image (render_direct, 1024 unshadowed virtual lights,
  16 film subpixels), what the viewport and VR show today;
- representation A, light per unit response (the chosen one): the bake's value per point and
  view times the response decoded live at the pixel's texel; its first frame is converged;
- representation C, a shadow-and-bounce ratio: the full bake over an unshadowed, unbounced bake
  of the same points, times the live unshadowed image — converged only once the live image is.
Each knob is swept from the default (spacing, view bins, samples); the bake's time includes its
analysis and grid, not the program build (the first build is timed on its own).

Usage: ``python benchmarks/bench_bake.py [--quick]``.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import table
from helpers import studiolights_dir

W, H = 96, 72
SAMPLES_REF = 4096
LIGHTS = 1024


def demo_scene(tmp: Path):
    import bpy

    import btf_addon
    from btf_addon.blender.demo import build_demo_scene
    from btf_addon.blender.export import export_scene

    btf_addon.register()  # the engine the demo scene names
    try:
        build_demo_scene(tmp / "demo_data", resolution=(W, H))
        return export_scene(bpy.context.evaluated_depsgraph_get(), W, H)
    finally:
        btf_addon.unregister()


def ground_scene(tmp: Path):
    from btf_addon.core.codecs.dense import tabulate
    from btf_addon.core.codecs.presets import make_preset
    from btf_addon.core.formats.container import read_container, write_container
    from btf_addon.core.formats.imageio import read_exr
    from btf_addon.core.sampling.envmap import Environment
    from btf_addon.scene.primitives import cube, plane, uv_sphere
    from btf_addon.scene.scene import Camera, Material, Scene, look_at

    woven_file = tmp / "woven-ubo81.btfm"
    if not woven_file.exists():
        write_container(woven_file, tabulate(make_preset("woven", texels=8)))
    woven = read_container(woven_file)
    ground = plane(6.0, material=0, name="Ground")
    ball = uv_sphere(0.6, 48, 24, material=1, name="Ball")
    ball.world_from_object = np.eye(4)
    ball.world_from_object[:3, 3] = (0.0, 0.0, 0.6)  # resting on the ground
    box = cube(0.8, material=2, name="Box")
    box.world_from_object = np.eye(4)
    box.world_from_object[:3, 3] = (1.1, 0.4, 0.4)
    return Scene(
        [ground, ball, box],
        [
            Material(woven, uv_scale=6.0, name="WovenGround"),
            Material(woven, uv_scale=3.0, name="WovenBall"),
            Material(make_preset("ggx", albedo=(0.9, 0.55, 0.2), roughness=0.35), name="Glossy"),
        ],
        Camera(np.asarray(look_at((0.4, -3.6, 1.6), (0.4, 0.0, 0.4)))),
        Environment(read_exr(studiolights_dir() / "forest.exr")),
    )


def masked_rmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """Relative RMSE (render/accuracy/ladder.py's definition) over the pixels of ``mask``."""
    d = image[..., :3][mask] - reference[..., :3][mask]
    return float(np.sqrt((d**2).mean()) / np.sqrt((reference[..., :3][mask] ** 2).mean()))


def mesh_masks(renderer, grid, baked) -> list[np.ndarray]:
    """Per mesh, the pixels whose every film subpixel sees it: a bake of ones on its points
    played back without the response."""
    from btf_addon.cl.bake import render_baked

    masks = []
    for m in range(len(renderer.scene.meshes)):
        ones = np.zeros((grid.point_count, *baked.ratio.shape[1:]), np.float32)
        ones[grid.point_mesh == m] = 1.0
        image = render_baked(
            renderer, grid, dataclasses.replace(baked, ratio=ones), times_response=False
        )
        masks.append(image[..., 0] > 0.999)
    return masks


def errors(image, reference, masks, names) -> str:
    """The relative RMSE over every surface pixel, then per mesh."""
    every = np.any(masks, axis=0)
    per = ", ".join(
        f"{n} {masked_rmse(image, reference, m):.3f}" for n, m in zip(names, masks, strict=True)
    )
    return f"{masked_rmse(image, reference, every):.3f} ({per})"


def measure(name: str, scene, ctx, quick: bool) -> list[list]:
    from btf_addon.cl.bake import BakedLight, BakeKnobs, bake_light, render_baked
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.scene.analysis import analyse
    from btf_addon.scene.bake_analysis import bake_needs
    from btf_addon.scene.bake_points import build_grid

    renderer = CLRenderer(scene, W, H, ctx)
    renderer.clamp_indirect = 10.0  # F12's default
    t0 = time.perf_counter()
    reference = renderer.render_sampled(512 if quick else SAMPLES_REF, max_bounces=4)
    ref_seconds = time.perf_counter() - t0
    flat = dataclasses.replace(analyse(scene), shadows=False)  # the drawer's: no shadow rays
    unshadowed = CLRenderer(scene, W, H, ctx, features=flat)
    live = unshadowed.render_direct(scene.environment.virtual_lights(LIGHTS), aa_samples=16)
    needs = bake_needs(scene)
    names = [m.name for m in scene.meshes]
    corners = [m.world_space_corners() for m in scene.meshes]
    defaults = BakeKnobs()
    sweeps = [("default", {})]
    if not quick:
        sweeps += [
            ("spacing 0.1", {"spacing": 0.1}),
            ("view bins 3", {"view_bins": 3}),
            ("view bins 7", {"view_bins": 7}),
            ("samples 32", {"samples": 32}),
            ("samples 128", {"samples": 128}),
        ]
    rows, masks = [], None
    for label, change in sweeps:
        knobs = dataclasses.replace(defaults, **change)
        t0 = time.perf_counter()
        grid = build_grid(corners, knobs.spacing, footprint=knobs.footprint)
        chosen = np.flatnonzero(np.array([n.anything for n in needs])[grid.point_mesh])
        feet = grid.footprint_tri[chosen], grid.footprint_bary[chosen]
        part = bake_light(renderer, *feet, knobs.view_bins, knobs.samples, knobs.bounces)
        seconds = time.perf_counter() - t0
        ratio = np.zeros((grid.point_count, *part.ratio.shape[1:]), np.float32)
        ratio[chosen] = part.ratio
        baked = dataclasses.replace(part, ratio=ratio)
        if masks is None:
            masks = mesh_masks(renderer, grid, baked)
            rows.append(
                [
                    name,
                    "unbaked drawer (today)",
                    "-",
                    "-",
                    "-",
                    errors(live.combined, reference, masks, names),
                ]
            )
        image = render_baked(renderer, grid, baked)
        mib = (ratio.nbytes + grid.tri_points.nbytes + 2 * grid.tri_cuts.nbytes) / 2**20
        rows.append(
            [
                name,
                f"A: {label}",
                len(chosen),
                f"{seconds:.1f}",
                f"{mib:.1f}",
                errors(image, reference, masks, names),
            ]
        )
        if label == "default":  # representation C at the same points, bins and samples
            t0 = time.perf_counter()
            plain = bake_light(unshadowed, *feet, knobs.view_bins, knobs.samples, 0)
            seconds_c = seconds + time.perf_counter() - t0
            with np.errstate(divide="ignore", invalid="ignore"):
                shade = np.nan_to_num(part.ratio / plain.ratio, nan=1.0, posinf=1.0)
            ratio_c = np.ones_like(ratio)
            ratio_c[chosen] = shade
            factor = render_baked(
                renderer, grid, BakedLight(ratio_c, knobs.view_bins, 0, 0.0), times_response=False
            )
            hit = np.any(masks, axis=0)[..., None]
            c_image = np.where(
                hit, live.combined[..., :3] * factor[..., :3], live.combined[..., :3]
            )
            rows.append(
                [
                    name,
                    "C: shadow ratio × live",
                    len(chosen),
                    f"{seconds_c:.1f}",
                    f"{2 * mib:.1f}",
                    errors(c_image, reference, masks, names),
                ]
            )
    print(f"{name}: reference {SAMPLES_REF} spp in {ref_seconds:.1f} s", file=sys.stderr)
    return rows


def main(quick: bool = False) -> str:
    from btf_addon.cl.context import create_context

    ctx = create_context()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rows += measure("ground", ground_scene(Path(tmp)), ctx, quick)
        rows += measure("demo", demo_scene(Path(tmp)), ctx, quick)
    return table(
        ["scene", "image", "points", "bake s", "MiB", "rel. RMSE: surfaces (per object)"], rows
    )


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
