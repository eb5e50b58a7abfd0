"""``scene.btf_vr`` (Blender's VR session) and ``scene.btf_bridge`` (the XTAL bridge) set the
same ideas for a headset's eyes: each with one meaning, one default and one range in both
groups, and the same plain values (blender/sync.py) for a fresh scene.

Before, the groups were written twice and drifted: the frame budget defaulted to 11 ms in one
and 0 ("the runtime's period") in the other, with different ranges, and only the VR group
described its settings or could fix the lights per frame."""

from __future__ import annotations

from dataclasses import fields

import pytest
from blender_helpers import extension_submodule

#: The headset's ideas, as both groups name them.
SHARED = {
    "lights_mode",
    "frame_budget_ms",
    "lights_per_frame",
    "lights_total",
    "exposure",
    "show_hud",
}
#: What only one path has: Blender's controller action sets and its own VR background; the
#: bridge's headset profile and eye resolution.
OWN = {
    "btf_vr": {"controller_actions", "show_world"},
    "btf_bridge": {"profile", "resolution_scale"},
}


def signature(prop) -> dict:
    """What a user sees of a property: its label, tooltip, default and limits."""
    keys = ["type", "name", "description", "subtype", "unit"]
    if prop.type in ("INT", "FLOAT"):
        keys += ["default", "hard_min", "hard_max", "soft_min", "soft_max", "step"]
    if prop.type == "FLOAT":
        keys.append("precision")
    if prop.type in ("BOOLEAN", "ENUM"):
        keys.append("default")
    values = {key: getattr(prop, key) for key in keys}
    if prop.type == "ENUM":
        values["items"] = [(i.identifier, i.name, i.description) for i in prop.enum_items]
    return values


@pytest.fixture
def groups(bpy_module, fresh_scene):
    scene = bpy_module.context.scene
    if not hasattr(scene, "btf_vr"):
        pytest.skip("this Blender build has no OpenXR: no VR session, no scene.btf_vr")
    return scene.btf_vr, scene.btf_bridge


def user_properties(group) -> set[str]:
    return {p.identifier for p in group.bl_rna.properties} - {"rna_type", "name"}


def test_each_shared_idea_has_one_default_and_one_range(groups):
    vr, bridge = groups
    assert user_properties(vr) & user_properties(bridge) == SHARED
    assert user_properties(vr) - SHARED == OWN["btf_vr"]
    assert user_properties(bridge) - SHARED == OWN["btf_bridge"]
    for name in sorted(SHARED):
        a, b = vr.bl_rna.properties[name], bridge.bl_rna.properties[name]
        assert signature(a) == signature(b), name
        assert a.description, name  # every setting says what it does


def test_a_fresh_scene_gives_both_paths_the_same_headset_settings(bpy_module, groups):
    """The plain values each path reads (blender/sync.py): equal for every shared idea, and
    ``HeadsetSettings``'s own defaults (the CLI's bridge starts from those)."""
    sync = extension_submodule("btf_addon.blender.sync")
    eye = extension_submodule("btf_addon.gl.eye")
    scene = bpy_module.context.scene
    vr, bridge = sync.vr_settings(scene), sync.bridge_settings(scene)
    assert isinstance(vr, eye.HeadsetSettings) and isinstance(bridge, eye.HeadsetSettings)
    for field in fields(eye.HeadsetSettings):
        name = field.name
        assert getattr(vr, name) == getattr(bridge, name) == field.default, name


def test_the_same_edit_gives_both_paths_the_same_values(bpy_module, groups):
    """One reader for both groups: fixed lights, a budget, exposure, HUD read alike."""
    sync = extension_submodule("btf_addon.blender.sync")
    eye = extension_submodule("btf_addon.gl.eye")
    scene = bpy_module.context.scene
    for group in groups:
        group.lights_mode, group.lights_per_frame, group.lights_total = "FIXED", 9, 64
        group.frame_budget_ms, group.exposure, group.show_hud = 8.0, 1.5, False
    vr, bridge = sync.vr_settings(scene), sync.bridge_settings(scene)
    expected = eye.HeadsetSettings(
        lights_total=64, lights_per_frame=9, budget_s=0.008, exposure=1.5, show_hud=False
    )
    for field in fields(eye.HeadsetSettings):
        name = field.name
        assert getattr(vr, name) == getattr(bridge, name) == getattr(expected, name), name
    assert not vr.use_budget and not bridge.use_budget


class Recorder:
    """A stand-in for a panel's layout: records the properties drawn, in order."""

    def __init__(self, shown: list):
        self.shown = shown
        self.use_property_split = self.enabled = True

    def prop(self, data, name, **_kw):
        self.shown.append(name)

    def column(self, **_kw):
        return self

    box = column

    def operator(self, *_args, **_kw):
        pass

    def label(self, **_kw):
        pass


def test_both_panels_show_the_shared_settings_alike(bpy_module, groups):
    """Budget mode shows the budget, fixed mode the K: in both panels, in one order."""
    bpy = bpy_module
    panels = {
        "btf_vr": bpy.types.VIEW3D_PT_btf_vr,
        "btf_bridge": bpy.types.VIEW3D_PT_btf_xtal_bridge,
    }
    for mode, hidden in (("BUDGET", "lights_per_frame"), ("FIXED", "frame_budget_ms")):
        drawn = {}
        for (name, panel), group in zip(panels.items(), groups, strict=True):
            group.lights_mode = mode
            shown = drawn[name] = []
            panel.draw(type("Self", (), {"layout": Recorder(shown)})(), bpy.context)
        for name, shown in drawn.items():
            assert hidden not in shown
            assert set(shown) == SHARED - {hidden} | OWN[name], name
        assert [n for n in drawn["btf_vr"] if n in SHARED] == [
            n for n in drawn["btf_bridge"] if n in SHARED
        ]
