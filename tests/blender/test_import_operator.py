"""The import operator: File > Import > BTF Material, as a user runs it (through bpy.ops)."""

from __future__ import annotations

import numpy as np
import pytest
from blender_helpers import extension_submodule
from helpers import shared_material

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container


def _scene_with_selection(bpy, tmp_path):
    """A saved .blend (so paths can be relative) with two selected meshes, one of which already
    has a material, and a selected camera (which cannot take a material)."""
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.object
    old = bpy.data.materials.new("old")
    cube.data.materials.append(old)
    bpy.ops.mesh.primitive_uv_sphere_add(location=(3, 0, 0))
    sphere = bpy.context.object
    bpy.ops.object.camera_add(location=(0, -5, 0))
    for obj in (cube, sphere, bpy.context.object):
        obj.select_set(True)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    return cube, sphere


def test_import_creates_and_assigns_a_btf_material(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    cube, sphere = _scene_with_selection(bpy, tmp_path)
    alu = shared_material("alu")
    # Any file of a BTFbase folder stands for the folder.
    result = bpy.ops.btf.import_material(filepath=str(alu / "all_materialInfo.txt"))
    assert result == {"FINISHED"}
    material = bpy.data.materials["alu"]
    assert material.btf.enabled
    assert material.btf.source.startswith("//")  # relative to the saved .blend
    assert bpy.path.abspath(material.btf.source).rstrip("/\\").endswith("alu")
    assert cube.material_slots[0].material == material  # the active slot replaced
    assert sphere.material_slots[0].material == material  # a slot added
    # Solid view shows the BTF's mean colour: brushed aluminium is a light grey.
    colour = np.array(material.diffuse_color[:3])
    assert 0.1 < colour.min() and colour.max() - colour.min() < 0.2
    export = extension_submodule("btf_addon.blender.export")
    messages: list[str] = []
    exported = export.export_material(material, messages)
    assert exported.material.btf.meta.codec == "mlvq" and not messages
    assert exported.material.name == "alu" and exported.uv_map == ""  # the active render map


def test_a_corrupt_file_changes_nothing(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    cube, sphere = _scene_with_selection(bpy, tmp_path)
    good = tmp_path / "good.btfm"
    write_container(good, LambertianBTF(0.5))
    bad = tmp_path / "bad.btfm"
    bad.write_bytes(good.read_bytes()[:-40])  # truncated
    before = set(bpy.data.materials.keys())
    with pytest.raises(RuntimeError, match="BTF import failed"):
        bpy.ops.btf.import_material(filepath=str(bad))
    with pytest.raises(RuntimeError, match="no such file"):
        bpy.ops.btf.import_material(filepath=str(tmp_path / "missing.btfm"))
    assert set(bpy.data.materials.keys()) == before
    assert cube.material_slots[0].material.name == "old" and len(sphere.material_slots) == 0


def test_procedural_btfs_are_refused_at_import(bpy_module, fresh_scene, tmp_path):
    """A BTF the GPU back ends cannot draw is refused when imported, not at F12."""
    from btf_addon.core.codecs.microgeometry import woven

    bpy = bpy_module
    _scene_with_selection(bpy, tmp_path)
    write_container(tmp_path / "woven.btfm", woven(texels=2, fine_per_texel=2))
    with pytest.raises(RuntimeError, match="tabulate"):
        bpy.ops.btf.import_material(filepath=str(tmp_path / "woven.btfm"))
    assert "woven" not in bpy.data.materials


def test_import_is_registered_as_one_undo_step(bpy_module, installed):
    """Blender pushes one undo step for an operator with UNDO when it finishes (cancelled or
    failed imports push none, and change nothing: the tests above). Background Blender has no
    window, so ed.undo itself cannot run here."""
    module = extension_submodule("btf_addon.blender.tools.import_btf")
    assert {"REGISTER", "UNDO"} <= module.BTF_OT_import_material.bl_options


def test_load_job_reports_errors_from_its_thread(bpy_module, installed, tmp_path):
    """The modal path's loader (the modal loop itself needs a window, which tests lack)."""
    load_job = extension_submodule("btf_addon.blender.tools.import_btf").LoadJob
    (tmp_path / "x.btfm").write_bytes(b"not a container")
    job = load_job(tmp_path / "x.btfm").start()
    assert job.wait(30) and job.btf is None and job.error
