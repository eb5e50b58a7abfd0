"""Choosing a BTF source as a user does: a folder, any file inside a BTFbase folder (its
tables, binary.btf), a .btfm file, nothing; the material panel's Load BTF filling the current
material; drag and drop. The BTFbase cases use the shared research data (skipped without it);
the loads are cached, so the file runs in about 15 s."""

from __future__ import annotations

import pytest
from blender_helpers import extension_submodule, with_nodes
from helpers import shared_material

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container


def paths():
    return extension_submodule("btf_addon.blender.paths")


def test_any_file_of_a_btfbase_folder_stands_for_the_folder(bpy_module, installed):
    alu = shared_material("alu")
    for chosen in (alu, f"{alu}/", alu / "all_materialInfo.txt", alu / "binary.btf"):
        assert paths().source_for(str(chosen)) == str(alu), chosen
        assert paths().source_hint(str(chosen)) == "", chosen


def test_the_source_property_stores_the_folder(bpy_module, fresh_scene):
    """The BTF Source browser picks files: a table picked inside the folder means the folder
    (it used to be loaded as a container: "bad magic")."""
    alu = shared_material("alu")
    material = bpy_module.data.materials.new("m")
    material.btf.source = str(alu / "alu_PDF6Dslices.txt")
    assert material.btf.source == str(alu)
    export = extension_submodule("btf_addon.blender.export")
    material.btf.enabled = True
    messages: list[str] = []
    assert export.export_material(material, messages).material.btf.meta.codec == "mlvq"
    assert messages == []


def test_empty_and_stray_choices_say_what_to_pick(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    assert "pick a BTFbase material folder" in paths().source_hint("")
    (tmp_path / "notes.txt").write_text("not a table")
    assert "pick the material's folder" in paths().source_hint(str(tmp_path / "notes.txt"))
    with pytest.raises(RuntimeError, match="no BTF chosen: pick a BTFbase material folder"):
        bpy.ops.btf.import_material(filepath="")
    with pytest.raises(RuntimeError, match="pick the material's folder"):
        bpy.ops.btf.import_material(filepath=str(tmp_path / "notes.txt"))


def test_load_btf_fills_the_current_material(bpy_module, fresh_scene, tmp_path):
    """The material panel's button: the material in the slot gets the BTF; no new material,
    nothing orphaned, its other settings kept."""
    bpy = bpy_module
    write_container(tmp_path / "grey.btfm", LambertianBTF(0.5))
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.object
    material = with_nodes(bpy.data.materials.new("Mine"))
    material.btf.exposure = 1.5
    cube.data.materials.append(material)
    before = set(bpy.data.materials.keys())
    result = bpy.ops.btf.import_material(
        filepath=str(tmp_path / "grey.btfm"), target_material="Mine"
    )
    assert result == {"FINISHED"}
    assert set(bpy.data.materials.keys()) == before
    assert cube.material_slots[0].material == material
    assert material.btf.enabled and material.btf.source == str(tmp_path / "grey.btfm")
    assert material.btf.exposure == 1.5
    assert material.diffuse_color[0] == pytest.approx(0.5, abs=0.01)  # the BTF's mean colour


def test_drag_and_drop_imports_btfm_and_btfbase_files(bpy_module, installed):
    bpy = bpy_module
    handler = bpy.types.FileHandler.bl_rna_get_subclass_py("BTF_FH_material")
    assert handler is not None and handler.bl_import_operator == "btf.import_material"
    assert {".btfm", ".btf", ".txt"} <= set(handler.bl_file_extensions.split(";"))
    # The operator takes a dropped path without a file browser: filepath is not remembered.
    props = bpy.ops.btf.import_material.get_rna_type().properties
    assert props["filepath"].is_skip_save
