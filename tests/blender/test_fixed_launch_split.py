"""Render › BTF › Fixed Launch Split reaches F12's launch plan (render/launch.py), and F12 with
it renders the same bits twice (farms diff frames)."""

from __future__ import annotations

import numpy as np
from blender_helpers import extension_submodule, sphere_on_ground

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr


def test_fixed_launch_split_reaches_the_plan_and_repeats_bits(
    bpy_module, fresh_scene, tmp_path, monkeypatch
):
    bpy = bpy_module
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (24, 16), 16, 8)
    scene.btf_render.final_mode = "SAMPLED"
    scene.btf_render.samples = 8
    scene.btf_render.fixed_launch_split = True
    renderer_module = extension_submodule("btf_addon.cl.renderer")
    plans = []

    class RecordingPlan(renderer_module.LaunchPlan):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            plans.append(kwargs.get("fixed"))

    monkeypatch.setattr(renderer_module, "LaunchPlan", RecordingPlan)
    images = []
    for _ in range(2):
        bpy.ops.render.render(write_still=True)
        images.append(read_exr(tmp_path / "f12.exr"))
    assert plans and all(fixed is True for fixed in plans)
    np.testing.assert_array_equal(images[0], images[1])


def test_btf_importance_sampling_setting_reaches_the_renderer(
    bpy_module, fresh_scene, tmp_path, monkeypatch
):
    """Render › BTF › BTF Importance Sampling (on by default) is what F12's renderer uses."""
    bpy = bpy_module
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (16, 12), 16, 8)
    scene.btf_render.final_mode = "SAMPLED"
    scene.btf_render.samples = 2
    renderer_module = extension_submodule("btf_addon.cl.renderer")
    seen = []
    real = renderer_module.CLRenderer.render_sampled

    def recording(self, *args, **kwargs):
        seen.append(self.importance_sampling)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(renderer_module.CLRenderer, "render_sampled", recording)
    assert scene.btf_render.btf_importance_sampling is True
    bpy.ops.render.render(write_still=True)
    scene.btf_render.btf_importance_sampling = False
    bpy.ops.render.render(write_still=True)
    assert seen == [True, False]
