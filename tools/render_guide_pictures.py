"""Render the user guide's stereo F12 and asset library pictures with the project's own engine,
from synthetic data only (pictures in the repository never show BTFbase research data):

- docs/images/demo-stereo.png: the demo scene's F12 with Output › Stereoscopy on, side by side
  (left eye left), each eye rendered by the engine from its own camera;
- docs/images/asset-library.png: the previews of a library built from the five synthetic
  presets by Build BTF Material Library, in a row as the Asset Browser shows them.

    python tools/render_guide_pictures.py [--output docs/images]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402

import btf_addon  # noqa: E402
from btf_addon.blender.demo import build_demo_scene  # noqa: E402
from btf_addon.core.formats.imageio import srgb8_from_linear, write_png  # noqa: E402


def stereo_f12(output: Path, work: Path) -> None:
    scene = build_demo_scene(work / "demo_data", resolution=(480, 270))
    scene.btf_render.final_mode = "VIRTUAL"
    scene.btf_render.lights_total = 64
    stereo = scene.camera.data.stereo
    stereo.convergence_mode, stereo.pivot = "OFFAXIS", "CENTER"
    stereo.interocular_distance = 0.065
    scene.render.use_multiview = True
    scene.render.views_format = "STEREO_3D"
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: an image, not a multilayer EXR or video
        settings.media_type = "IMAGE"
    settings.file_format = "PNG"
    settings.views_format = "STEREO_3D"
    settings.stereo_3d_format.display_mode = "SIDEBYSIDE"
    settings.stereo_3d_format.use_sidebyside_crosseyed = False
    scene.render.filepath = str(output / "demo-stereo.png")
    bpy.ops.render.render(write_still=True)


def asset_library(output: Path, work: Path) -> None:
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    folder = work / "library"
    bpy.ops.btf.build_asset_library(directory=str(folder), source_folder="", preview_size=128)
    previews = []
    with bpy.data.libraries.load(str(folder / "btf_materials.blend")) as (source, target):
        target.materials = list(source.materials)
    for material in sorted(target.materials, key=lambda m: m.name):
        preview = material.preview
        w, h = preview.image_size
        rgba = np.array(preview.image_pixels_float[:], dtype=np.float32).reshape(h, w, 4)
        previews.append(rgba[::-1])  # previews store rows bottom first
    gap = np.ones((previews[0].shape[0], 8, 4), dtype=np.float32)
    row = np.concatenate([p for preview in previews for p in (preview, gap)][:-1], axis=1)
    grey = 0.18  # the Asset Browser's dark grey behind transparent previews
    rgb = row[..., :3] + grey * (1.0 - row[..., 3:4])
    write_png(output / "asset-library.png", srgb8_from_linear(rgb))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=ROOT / "docs" / "images")
    args = parser.parse_args()
    btf_addon.register()
    with tempfile.TemporaryDirectory() as tmp:
        for job in (stereo_f12, asset_library):
            t0 = time.perf_counter()
            job(args.output, Path(tmp))
            print(f"{job.__name__}: {time.perf_counter() - t0:.1f} s")
    from btf_addon.blender.compat import exit_python

    exit_python(0)


if __name__ == "__main__":
    main()
