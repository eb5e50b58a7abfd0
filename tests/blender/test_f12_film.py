"""F12's film as Blender defines it: Render Region (Ctrl+B) with passes at odd sizes, cropped
or not, and Film › Transparent — through bpy.ops.render.render, on OpenCL and on the GLSL
fallback. Tiny frames (37 × 23, 4 virtual lights): the file runs in about 20 s."""

from __future__ import annotations

import math

import numpy as np
import pytest
from blender_helpers import extension_submodule, with_nodes

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container

W, H = 37, 23  # odd, and not multiples of anything: region arithmetic must be exact


def read_rgba_exr(path) -> dict[str, np.ndarray]:
    """An EXR's channels as {channel group: (H, W, C) float32}, row 0 = top."""
    import OpenEXR

    with OpenEXR.File(str(path)) as exr:
        return {
            name: np.asarray(ch.pixels, dtype=np.float32) for name, ch in exr.channels().items()
        }


def rgba(channels: dict[str, np.ndarray]) -> np.ndarray:
    if "RGBA" in channels:
        return channels["RGBA"]
    return np.stack([channels[c] for c in "RGBA"], axis=-1)


def tiny_scene(bpy, tmp_path):
    """A grey Lambertian BTF sphere in the middle of a W × H frame, grey World, camera on −y."""
    write_container(tmp_path / "grey.btfm", LambertianBTF(0.5))
    scene = bpy.context.scene
    scene.render.engine = "BTF_RENDER"
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    scene.btf_render.lights_total = 4
    # The tests compare renders bit for bit: launches split by a fixed plan, not by measured
    # times (which a busy machine changes, and with them the rounding of the sums).
    scene.btf_render.fixed_launch_split = True
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=12, ring_count=6)
    material = bpy.data.materials.new("Grey")
    material.btf.enabled = True
    material.btf.source = str(tmp_path / "grey.btfm")
    bpy.context.object.data.materials.append(material)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -5.0, 0.0)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.camera = cam
    world = with_nodes(bpy.data.worlds.new("W"))
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    scene.world = world
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: a multilayer EXR or video first
        settings.media_type = "IMAGE"
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    scene.render.filepath = str(tmp_path / "f12.exr")
    return scene


def render(bpy, scene) -> dict[str, np.ndarray]:
    bpy.ops.render.render(write_still=True)
    return read_rgba_exr(scene.render.filepath)


def set_region(scene, crop: bool) -> tuple[slice, slice]:
    """Render Region on at fractions that land between pixels; returns the (rows, cols) of the
    whole frame (row 0 = top) that Blender's own arithmetic puts in it:
    int(float(border) · size) per edge."""
    r = scene.render
    r.use_border, r.use_crop_to_border = True, crop
    r.border_min_x, r.border_max_x = 0.13, 0.71
    r.border_min_y, r.border_max_y = 0.21, 0.77
    f32 = np.float32
    x0, x1 = int(f32(0.13) * f32(W)), int(f32(0.71) * f32(W))
    y0, y1 = int(f32(0.21) * f32(H)), int(f32(0.77) * f32(H))
    return slice(H - y1, H - y0), slice(x0, x1)  # Blender's y counts from the bottom


def read_back_passes(monkeypatch) -> dict[str, np.ndarray]:
    """Every pass F12 hands Blender, read as it ends the result: {name: (h, w, C), row 0 =
    top} (RNA methods cannot be patched on the engine class: the engine is wrapped)."""
    final_render = extension_submodule("btf_addon.blender.final_render")
    passes: dict[str, np.ndarray] = {}

    class ReadBack:
        def __init__(self, engine):
            self.engine = engine

        def __getattr__(self, name):
            return getattr(self.engine, name)

        def end_result(self, result, *args, **kwargs):
            layer = result.layers[0]
            h, w = result.resolution_y, result.resolution_x
            for render_pass in layer.passes:
                rect = np.array(render_pass.rect, dtype=np.float32)
                passes[render_pass.name] = rect.reshape(h, w, -1)[::-1]
            return self.engine.end_result(result, *args, **kwargs)

    original = final_render.render
    monkeypatch.setattr(
        final_render, "render", lambda engine, depsgraph: original(ReadBack(engine), depsgraph)
    )
    return passes


@pytest.mark.parametrize("crop", [True, False])
def test_render_region_with_passes_matches_the_whole_frame(
    bpy_module, fresh_scene, tmp_path, monkeypatch, crop
):
    """Ctrl+B used to fail (a pass array of the whole frame into a region-sized result) and
    still report FINISHED. The region must hold exactly the whole frame's pixels there, in
    every pass: Virtual Lights is deterministic, so equality is exact. Blender then crops the
    saved image to the region, or pastes it into an empty frame."""
    bpy = bpy_module
    scene = tiny_scene(bpy, tmp_path)
    view_layer = scene.view_layers[0]
    view_layer.use_pass_z = view_layer.use_pass_normal = view_layer.use_pass_uv = True
    passes = read_back_passes(monkeypatch)
    saved_full = rgba(render(bpy, scene))
    full = dict(passes)
    assert set(full) >= {"Combined", "Depth", "Normal", "UV"}
    assert full["Combined"].shape == (H, W, 4)
    assert full["Combined"][H // 2, W // 2, :3].max() > 0.05  # the sphere is there and lit
    rows, cols = set_region(scene, crop)
    passes.clear()
    saved = rgba(render(bpy, scene))
    assert set(passes) == set(full)
    for name, image in full.items():
        np.testing.assert_array_equal(passes[name], image[rows, cols], err_msg=name)
    if crop:
        np.testing.assert_array_equal(saved, saved_full[rows, cols])
    else:
        inside = np.zeros((H, W), dtype=bool)
        inside[rows, cols] = True
        np.testing.assert_array_equal(saved[inside], saved_full[inside])
        assert np.all(saved[~inside] == 0.0)


@pytest.mark.parametrize("mode", ["SAMPLED", "VIRTUAL"])
def test_transparent_film_alpha(bpy_module, fresh_scene, tmp_path, mode):
    """Film › Transparent, anti-aliased (Blender's default film): alpha is the share of the
    pixel filter's rays that hit the sphere, premultiplied as Cycles. The background is RGBA 0;
    pixels wholly on the sphere are unchanged (the World still lights it); along the silhouette
    0 < alpha < 1, and what the opaque film adds there is exactly the grey World's 0.5 times
    the missing coverage (same rays, same samples: only the World's share differs)."""
    bpy = bpy_module
    scene = tiny_scene(bpy, tmp_path)
    scene.btf_render.final_mode = mode
    scene.btf_render.samples = 16
    opaque = rgba(render(bpy, scene))
    scene.render.film_transparent = True
    clear = rgba(render(bpy, scene))
    assert opaque[..., 3].min() == 1.0
    alpha = clear[..., 3]
    background, covered = alpha == 0.0, alpha == 1.0
    edge = ~background & ~covered
    assert 0.2 < background.mean() < 0.9  # corners are background, the middle is the sphere
    assert background[0, 0] and covered[H // 2, W // 2]
    assert edge.sum() >= 10, edge.sum()  # the silhouette is anti-aliased, not a hard mask
    assert np.all(clear[background] == 0.0)
    np.testing.assert_array_equal(clear[covered], opaque[covered])
    # Summation order differs between the two films: float32 rounding, 1e-5 relative.
    world = np.repeat(0.5 * (1.0 - alpha[..., None]), 3, axis=-1)
    np.testing.assert_allclose(opaque[..., :3] - clear[..., :3], world, rtol=1e-5, atol=1e-5)
    assert np.all(opaque[background][:, :3] > 0.1)  # the grey World was there before
    assert extension_submodule("btf_addon.blender.final_render").last_device.startswith("OpenCL")


def test_transparent_film_and_region_on_the_glsl_fallback(
    bpy_module, fresh_scene, tmp_path, monkeypatch
):
    """The GLSL fallback honours the region and the transparent film too."""
    bpy = bpy_module
    final_render = extension_submodule("btf_addon.blender.final_render")
    context = extension_submodule("btf_addon.cl.context")

    def unavailable(_index=None):
        raise context.OpenCLUnavailableError("no OpenCL platform found (test)")

    monkeypatch.setattr(final_render, "create_context", unavailable)
    scene = tiny_scene(bpy, tmp_path)
    scene.render.film_transparent = True
    full = rgba(render(bpy, scene))
    assert final_render.last_device.startswith("GLSL")
    background = full[..., 3] == 0.0
    assert background[0, 0] and not background[H // 2, W // 2]
    assert np.all(full[background] == 0.0)
    rows, cols = set_region(scene, crop=True)
    region = rgba(render(bpy, scene))
    # The same shaders draw the same frame: equal to float rounding of two draws (1e-6).
    np.testing.assert_allclose(region, full[rows, cols], atol=1e-6)


def _stereo(scene, interocular: float = 0.5) -> None:
    """Output › Stereoscopy on, eyes side by side in parallel, the camera between them."""
    stereo = scene.camera.data.stereo
    stereo.convergence_mode, stereo.pivot = "PARALLEL", "CENTER"
    stereo.interocular_distance = interocular
    scene.render.use_multiview = True
    scene.render.views_format = "STEREO_3D"


@pytest.mark.parametrize("engine", ["opencl", "glsl"])
def test_stereo_f12_renders_each_eye_as_its_own_camera(
    bpy_module, fresh_scene, tmp_path, engine, monkeypatch
):
    """Issue 32 item 2: with Stereoscopy on, F12 filled one view only (an empty left image or
    half). Each view must equal a plain F12 from a camera where Blender puts that eye: parallel
    eyes, pivot in the middle: ± half the interocular distance along the camera's x."""
    bpy = bpy_module
    final_render = extension_submodule("btf_addon.blender.final_render")
    if engine == "glsl":
        context = extension_submodule("btf_addon.cl.context")

        def unavailable(_index=None):
            raise context.OpenCLUnavailableError("no OpenCL platform found (test)")

        monkeypatch.setattr(final_render, "create_context", unavailable)
    scene = tiny_scene(bpy, tmp_path)
    scene.render.film_transparent = True  # alpha shows where each eye sees the sphere
    _stereo(scene)
    scene.render.image_settings.views_format = "INDIVIDUAL"
    bpy.ops.render.render(write_still=True)
    views = {eye: rgba(read_rgba_exr(tmp_path / f"f12_{eye}.exr")) for eye in "LR"}
    scene.render.use_multiview = False
    for eye, side in (("L", -1.0), ("R", 1.0)):
        scene.camera.location = (side * 0.25, -5.0, 0.0)  # the camera's x is the world's x
        single = rgba(render(bpy, scene))
        assert (single[..., 3] > 0).sum() > 50, "the sphere is in view"
        # The same renderer from a camera matrix Blender composes in float32 either way:
        # equal to float32 rounding of the image values.
        np.testing.assert_allclose(views[eye], single, atol=2e-6, err_msg=eye)
    assert final_render.last_device.startswith("GLSL" if engine == "glsl" else "OpenCL")
    disparity = np.abs(views["L"][..., 3] - views["R"][..., 3]).sum()
    assert disparity > 2, "the eyes see the sphere from 0.5 apart"


def test_stereo_f12_side_by_side_has_both_eyes(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    scene = tiny_scene(bpy, tmp_path)
    _stereo(scene)
    scene.render.image_settings.views_format = "INDIVIDUAL"
    bpy.ops.render.render(write_still=True)
    views = {eye: rgba(read_rgba_exr(tmp_path / f"f12_{eye}.exr")) for eye in "LR"}
    scene.render.image_settings.views_format = "STEREO_3D"
    scene.render.image_settings.stereo_3d_format.display_mode = "SIDEBYSIDE"
    scene.render.image_settings.stereo_3d_format.use_sidebyside_crosseyed = False
    scene.render.filepath = str(tmp_path / "sbs.exr")
    bpy.ops.render.render(write_still=True)
    pair = rgba(read_rgba_exr(tmp_path / "sbs.exr"))
    assert pair.shape[1] == 2 * W, pair.shape
    assert (pair[:, :W, 3] == 1).all() and (pair[:, W:, 3] == 1).all()  # both halves drawn
    np.testing.assert_array_equal(pair[:, :W], views["L"])
    np.testing.assert_array_equal(pair[:, W:], views["R"])
