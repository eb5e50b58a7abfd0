"""Adaptive sampling's two settings (issue 33) between Blender and the render: the properties
read into RenderSettings and written back, and both drawn in the BTF render panel beside
Samples. That old files open with it off is tests/blender/test_versioning.py's table row."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import pytest
from blender_helpers import draw_panel, extension_submodule


def test_adaptive_sampling_round_trips_and_is_drawn_beside_samples(bpy_module, fresh_scene):
    settings = extension_submodule("btf_addon.render.settings")
    props = fresh_scene.btf_render
    assert props.use_adaptive_sampling and props.adaptive_threshold == pytest.approx(0.01)
    values = settings.RenderSettings.from_properties(props)
    assert values.noise_threshold == pytest.approx(0.01)  # on in new scenes, as Cycles
    changed = replace(values, use_adaptive_sampling=False, adaptive_threshold=0.05)
    changed.to_properties(props)
    back = settings.RenderSettings.from_properties(props)
    assert not back.use_adaptive_sampling and back.noise_threshold == 0.0  # off renders fully
    assert back.adaptive_threshold == pytest.approx(0.05)  # kept for when it is on again

    panels = extension_submodule("btf_addon.blender.ui.btf_panels")
    context = SimpleNamespace(engine="BTF_RENDER", scene=fresh_scene)
    names = [name for _data, name in draw_panel(panels.BTF_PT_render_settings, context).props]
    at = names.index("samples")
    assert names[at + 1 : at + 3] == ["use_adaptive_sampling", "adaptive_threshold"]
