"""Numerically hard scenes rendered through the CLI (``render --blend``), as a farm would: every
one must finish with exit code 0 and a finite, non-negative image, and where the right answer
is known independently, give it."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from helpers import ROOT, run_cli, run_python

from btf_addon.core.formats.imageio import read_exr

WORLD = (0.3, 0.5, 0.7)

#: bpy code per case, run after a camera "Cam" and a uniform World of colour WORLD exist.
CASES = {
    "empty": "",  # the World only
    "degenerate": """
        nan = float("nan")
        verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (nan, 0, 0), (2, 0, 0), (3, 0, 0),
                 (-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1)]
        faces = [(0, 1, 2), (3, 1, 2), (0, 4, 5), (6, 9, 8, 7)]  # ok, NaN, zero area, flipped
        mesh = bpy.data.meshes.new("bad")
        mesh.from_pydata(verts, [], faces)
        obj = bpy.data.objects.new("bad", mesh)
        scene.collection.objects.link(obj)
    """,
    "camera_inside": """
        bpy.ops.mesh.primitive_uv_sphere_add(radius=5.0)
        cam.location = (0.0, 0.0, 0.0)
    """,
    "grazing": """
        bpy.ops.mesh.primitive_plane_add(size=1000.0)
        cam.location = (0.0, -10.0, 0.001)
        cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    """,
}
for scale in (1e-3, 1.0, 1e4):
    CASES[f"scale_{scale:g}"] = f"""
        s = {scale!r}
        bpy.ops.mesh.primitive_plane_add(size=6.0 * s, location=(0.0, 0.0, -s))
        bpy.ops.mesh.primitive_uv_sphere_add(radius=s)
        bpy.ops.object.shade_smooth()
        cam.location = (0.0, -5.0 * s, 2.0 * s)
        cam.data.clip_start, cam.data.clip_end = 0.01 * s, 1000.0 * s
    """


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    """Every case's .blend, built in one Blender process (this one must not import bpy)."""
    folder = tmp_path_factory.mktemp("hard")
    parts = [
        f"import sys, math\nsys.path.insert(0, {str(ROOT)!r})\nimport bpy\n"
        "from btf_addon.blender.compat import with_nodes\n"
    ]
    for name, body in CASES.items():
        parts.append(
            textwrap.dedent(f"""
            bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
            scene = bpy.context.scene
            cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
            scene.collection.objects.link(cam)
            scene.camera = cam
            cam.location = (0.0, -6.0, 2.0)
            cam.rotation_euler = (math.radians(72.0), 0.0, 0.0)
            world = with_nodes(bpy.data.worlds.new("W"))
            world.node_tree.nodes["Background"].inputs["Color"].default_value = (*{WORLD!r}, 1)
            scene.world = world
            """)
            + textwrap.dedent(body)
            + f"\nbpy.ops.wm.save_as_mainfile(filepath={str(folder / (name + '.blend'))!r})\n"
        )
    run_python("-c", "".join(parts))
    return folder


def render(blends, name: str, *extra) -> np.ndarray:
    out = blends / f"{name}.exr"
    run_cli(
        "render", "--blend", blends / f"{name}.blend", "-o", out, "--resolution", "64x48", *extra
    )
    image = read_exr(out)
    assert np.all(np.isfinite(image)) and image.min() >= 0.0, name
    return image


@pytest.mark.parametrize(
    "lighting",
    [["--final-mode", "virtual", "--lights", "16"], ["--final-mode", "sampled", "--samples", "4"]],
)
def test_hard_scenes_render_finite(blends, lighting):
    images = {name: render(blends, name, *lighting) for name in CASES}
    # The World alone: every pixel is its colour.
    np.testing.assert_allclose(
        images["empty"][..., :3], np.broadcast_to(WORLD, (48, 64, 3)), rtol=1e-5
    )
    # Inside a sphere the camera sees its lit inner side (back faces are shaded as seen), not
    # black and not the World.
    assert 0.0 < images["camera_inside"][..., :3].mean()
    # The flipped and the valid triangle are drawn; the NaN and zero-area ones are skipped.
    assert not np.allclose(images["degenerate"][..., :3], WORLD)
    # Up to the grazing horizon, the ground is lit like any other ground.
    assert images["grazing"][40:, :, :3].mean() > 0.1


def test_scene_scale_changes_nothing(blends):
    """Millimetre and kilometre versions of one scene look the same (relative RMSE < 1 %:
    only float rounding in the intersections differs)."""
    base = render(blends, "scale_1")
    for name in ("scale_0.001", "scale_10000"):
        image = render(blends, name)
        rmse = np.sqrt(np.mean((image - base) ** 2)) / np.sqrt(np.mean(base**2))
        assert rmse < 0.01, (name, rmse)


def test_a_4k_frame_keeps_memory_bounded(blends):
    """3840×2160 renders in bands (device memory holds one band of passes), so the process's
    peak memory grows with the pixel count only by what the host must hold: the passes (10
    floats = 40 B per pixel), Blender's render result (Combined, 16 B) and its conversion for
    the PNG. Measured against a 384×216 run of the same scene through F12's write_still:
    ≈ 99 B per added pixel (474 → 1250 MiB; ≈ 110 B when the CLI wrote the PNG itself); the
    bound is 160 B."""
    peaks = {}
    for resolution in ("384x216", "3840x2160"):
        out = blends / f"big_{resolution}.png"
        code = (
            "import atexit, resource, runpy, sys\n"
            "atexit.register(lambda: print('peak_kb', resource.getrusage("
            "resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr))\n"
            f"sys.argv = ['btf_addon', 'render', '--blend', {str(blends / 'scale_1.blend')!r},"
            f" '-o', {str(out)!r}, '--resolution', {resolution!r}, '--lights', '1',"
            " '--final-mode', 'virtual', '--filter', 'none']\n"
            "runpy.run_module('btf_addon', run_name='__main__')\n"
        )
        proc = run_python("-c", code)
        peaks[resolution] = int(proc.stderr.split("peak_kb")[-1].split()[0]) * 1024
        assert out.stat().st_size > 0
    growth = (peaks["3840x2160"] - peaks["384x216"]) / (3840 * 2160 - 384 * 216)
    print(
        f"peak RSS 384x216 {peaks['384x216'] / 2**20:.0f} MiB, 4K "
        f"{peaks['3840x2160'] / 2**20:.0f} MiB"
    )
    assert growth < 160, f"{growth:.0f} bytes per pixel"
