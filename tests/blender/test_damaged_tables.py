"""A BTFbase folder with a damaged text table in Blender (issue 31): the table comes from
binary.btf, and the user is told — the material panel shows a warning row naming the file,
F12 reports it — and Use binary.btf reads the folder from binary.btf alone. Uses the shared alu
(skipped, saying why, without the research data); one small F12: about 10 s."""

from __future__ import annotations

import shutil
from types import SimpleNamespace

from blender_helpers import draw_panel, extension_submodule, sphere_on_ground
from helpers import shared_material


def _damaged_alu(tmp_path):
    folder = tmp_path / "alu"
    shutil.copytree(shared_material("alu"), folder)
    table = folder / "all_PDF3Dscale.txt"
    text = table.read_text()
    table.write_text(text[: len(text) // 2])  # truncated half-way
    return folder


def test_a_damaged_table_is_shown_reported_and_the_binary_form_chosen(
    bpy_module, fresh_scene, tmp_path, capfd
):
    bpy = bpy_module
    folder = _damaged_alu(tmp_path)
    scene = sphere_on_ground(bpy, tmp_path, folder, (32, 24), 16, 8)
    material = next(m for m in bpy.data.materials if m.btf.enabled)
    export = extension_submodule("btf_addon.blender.export")
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), 32, 24)
    notes = [m for m in exported.messages if "all_PDF3Dscale.txt" in m]
    assert notes and material.name in notes[0], exported.messages

    panels = extension_submodule("btf_addon.blender.ui.btf_panels")
    context = SimpleNamespace(engine="BTF_RENDER", material=material)
    labels = draw_panel(panels.BTF_PT_material, context).labels
    assert any("all_PDF3Dscale.txt" in t for t in labels), labels

    # F12 says it too (a warning, the render goes on).
    scene.render.filepath = str(tmp_path / "f12.png")
    scene.render.image_settings.file_format = "PNG"
    capfd.readouterr()
    bpy.ops.render.render(write_still=True)
    assert (tmp_path / "f12.png").is_file()
    out = capfd.readouterr().out
    warned = [line for line in out.splitlines() if "all_PDF3Dscale.txt" in line]
    assert len(warned) == 1 and warned[0].startswith("Warning:"), out[-3000:]

    material.btf.prefer_binary = True  # the user's choice: binary.btf alone, no mixed read
    materials = extension_submodule("btf_addon.blender.export.materials")
    btf = materials.load_cached(material.btf.source, True)
    assert btf.meta.extra["btfbase_form"] == "binary"
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), 32, 24)
    assert not [m for m in exported.messages if "all_PDF3Dscale.txt" in m], exported.messages
