"""BTF sources behave like image paths (blender/paths.py): relative on first save, kept
pointing at the same data when the .blend moves, File › External Data operators, and a missing
source that fails F12 (or renders magenta by the preference). Tiny scenes; about 20 s."""

from __future__ import annotations

import math
import os
import shutil

import numpy as np
import pytest
from blender_helpers import EXTENSION_MODULE, extension_submodule, with_nodes

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container


def btf_material(bpy, source: str, name: str = "Grey"):
    material = bpy.data.materials.new(name)
    material.btf.enabled = True
    material.btf.source = source
    material.use_fake_user = True  # saved even where no object uses it
    return material


def test_first_save_makes_sources_relative_and_save_as_keeps_them_pointing(
    bpy_module, fresh_scene, tmp_path
):
    bpy = bpy_module
    data = tmp_path / "project" / "materials"
    data.mkdir(parents=True)
    write_container(data / "grey.btfm", LambertianBTF(0.5))
    material = btf_material(bpy, str(data / "grey.btfm"))  # imported before the first save
    assert bpy.context.preferences.filepaths.use_relative_paths  # Blender's default
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "project" / "scene.blend"))
    assert material.btf.source == "//materials/grey.btfm"
    # Saved elsewhere: the relative path is rewritten to reach the same file.
    (tmp_path / "other" / "deeper").mkdir(parents=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "other" / "deeper" / "moved.blend"))
    assert material.btf.source == "//../../project/materials/grey.btfm"
    assert os.path.normpath(bpy.path.abspath(material.btf.source)) == str(data / "grey.btfm")
    # Save Copy: the copy gets paths for its own place, this session keeps its own.
    (tmp_path / "copy").mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "copy" / "c.blend"), copy=True)
    assert material.btf.source == "//../../project/materials/grey.btfm"
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "copy" / "c.blend"))
    copied = bpy.data.materials["Grey"]
    assert copied.btf.source == "//../project/materials/grey.btfm"
    assert os.path.normpath(bpy.path.abspath(copied.btf.source)) == str(data / "grey.btfm")


def test_an_absolute_source_stays_absolute_after_the_first_save(bpy_module, fresh_scene, tmp_path):
    """As Blender's image paths: only the first save makes paths relative."""
    bpy = bpy_module
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    material = btf_material(bpy, str(tmp_path / "grey.btfm"))
    bpy.ops.wm.save_mainfile()
    assert material.btf.source == str(tmp_path / "grey.btfm")


def test_external_data_operators(bpy_module, fresh_scene, tmp_path, capfd):
    bpy = bpy_module
    (tmp_path / "data").mkdir()
    write_container(tmp_path / "data" / "grey.btfm", LambertianBTF(0.5))
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    grey = btf_material(bpy, str(tmp_path / "data" / "grey.btfm"))
    gone = btf_material(bpy, str(tmp_path / "gone.btfm"), "Gone")
    assert bpy.ops.btf.make_paths_relative() == {"FINISHED"}
    assert (grey.btf.source, gone.btf.source) == ("//data/grey.btfm", "//gone.btfm")
    assert bpy.ops.btf.make_paths_absolute() == {"FINISHED"}
    assert grey.btf.source == str(tmp_path / "data" / "grey.btfm")
    assert bpy.ops.btf.report_missing() == {"FINISHED"}
    paths = extension_submodule("btf_addon.blender.paths")
    missing = [m.btf.source for m in paths.btf_materials() if paths.source_problem(m.btf.source)]
    assert missing == [str(tmp_path / "gone.btfm")]
    # Pack beside the .blend: a folder next to it holds a copy; the .blend and it travel.
    assert bpy.ops.btf.pack_beside() == {"FINISHED"}
    assert grey.btf.source == "//btf_sources/grey.btfm"
    assert (tmp_path / "btf_sources" / "grey.btfm").read_bytes() == (
        tmp_path / "data" / "grey.btfm"
    ).read_bytes()
    assert gone.btf.source == str(tmp_path / "gone.btfm")  # nothing to copy: left, reported
    menu = {f.__name__ for f in bpy.types.TOPBAR_MT_file_external_data._dyn_ui_initialize()}
    assert "menu_external_data" in menu


def test_a_light_bake_is_external_data_like_a_btf_source(bpy_module, fresh_scene, tmp_path):
    """Issue 34: the scene's bake path (written relative by Bake Light for VR) is remapped on
    Save As, made absolute and relative, reported when missing and packed beside the .blend,
    as BTF sources are (the file's bytes stand in for a bake: only its path is handled)."""
    bpy = bpy_module
    project = tmp_path / "project"
    project.mkdir()
    bake = project / "scene.Scene.light_bake.npz"
    bake.write_bytes(b"a bake's bytes")
    bpy.ops.wm.save_as_mainfile(filepath=str(project / "scene.blend"))
    scene = bpy.context.scene
    scene.btf_bake.path = "//scene.Scene.light_bake.npz"
    (tmp_path / "other").mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "other" / "moved.blend"))
    assert scene.btf_bake.path == "//../project/scene.Scene.light_bake.npz"
    assert os.path.normpath(bpy.path.abspath(scene.btf_bake.path)) == str(bake)
    assert bpy.ops.btf.make_paths_absolute() == {"FINISHED"}
    assert scene.btf_bake.path == str(bake)
    assert bpy.ops.btf.make_paths_relative() == {"FINISHED"}
    assert scene.btf_bake.path == "//../project/scene.Scene.light_bake.npz"
    paths = extension_submodule("btf_addon.blender.paths")
    assert [p.label for p in paths.external_paths()] == ["scene 'Scene' light bake"]
    assert bpy.ops.btf.pack_beside() == {"FINISHED"}
    assert scene.btf_bake.path == "//btf_sources/scene.Scene.light_bake.npz"
    assert (tmp_path / "other" / "btf_sources" / bake.name).read_bytes() == bake.read_bytes()
    # Save Copy elsewhere: the copy's path reaches the same bake, this session keeps its own.
    (tmp_path / "copy").mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "copy" / "c.blend"), copy=True)
    assert scene.btf_bake.path == "//btf_sources/scene.Scene.light_bake.npz"
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "copy" / "c.blend"))
    assert bpy.context.scene.btf_bake.path == "//../other/btf_sources/scene.Scene.light_bake.npz"


def small_render_scene(bpy, tmp_path, source: str):
    scene = bpy.context.scene
    scene.render.engine = "BTF_RENDER"
    scene.render.resolution_x, scene.render.resolution_y = 16, 16
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.btf_render.lights_total = 4
    bpy.ops.mesh.primitive_cube_add()
    bpy.context.object.data.materials.append(btf_material(bpy, source, "Broken"))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -6.0, 0.0)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.camera = cam
    world = with_nodes(bpy.data.worlds.new("W"))
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    scene.world = world
    scene.render.filepath = str(tmp_path / "x.exr")
    return scene


@pytest.fixture
def preferences(bpy_module, installed):
    prefs = bpy_module.context.preferences.addons[EXTENSION_MODULE].preferences
    yield prefs
    prefs.missing_source = "FAIL"


def test_missing_source_fails_the_render_or_renders_magenta(
    bpy_module, fresh_scene, tmp_path, preferences
):
    """A missing BTF used to render a plausible colour with a warning and a successful job."""
    from btf_addon.core.formats.imageio import read_exr

    bpy = bpy_module
    small_render_scene(bpy, tmp_path, str(tmp_path / "missing.btfm"))
    assert preferences.missing_source == "FAIL"  # the default
    with pytest.raises(RuntimeError, match=r"missing; nothing rendered(.|\n)*'Broken'"):
        bpy.ops.render.render(write_still=True)
    assert not (tmp_path / "x.exr").exists()
    preferences.missing_source = "PINK"
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    centre = read_exr(tmp_path / "x.exr")[8, 8]  # the cube's front face
    # Magenta: red and blue lit by the grey World, no green at all.
    assert centre[0] > 0.05 and centre[2] > 0.05 and centre[1] == 0.0


def test_a_corrupt_source_fails_the_render_in_one_line_naming_the_file(
    bpy_module, fresh_scene, tmp_path, preferences
):
    """Issue 30 item 16: a damaged .btfm gave three lines ("1 BTF source(s) missing", the
    material, the advice); a farm's log shows the first. One line names the material and the
    file, and why."""
    from btf_addon.core.codecs.analytic import LambertianBTF
    from btf_addon.core.formats.container import write_container

    bpy = bpy_module
    source = write_container(tmp_path / "damaged.btfm", LambertianBTF(0.5))
    source.write_bytes(source.read_bytes()[:-7])  # truncated: the end marker is gone
    small_render_scene(bpy, tmp_path, str(source))
    with pytest.raises(RuntimeError) as err:
        bpy.ops.render.render(write_still=True)
    # Blender lists the error once per way it was raised (error_set and report): one line,
    # however many times it is listed.
    lines = {line.removeprefix("Error: ") for line in str(err.value).strip().splitlines()}
    assert len(lines) == 1, lines
    (line,) = lines
    assert "nothing rendered" in line and "'Broken'" in line
    assert str(source) in line and "truncated" in line


def test_a_blend_and_its_folder_render_elsewhere(bpy_module, fresh_scene, tmp_path):
    """The project folder moved to another machine's path: relative sources still load."""
    bpy = bpy_module
    project = tmp_path / "here"
    (project / "materials").mkdir(parents=True)
    write_container(project / "materials" / "grey.btfm", LambertianBTF(0.5))
    scene = small_render_scene(bpy, tmp_path, str(project / "materials" / "grey.btfm"))
    bpy.ops.wm.save_as_mainfile(filepath=str(project / "scene.blend"))
    assert bpy.data.materials["Broken"].btf.source == "//materials/grey.btfm"
    moved = tmp_path / "farm" / "elsewhere"
    shutil.move(str(project), str(moved))
    bpy.ops.wm.open_mainfile(filepath=str(moved / "scene.blend"))
    scene = bpy.context.scene
    scene.render.filepath = str(tmp_path / "farm.exr")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}  # FAIL mode: it loaded
    from btf_addon.core.formats.imageio import read_exr

    assert np.ptp(read_exr(tmp_path / "farm.exr")[8, 8]) < 1e-3  # grey, not magenta
