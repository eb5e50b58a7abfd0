"""One headless render path: ``python -m btf_addon render --blend f.blend`` and F12 in Blender
with the extension installed (``bpy.ops.render.render(write_still=True)``, what
``blender -b f.blend -f 1`` runs) give the same image of the same file, with the file's own
render settings."""

from __future__ import annotations

import os
import textwrap

import numpy as np
import pytest
from blender_helpers import EXTENSION_MODULE
from helpers import (
    cli_env,
    make_blend,
    read_png,
    run_cli,
    run_python,
    studiolights_dir,
    venv_opencl_vendors,
)

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr

#: The saved scene: a GGX BTF sphere on a plain ground under forest.exr, 64×48, with
#: non-default render settings (lights_total 7, seed 3) that the CLI must honour.
SCENE = """
import math
scene.render.engine = "BTF_RENDER"
scene.render.resolution_x, scene.render.resolution_y = 64, 48
scene.render.resolution_percentage = 100
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=32, ring_count=16)
bpy.ops.object.shade_smooth()
material = with_nodes(bpy.data.materials.new("BTF"))
material.btf.enabled = True
material.btf.source = {btf!r}
bpy.context.object.data.materials.append(material)
bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0.0, 0.0, -1.0))
plain = with_nodes(bpy.data.materials.new("Plain"))
plain.diffuse_color = (0.3, 0.6, 0.2, 1.0)
bpy.context.object.data.materials.append(plain)
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
cam.location = (0.0, -5.0, 1.5)
cam.rotation_euler = (math.radians(75), 0.0, 0.0)
scene.camera = cam
world = with_nodes(bpy.data.worlds.new("W"))
texture = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
texture.image = bpy.data.images.load({envmap!r})
world.node_tree.links.new(
    texture.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"]
)
scene.world = world
scene.btf_render.lights_total = 7
scene.btf_render.seed = 3
scene.btf_render.final_mode = "VIRTUAL"
"""

SAMPLED = """
scene.btf_render.final_mode = "SAMPLED"
scene.btf_render.samples = 16
scene.btf_render.max_bounces = 2
"""

#: F12 in a fresh Blender with the installed extension enabled: open each file, choose the
#: output format in Output Properties' words, render and save.
F12 = """
import bpy
import addon_utils
assert addon_utils.enable({module!r}, default_set=True) is not None
for blend, out in {jobs!r}:
    bpy.ops.wm.open_mainfile(filepath=blend)
    scene = bpy.context.scene
    image = scene.render.image_settings
    if hasattr(image, "media_type"):  # Blender 5: a multilayer EXR or video first
        image.media_type = "IMAGE"
    if out.endswith(".exr"):
        image.file_format, image.color_mode, image.color_depth = "OPEN_EXR", "RGBA", "32"
    else:
        image.file_format, image.color_mode, image.color_depth = "PNG", "RGBA", "8"
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
import importlib
importlib.import_module({module!r} + ".btf_addon.blender.compat").exit_python(0)
"""


@pytest.fixture(scope="module")
def renders(installed, tmp_path_factory):
    """Every image the tests compare: F12 (subprocess, installed extension) and the CLI
    (subprocess, this checkout) of the same two files."""
    folder = tmp_path_factory.mktemp("headless")
    write_container(folder / "ggx.btfm", GGXBTF((0.9, 0.6, 0.3), 0.4))
    scene = SCENE.format(
        btf=str(folder / "ggx.btfm"), envmap=str(studiolights_dir() / "forest.exr")
    )
    make_blend(folder / "virtual.blend", scene)
    make_blend(folder / "sampled.blend", scene + SAMPLED)
    jobs = [
        (str(folder / "virtual.blend"), str(folder / "f12_virtual.exr")),
        (str(folder / "virtual.blend"), str(folder / "f12_virtual.png")),
        (str(folder / "sampled.blend"), str(folder / "f12_sampled.exr")),
    ]
    # The extension's bundled pyopencl sees the machine's OpenCL drivers, not the venv's PoCL.
    env = cli_env(
        BLENDER_USER_RESOURCES=os.environ["BLENDER_USER_RESOURCES"],
        **venv_opencl_vendors(folder / "vendors"),
    )
    proc = run_python(
        "-c", textwrap.dedent(F12.format(module=EXTENSION_MODULE, jobs=jobs)), env=env
    )
    # Both must have rendered through OpenCL: a GLSL fallback would be a different image.
    assert "OpenCL unavailable" not in proc.stdout, proc.stdout
    for blend, out in jobs:
        proc = run_cli("render", "--blend", blend, "-o", out.replace("f12_", "cli_"))
        assert "OpenCL unavailable" not in proc.stdout, proc.stdout
    # The same file with the defaults (256 lights, seed 0) given as overrides.
    run_cli(
        "render",
        "--blend",
        folder / "virtual.blend",
        "-o",
        folder / "cli_defaults.exr",
        "--lights",
        "256",
        "--seed",
        "0",
    )
    return folder


def test_virtual_lights_identical(renders):
    """Virtual Lights is deterministic and both runs are the same code on the same file: the
    same pixels, bit for bit, in the linear EXR and in the PNG (through the file's own view
    transform, Blender's default AgX here, applied by the same write_still)."""
    f12, cli = read_exr(renders / "f12_virtual.exr"), read_exr(renders / "cli_virtual.exr")
    assert f12.shape == (48, 64, 3) and f12[24, 32].max() > 0.05  # the sphere, lit
    np.testing.assert_array_equal(cli, f12)
    np.testing.assert_array_equal(
        read_png(renders / "cli_virtual.png"), read_png(renders / "f12_virtual.png")
    )


def test_sampled_equal_up_to_float_rounding(renders):
    """Sampled: every sample's random points depend only on its index, so the image does not
    depend on how launches split the samples; only the float sums do (each launch returns
    the mean of its samples, weighted back by their count), so two runs may differ by float32
    rounding: bounded by 1e-5 of the brightest pixel, 1000× below this image's noise."""
    f12, cli = read_exr(renders / "f12_sampled.exr"), read_exr(renders / "cli_sampled.exr")
    virtual = read_exr(renders / "f12_virtual.exr")
    assert not np.array_equal(f12, virtual)  # the file's Sampled mode was used
    difference = np.abs(cli - f12).max()
    print(f"Sampled: largest difference CLI − F12 = {difference:.3g} (max {f12.max():.3g})")
    assert difference <= 1e-5 * f12.max()


def test_cli_honours_the_files_render_settings(renders):
    """The file's 7 lights with seed 3 give a visibly different image from the defaults (256
    lights, seed 0) — and the CLI without flags renders the file's, as F12 does (above)."""
    saved = read_exr(renders / "cli_virtual.exr")
    defaults = read_exr(renders / "cli_defaults.exr")
    # 7 directional lights against 256: the sphere's highlights move; far beyond rounding.
    assert np.abs(saved - defaults).max() > 0.05 * defaults.max()
    np.testing.assert_array_equal(saved, read_exr(renders / "f12_virtual.exr"))
