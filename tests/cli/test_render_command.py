"""``render``: the demo scene and saved .blend files, rendered headless through the CLI."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import cli_env, make_blend, read_png, run_cli

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr, srgb8_from_linear


def test_demo_renders_a_png_and_reports_timing(tmp_path):
    out = tmp_path / "demo.png"
    virtual = ("--final-mode", "virtual")  # deterministic: PNG and EXR of the same image
    args = ("render", "--demo", "--resolution", "96x54", "--lights", "8", *virtual)
    proc = run_cli(*args, "-o", out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "96x54 with 8 virtual lights" in proc.stdout and " s -> " in proc.stdout
    # The demo's Standard view without dither: the PNG is the sRGB curve of the linear render.
    # Blender's OpenColorIO rounds a value within 1/255 of a code boundary either way, where
    # core.formats.imageio rounds to nearest: at most 1 code apart, on under 1 % of the pixels.
    exr = tmp_path / "demo.exr"
    run_cli(*args, "-o", exr)
    png = read_png(out)
    assert png.shape == (54, 96, 4) and np.all(png[..., 3] == 255)
    diff = np.abs(png[..., :3].astype(int) - srgb8_from_linear(read_exr(exr)).astype(int))
    assert diff.max() <= 1 and (diff > 0).mean() < 0.01


def test_without_opencl_the_cli_falls_back_like_f12(tmp_path):
    """No OpenCL driver at all: the same F12 path warns and draws through the GLSL viewport
    path; the image is the demo scene without shadows, so close to the OpenCL one (the demo
    has no ground: only Suzanne's creases shadow themselves)."""
    # The ICD loader pointed at a vendors path that does not exist finds no platform (an
    # existing empty folder is not enough: pyopencl's bundled vendors folder is still read).
    empty = tmp_path / "no-icd-here"
    out, reference = tmp_path / "glsl.exr", tmp_path / "cl.exr"
    args = ("render", "--demo", "--resolution", "96x54", "--lights", "8")
    args += ("--final-mode", "virtual", "-o")
    proc = run_cli(*args, out, env=cli_env(OCL_ICD_VENDORS=str(empty)))
    assert "OpenCL unavailable" in proc.stdout and "GLSL viewport path" in proc.stdout
    run_cli(*args, reference)
    glsl, cl = read_exr(out), read_exr(reference)
    assert np.all(np.isfinite(glsl)) and glsl.max() > 0.05
    assert abs(glsl.mean() - cl.mean()) < 0.05 * cl.mean()


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
        material = with_nodes(bpy.data.materials.new("Lambert"))
        material.btf.enabled = True
        material.btf.source = "//lambert.btfm"
        plane.data.materials.append(material)
        cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
        scene.collection.objects.link(cam)
        cam.location = (0.0, 0.0, 5.0)
        scene.camera = cam
        world = with_nodes(bpy.data.worlds.new("W"))
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
        "--lights",
        "64",
        "--final-mode",
        "virtual",
        cwd=tmp_path.parent,
    )
    assert "has no UV map" in proc.stdout  # the engine's warning, printed by Blender
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
        (["--lights", "0"], "--lights 0 is outside 1…4096"),
        (["--samples", "70000"], "--samples 70000 is outside 1…65536"),
        (["--final-mode", "envmap"], "virtual|sampled"),
        (["--lighting", "virtual:8"], "--final-mode virtual --lights N"),
        (["--lighting", "envmap"], "--final-mode sampled"),
        (["--engine", "glsl"], "--engine is gone"),
        (["--device", "99"], "no such OpenCL device"),
        (["-o", tmp_path / "x.jpg"], ".png or .exr"),
    ):
        extra = args if "-o" in args else ["-o", tmp_path / "x.png", *args]
        proc = run_cli("render", "--demo", *extra, check=False)
        assert proc.returncode == 2 and message in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("missing", ["nofile.blend"])
def test_missing_blend(tmp_path, missing):
    proc = run_cli("render", "--blend", tmp_path / missing, "-o", tmp_path / "x.png", check=False)
    assert proc.returncode == 2 and "no such .blend" in proc.stderr


def test_sampled_final_mode_renders_by_sampling(tmp_path):
    out = tmp_path / "s.exr"
    proc = run_cli(
        "render",
        "--demo",
        "-o",
        out,
        "--resolution",
        "48x27",
        "--final-mode",
        "sampled",
        "--samples",
        "8",
    )
    assert "sampled, 8 samples per pixel, 4 bounces" in proc.stdout
    assert np.all(np.isfinite(read_exr(out)))


def test_clamp_indirect_flag_reaches_f12(tmp_path):
    """`--clamp-indirect X` is the scene's Clamp Indirect for this render: a limit far below the
    demo's indirect light (Suzanne and the sphere light each other) darkens the frame against
    the unclamped render of the same samples; everything else is the same render."""
    means = {}
    for limit in ("0", "0.001"):
        out = tmp_path / f"clamp-{limit}.exr"
        run_cli("render", "--demo", "--resolution", "64x36", "--samples", "8",
                "--clamp-indirect", limit, "-o", out)  # fmt: skip
        means[limit] = float(read_exr(out)[..., :3].mean())
    assert means["0.001"] < 0.995 * means["0"], means


def test_samples_per_camera_ray_flag_reaches_f12(tmp_path):
    """`--samples-per-camera-ray N` is the scene's setting for this render: the same seed with 1
    and with 8 gives different images (every pixel's 8 samples on one camera ray against 8
    rays); what sharing means is checked in tests/kernels/test_samples_per_camera_ray.py."""
    images = {}
    for split in ("1", "8"):
        out = tmp_path / f"split-{split}.exr"
        run_cli("render", "--demo", "--resolution", "64x36", "--samples", "8",
                "--samples-per-camera-ray", split, "-o", out)  # fmt: skip
        images[split] = read_exr(out)[..., :3]
    assert not np.array_equal(images["1"], images["8"])


@pytest.mark.parametrize(
    ("flag", "expected"),
    [
        (None, {"use_adaptive_sampling": None, "adaptive_threshold": None}),  # the scene's
        ("0.05", {"use_adaptive_sampling": True, "adaptive_threshold": 0.05}),
        ("0", {"use_adaptive_sampling": False, "adaptive_threshold": None}),  # its threshold kept
    ],
)
def test_noise_threshold_flag_in_the_settings_words(flag, expected):
    """`--noise-threshold T` → the two settings Blender's panel shows (no Blender here)."""
    import argparse

    from btf_addon.cli.render_command import add_parser, overrides

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    args = ["render", "--demo", "-o", "x.exr"] + (
        [] if flag is None else ["--noise-threshold", flag]
    )
    given = overrides(parser.parse_args(args))
    assert {k: given[k] for k in expected} == expected


def test_noise_threshold_flag_reaches_f12(tmp_path):
    """`--noise-threshold T` is the scene's adaptive sampling for this render: said in the
    summary line, and a high threshold stops pixels that 0 (off) renders fully, so the images
    differ; what stopping means is checked in tests/kernels/test_adaptive_sampling.py."""
    images = {}
    for threshold in ("0", "0.1"):
        out = tmp_path / f"t-{threshold}.exr"
        proc = run_cli("render", "--demo", "--resolution", "48x27", "--samples", "64",
                       "--noise-threshold", threshold, "-o", out)  # fmt: skip
        assert ("noise threshold 0.1" in proc.stdout) == (threshold == "0.1"), proc.stdout
        images[threshold] = read_exr(out)[..., :3]
    assert not np.array_equal(images["0"], images["0.1"])
