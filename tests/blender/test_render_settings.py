"""``scene.btf_render`` and ``render.settings.RenderSettings`` are one vocabulary: the same
fields, the same defaults, enum identifiers and numbers taken from the Python enums."""

from __future__ import annotations

import enum
from dataclasses import fields

import pytest
from blender_helpers import extension_submodule


def test_defaults_equal_the_blender_property_defaults(bpy_module, installed):
    settings = extension_submodule("btf_addon.render.settings")
    props = bpy_module.types.Scene.bl_rna.properties["btf_render"].fixed_type.properties
    defaults = settings.RenderSettings()
    names = [f.name for f in fields(defaults)]
    # The film filter lives on the scene's film (scene.cycles), not on btf_render.
    names = [name for name in names if name not in settings.FILM_FIELDS]
    assert set(names) == {p.identifier for p in props} - {"rna_type", "name"}
    for name in names:
        value = getattr(defaults, name)
        expected = props[name].default
        assert (value.name if isinstance(value, enum.Enum) else value) == expected, name


def test_enum_items_are_the_python_enums(bpy_module, installed):
    settings = extension_submodule("btf_addon.render.settings")
    props = bpy_module.types.Scene.bl_rna.properties["btf_render"].fixed_type.properties
    for prop, members in (("lighting", settings.Lighting), ("final_mode", settings.FinalMode)):
        items = [(item.identifier, item.value) for item in props[prop].enum_items]
        assert items == [(m.name, m.value) for m in members], prop


def test_a_fresh_scene_reads_back_as_the_defaults(bpy_module, fresh_scene):
    settings = extension_submodule("btf_addon.render.settings")
    props = fresh_scene.btf_render
    assert settings.RenderSettings.from_properties(props) == settings.RenderSettings()
    # With Cycles on, its default film is Blender's: the same as ours without it.
    assert settings.RenderSettings.from_scene(fresh_scene) == settings.RenderSettings()
    changed = settings.RenderSettings(
        lights_total=7,
        seed=3,
        lighting=settings.Lighting.HEADLIGHT,
        final_mode=settings.FinalMode.SAMPLED,
    )
    changed.to_properties(props)
    assert props.lighting == "HEADLIGHT" and props.final_mode == "SAMPLED"
    assert settings.RenderSettings.from_properties(props) == changed


def test_a_saved_device_no_longer_listed_renders_on_the_automatic_choice(
    bpy_module, installed, monkeypatch
):
    """A GPU or driver removed since the preference was saved: Blender reads the stored
    enum value back as "" (not among the items any more). F12 must then choose automatically,
    not fail while parsing the choice."""
    preferences = extension_submodule("btf_addon.blender.preferences")
    entry = bpy_module.context.preferences.addons[preferences.ADDON_PACKAGE]
    items = preferences.device_items()
    if len(items) < 2:
        pytest.skip("needs one OpenCL device to save as the preference (PoCL in CI)")
    entry.preferences.opencl_device = items[1][0]
    assert preferences.preferred_device() == 0
    # The device disappears: the dynamic enum's items are only "Automatic" now.
    monkeypatch.setattr(preferences, "_device_items", [items[0]])
    try:
        assert entry.preferences.opencl_device == ""  # what Blender reads back
        assert preferences.preferred_device() is None
    finally:
        monkeypatch.undo()
        entry.preferences.opencl_device = preferences.AUTOMATIC
