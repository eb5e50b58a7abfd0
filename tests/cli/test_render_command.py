"""``render``: the demo scene and saved .blend files, rendered headless through the CLI."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from helpers import ROOT, run_cli, run_python

from btf_addon.core.analytic import LambertianBTF
from btf_addon.core.container import write_container
from btf_addon.core.imageio import read_exr


def make_blend(path, script: str) -> None:
    """Build a .blend in a separate Blender process (this one must not import bpy)."""
    code = (
        textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        import bpy
        import btf_addon
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        btf_addon.register()
        scene = bpy.context.scene
    """)
        + textwrap.dedent(script)
        + f"\nbpy.ops.wm.save_as_mainfile(filepath={str(path)!r})\n"
    )
    run_python("-c", code)


def test_demo_renders_a_png_and_reports_timing(tmp_path):
    out = tmp_path / "demo.png"
    proc = run_cli(
        "render", "--demo", "-o", out, "--resolution", "96x54", "--lighting", "virtual:8"
    )
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "opencl render" in proc.stdout and "96x54" in proc.stdout
    glsl = tmp_path / "demo_glsl.png"
    proc = run_cli(
        "render",
        "--demo",
        "-o",
        glsl,
        "--resolution",
        "96x54",
        "--lighting",
        "virtual:8",
        "--engine",
        "glsl",
    )
    assert "glsl render" in proc.stdout and glsl.exists()


def test_blend_with_relative_btf_path_and_missing_uvs(tmp_path):
    """A BTF referenced as //lambert.btfm resolves next to the .blend, from any working folder;
    an object without UVs is rendered with a per-object message."""
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.6))
    blend = tmp_path / "scene.blend"
    make_blend(
        blend,
        """
        bpy.ops.mesh.primitive_plane_add(size=4.0)
        plane = bpy.context.object
        bpy.ops.mesh.uv_texture_remove()
        material = bpy.data.materials.new("Lambert")
        material.btf.enabled = True
        material.btf.source = "//lambert.btfm"
        plane.data.materials.append(material)
        cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
        scene.collection.objects.link(cam)
        cam.location = (0.0, 0.0, 5.0)
        scene.camera = cam
        world = bpy.data.worlds.new("W")
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        scene.world = world
    """,
    )
    out = tmp_path / "r.exr"
    proc = run_cli(
        "render",
        "--blend",
        blend,
        "-o",
        out,
        "--resolution",
        "40x30",
        "--lighting",
        "virtual:64",
        cwd=tmp_path.parent,
    )
    assert "has no UV map" in proc.stderr
    image = read_exr(out)
    # A white uniform World (L = 1) on a Lambertian plane facing it: E = π, radiance = ρ = 0.6
    # (64 Sobol lights: within 3%), seen at the centre of the image.
    centre = image[15, 20]
    np.testing.assert_allclose(centre, 0.6, rtol=0.03)


def test_render_errors_are_clear(tmp_path):
    blend = tmp_path / "nocam.blend"
    make_blend(blend, "bpy.ops.mesh.primitive_cube_add()\n")
    proc = run_cli("render", "--blend", blend, "-o", tmp_path / "x.png", check=False)
    assert proc.returncode == 2 and "no camera" in proc.stderr and "Traceback" not in proc.stderr
    for args, message in (
        (["--resolution", "0x10"], "outside"),
        (["--lighting", "virtual:zero"], "virtual:N"),
        (["-o", tmp_path / "x.jpg"], ".png or .exr"),
    ):
        extra = args if "-o" in args else ["-o", tmp_path / "x.png", *args]
        proc = run_cli("render", "--demo", *extra, check=False)
        assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("missing", ["nofile.blend"])
def test_missing_blend(tmp_path, missing):
    proc = run_cli("render", "--blend", tmp_path / missing, "-o", tmp_path / "x.png", check=False)
    assert proc.returncode == 2 and "no such .blend" in proc.stderr


def test_envmap_lighting_renders_by_sampling(tmp_path):
    out = tmp_path / "s.exr"
    proc = run_cli(
        "render",
        "--demo",
        "-o",
        out,
        "--resolution",
        "48x27",
        "--lighting",
        "envmap",
        "--samples",
        "8",
    )
    assert "sampled, 8 samples per pixel" in proc.stdout
    assert np.all(np.isfinite(read_exr(out)))
    proc = run_cli(
        "render", "--demo", "-o", out, "--lighting", "envmap", "--engine", "glsl", check=False
    )
    assert proc.returncode == 2 and "needs the opencl engine" in proc.stderr
