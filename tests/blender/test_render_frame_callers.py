"""F12 and the accuracy report's rungs run one frame sequence (cl/frame.py ``render_frame``),
and the report renders every rung on one renderer: the scene's BVH built once, each rung's
image bit for bit the one a renderer built for its film and texel filter gave before."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from aa_scenes import checker_btf
from blender_helpers import extension_submodule, sphere_on_ground

from btf_addon.core.formats.container import write_container


def _checker_scene(bpy, tmp_path, size=(32, 24)):
    """The tests' sphere on ground in a measured (dense) checkerboard BTF: the texel filters
    and the Sampled mode's importance tables both matter."""
    write_container(tmp_path / "checker.btfm", checker_btf())
    return sphere_on_ground(bpy, tmp_path, tmp_path / "checker.btfm", size, 16, 8)


def _recording(module, calls):
    """``module.render_frame`` replaced by one that records its settings, then renders."""
    real = module.render_frame

    def render_frame(renderer, settings, *args, **kwargs):
        calls.append(settings)
        return real(renderer, settings, *args, **kwargs)

    return render_frame


def test_f12_renders_through_render_frame(bpy_module, fresh_scene, tmp_path, monkeypatch):
    bpy = bpy_module
    scene = _checker_scene(bpy, tmp_path, (16, 12))
    scene.btf_render.samples = 2
    final_render = extension_submodule("btf_addon.blender.final_render")
    frame = extension_submodule("btf_addon.cl.frame")
    assert final_render.render_frame is frame.render_frame
    calls = []
    monkeypatch.setattr(final_render, "render_frame", _recording(frame, calls))
    for mode in ("SAMPLED", "VIRTUAL"):
        scene.btf_render.final_mode = mode
        bpy.ops.render.render(write_still=True)
    assert [s.final_mode.name for s in calls] == ["SAMPLED", "VIRTUAL"]


def test_every_rung_on_one_renderer_as_on_its_own_before(
    bpy_module, fresh_scene, tmp_path, monkeypatch
):
    bpy = bpy_module
    _checker_scene(bpy, tmp_path)
    # Bit for bit needs launches split by a fixed plan (render/launch.py), old and new alike.
    monkeypatch.setenv("BTF_FIXED_LAUNCHES", "1")
    run = extension_submodule("btf_addon.blender.accuracy.run")
    ladder = extension_submodule("btf_addon.render.accuracy.ladder")
    cl_renderer = extension_submodule("btf_addon.cl.renderer")
    frame = extension_submodule("btf_addon.cl.frame")
    builds, calls = [], []
    real_build = cl_renderer.cached_bvh

    def counting_build(*args, **kwargs):
        builds.append(1)
        return real_build(*args, **kwargs)

    monkeypatch.setattr(cl_renderer, "cached_bvh", counting_build)
    monkeypatch.setattr(run, "render_frame", _recording(frame, calls))
    estimate, rungs, renderer = run.prepare(
        bpy.context.evaluated_depsgraph_get(), 16, reference_samples=8, reference_bounces=2
    )
    reference = ladder.Rung(estimate.reference, "reference", extra=(("texel_filter", "LINEAR"),))
    rungs = [reference, *rungs]
    pairs = {(r.settings.film(), r.value("texel_filter")) for r in rungs}
    assert len(pairs) >= 3  # the ladder changes both the film and the texel filter
    images = [renderer(rung, lambda fraction: True) for rung in rungs]
    assert len(builds) == 1  # one renderer for every rung
    assert all(image is not None and image.max() > 0 for image in images)
    assert calls == [r.settings for r in rungs]

    def before(rung):
        """The rung as a renderer built for its film and texel filter rendered it."""
        scene, texel_filter = renderer.scene, rung.value("texel_filter")
        if texel_filter is not None:
            materials = [replace(m, texel_filter=texel_filter) for m in scene.materials]
            scene = replace(scene, materials=materials)
        own = cl_renderer.CLRenderer(
            scene, renderer.width, renderer.height, renderer.ctx, film=rung.settings.film()
        )
        settings = rung.settings
        lights = run.frame_lights(settings, scene, scene.camera.world_from_camera[:3, 2])
        if settings.sampled:
            own.clamp_indirect = settings.clamp_indirect
            own.samples_per_camera_ray = settings.samples_per_camera_ray
            own.adaptive_threshold = settings.noise_threshold
            own.render_direct(lights.prefix(1))
            image = own.render_sampled(
                settings.samples, settings.seed, max_bounces=settings.max_bounces
            )
        else:
            image = own.render_direct(lights, aa_samples=settings.aa_samples).combined
        return image[..., :3]

    for rung, image in zip(rungs, images, strict=True):
        assert np.array_equal(image, before(rung)), rung.knob_values()
