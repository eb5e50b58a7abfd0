"""Old files keep their look when defaults change (blender/versioning.py), tested with a file
saved by the code before issue 14 (tests/data/settings_v0.blend, see tests/data/README.md).
Rows of the upgrade table whose property does not exist yet are skipped here; the test covers
every row that exists. No renders: a few seconds."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from blender_helpers import draw_panel, extension_submodule
from helpers import ROOT

DATA = ROOT / "tests" / "data"


def open_v0(bpy, tmp_path):
    if bpy.app.version < (4, 5, 0):
        pytest.skip(
            "tests/data/settings_v0.blend was saved by Blender 5.0, whose file header Blender "
            "4.2 cannot read (4.5 was given that ability; 4.2 opens only older files); these "
            "tests run on Blender 4.5, 5.0 and 5.3"
        )
    for name in ("settings_v0.blend", "woven.btfm", "settings_v0.exr"):
        shutil.copy(DATA / name, tmp_path / name)
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "settings_v0.blend"))


def group_of(bpy, row):
    block = bpy.context.scene if row.owner == "scene" else bpy.data.materials["Woven"]
    return getattr(block, row.group)


def test_a_version_0_file_gets_its_old_defaults_explicitly(bpy_module, installed, tmp_path):
    bpy = bpy_module
    versioning = extension_submodule("btf_addon.blender.versioning")
    open_v0(bpy, tmp_path)
    scene = bpy.context.scene
    assert scene.render.engine == "BTF_RENDER" and bpy.data.materials["Woven"].btf.enabled
    assert scene.btf_settings_version == 0  # saved before versioning; stamped on save
    present = [r for r in versioning.UPGRADES if r.prop in group_of(bpy, r).bl_rna.properties]
    assert any(r.prop == "final_mode" for r in present)  # exists today; others as they land
    for row in present:
        group = group_of(bpy, row)
        assert group.is_property_set(row.prop), row
        assert getattr(group, row.prop) == row.old, row
    # Saved and reopened: the old values are now stored, and stay.
    bpy.ops.wm.save_mainfile()
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "settings_v0.blend"))
    assert bpy.context.scene.btf_settings_version == versioning.SETTINGS_VERSION
    for row in present:
        assert getattr(group_of(bpy, row), row.prop) == row.old, row


def test_current_files_keep_current_defaults(bpy_module, installed, tmp_path):
    """A file made now is stamped with the current version on save: nothing is set on load,
    so it keeps the defaults it was made with (today's)."""
    bpy = bpy_module
    versioning = extension_submodule("btf_addon.blender.versioning")
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    material = bpy.data.materials.new("Woven")
    material.use_fake_user = True
    material.btf.enabled = True
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "now.blend"))
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "now.blend"))
    scene = bpy.context.scene
    assert scene.btf_settings_version == versioning.SETTINGS_VERSION
    for row in versioning.UPGRADES:
        group = group_of(bpy, row)
        if row.prop in group.bl_rna.properties:
            assert not group.is_property_set(row.prop), row


def test_a_version_0_file_renders_as_it_did(bpy_module, installed, tmp_path):
    """The point of versioning: F12 of the old file equals the frame the old code rendered
    (tests/data/settings_v0.exr), whatever defaults have changed since. Virtual Lights is
    deterministic; 1e-4 of the brightest value allows for float reassociation between kernel
    builds, far below any change of filtering, mapping or mode (those move whole texels)."""
    from btf_addon.core.formats.imageio import read_exr

    bpy = bpy_module
    open_v0(bpy, tmp_path)
    scene = bpy.context.scene
    image = scene.render.image_settings
    if hasattr(image, "media_type"):  # Blender 5: a multilayer EXR or video first
        image.media_type = "IMAGE"
    image.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "now.exr")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    then = read_exr(tmp_path / "settings_v0.exr")
    now = read_exr(tmp_path / "now.exr")
    assert then.shape == now.shape == (24, 32, 3)
    assert np.ptp(then) > 0.3  # a lit, textured plane, not an empty frame
    np.testing.assert_allclose(now, then, rtol=0, atol=1e-4 * then.max())


def test_the_upgrade_is_reported_and_shown_in_the_render_panel(
    bpy_module, installed, tmp_path, capfd
):
    """Issue 32 item 6: the upgrade was a print on the console only. It is a Blender report
    (stdout in background, the status bar with a UI) and a box in the render panel until the
    next file is loaded."""
    from types import SimpleNamespace

    bpy = bpy_module
    versioning = extension_submodule("btf_addon.blender.versioning")
    panels = extension_submodule("btf_addon.blender.ui.btf_panels")
    open_v0(bpy, tmp_path)
    out = capfd.readouterr().out
    assert "Info: BTF:" in out and "kept its look" in out, out[-2000:]
    assert versioning.upgraded

    context = SimpleNamespace(engine="BTF_RENDER", scene=bpy.context.scene)
    labels = draw_panel(panels.BTF_PT_render_settings, context).labels
    assert any(t.startswith("Opened from an older version") for t in labels), labels
    assert set(versioning.upgraded) <= set(labels)
    bpy.ops.wm.read_homefile(use_empty=True)  # another file: the note goes
    assert not versioning.upgraded
