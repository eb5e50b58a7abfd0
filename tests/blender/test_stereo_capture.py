"""The Stereo Capture operator (``btf.stereo_capture``) as a user runs it, in background
Blender: the pair and its JSON written beside the .blend or to a chosen path, reported, PNGs
through the scene's colour management, the file left unchanged, clear errors."""

from __future__ import annotations

import ctypes
import json

import numpy as np
import pytest
from blender_helpers import sphere_on_ground
from helpers import read_png

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr, srgb8_from_linear


def blender_output(capfd) -> str:
    """What Blender printed so far (reports go through C stdio: flush it first)."""
    ctypes.CDLL(None).fflush(None)
    return capfd.readouterr().out


@pytest.fixture
def saved_scene(bpy_module, fresh_scene, tmp_path):
    """tests' sphere on the ground (24 virtual lights), saved as tmp_path/scene.blend."""
    write_container(tmp_path / "ggx.btfm", GGXBTF((0.9, 0.6, 0.3), 0.4))
    scene = sphere_on_ground(bpy_module, tmp_path, tmp_path / "ggx.btfm")
    bpy_module.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    return scene


def test_capture_beside_the_blend_is_written_and_reported(bpy_module, saved_scene, tmp_path, capfd):
    bpy = bpy_module
    blender_output(capfd)
    result = bpy.ops.btf.stereo_capture(profile="simulated", eye_width=32)
    assert result == {"FINISHED"}
    out, meta_path = (
        tmp_path / "scene_stereo_simulated.exr",
        tmp_path / "scene_stereo_simulated.json",
    )
    report = blender_output(capfd)
    assert "Stereo Capture (simulated: 2 × 32×24, IPD 63 mm" in report
    assert f"24 lights): wrote {out}, {meta_path}" in report
    image = read_exr(out)
    assert image.shape == (24, 64, 3) and np.isfinite(image).all()
    assert image[12, :32].max() > 0.05 and np.abs(image[:, :32] - image[:, 32:]).max() > 0.01
    meta = json.loads(meta_path.read_text())
    assert meta["lights"] == {"count": 24, "lighting": "environment", "seed": 0}  # the scene's
    cam = np.array(saved_scene.camera.matrix_world)
    left, right = (np.array(meta["eyes"][e]["world_from_eye"]) for e in ("left", "right"))
    # The camera is the head: the eyes sit ∓31.5 mm along its x axis, oriented as it is.
    np.testing.assert_allclose((left[:3, 3] + right[:3, 3]) / 2, cam[:3, 3], atol=1e-6)
    np.testing.assert_allclose(right[:3, 3] - left[:3, 3], 0.063 * cam[:3, 0], atol=1e-6)
    np.testing.assert_allclose(left[:3, :3], cam[:3, :3], atol=1e-6)


def test_per_eye_png_through_colour_management_changes_nothing(bpy_module, saved_scene, tmp_path):
    """PNGs are saved as the scene's renders are: on the Standard view without dither they are
    the sRGB curve of the linear eyes (OpenColorIO may round a value within 1/255 of a code
    boundary the other way: at most 1 code, under 1 % of pixels); on AgX they differ. The
    operator leaves no image behind and puts the output settings back."""
    bpy = bpy_module
    scene = saved_scene
    images_before = len(bpy.data.images)
    settings = scene.render.image_settings
    before = (settings.file_format, settings.color_mode, settings.color_depth)
    scene.view_settings.view_transform = "Standard"
    scene.render.dither_intensity = 0.0
    common = {"profile": "xtal-8k", "eye_width": 32, "layout": "per-eye"}
    assert bpy.ops.btf.stereo_capture(filepath=str(tmp_path / "shots" / "s.exr"), **common) == {
        "FINISHED"
    }
    assert bpy.ops.btf.stereo_capture(filepath=str(tmp_path / "shots" / "s.png"), **common) == {
        "FINISHED"
    }
    for eye in ("left", "right"):
        png = read_png(tmp_path / "shots" / f"s_{eye}.png")
        linear = read_exr(tmp_path / "shots" / f"s_{eye}.exr")
        assert png.shape[:2] == linear.shape[:2] == (18, 32)
        diff = np.abs(png[..., :3].astype(int) - srgb8_from_linear(linear).astype(int))
        assert diff.max() <= 1 and (diff > 0).mean() < 0.01, eye
    scene.view_settings.view_transform = "AgX"
    assert bpy.ops.btf.stereo_capture(filepath=str(tmp_path / "agx.png"), **common) == {"FINISHED"}
    standard = read_png(tmp_path / "shots" / "s_left.png").astype(int)
    assert np.abs(read_png(tmp_path / "agx_left.png").astype(int) - standard).max() > 10
    assert len(bpy.data.images) == images_before
    assert (settings.file_format, settings.color_mode, settings.color_depth) == before


def test_errors_are_reported(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    bpy.ops.object.camera_add()
    fresh_scene.camera = bpy.context.object
    with pytest.raises(RuntimeError, match=r"save the \.blend first, or choose a file path"):
        bpy.ops.btf.stereo_capture(profile="simulated", eye_width=16)
    fresh_scene.camera = None
    with pytest.raises(RuntimeError, match="has no camera to capture from"):
        bpy.ops.btf.stereo_capture(profile="simulated", filepath=str(tmp_path / "x.exr"))
    with pytest.raises(RuntimeError, match=r"must end in \.exr or \.png"):
        bpy.ops.btf.stereo_capture(profile="simulated", filepath=str(tmp_path / "x.jpg"))
    assert not list(tmp_path.glob("x*"))


def test_blenders_gpu_device_draws_the_same_eyes(bpy_module, saved_scene):
    """Inside Blender's UI the operator draws on Blender's ``gpu`` module; in the background
    on moderngl. Both are the one drawer with the same shaders and data on two OpenGL
    pipelines: the eyes agree to single-precision rounding (as F12's GLSL fallback and the
    standalone renderer do in test_engine.py). A capture on its own moderngl context gives
    Blender's context back: Blender draws again afterwards (epoxy aborts the process when it
    finds no current context)."""
    from blender_helpers import extension_submodule, init_gpu_module

    bpy = bpy_module
    init_gpu_module(bpy)
    capture = extension_submodule("btf_addon.gl.stereo_capture")
    export = extension_submodule("btf_addon.blender.export")
    gpu_draw = extension_submodule("btf_addon.blender.gpu_draw")
    settings = extension_submodule("btf_addon.render.settings").RenderSettings(lights_total=24)
    prof = capture.capture_profile(
        extension_submodule("btf_addon.render.headsets").profile("simulated"), 32
    )
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), 32, 24)
    on_gpu = capture.render_stereo(exported, settings, prof, gpu_draw.BlenderGPUDevice())
    on_moderngl = capture.render_stereo(exported, settings, prof)
    for eye in ("left", "right"):
        a, b = on_gpu.images[eye], on_moderngl.images[eye]
        assert a.shape == b.shape == (24, 32, 3)
        assert np.abs(a - b).max() < 1e-3 * b.max(), eye
        assert b[12].max() > 0.05  # the sphere is there and lit
    again = capture.render_stereo(exported, settings, prof, gpu_draw.BlenderGPUDevice())
    np.testing.assert_array_equal(again.images["left"], on_gpu.images["left"])
