"""Non-BTF materials: which analytic BTF each surface shader becomes
(blender/export/surface_shaders.py)."""

from __future__ import annotations

import numpy as np
import pytest
from blender_helpers import extension_submodule, with_nodes


def _material(bpy, node_type: str | None, **inputs):
    material = with_nodes(bpy.data.materials.new(node_type or "plain"))
    tree = material.node_tree
    for node in list(tree.nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(node)
    if node_type is not None:
        node = tree.nodes.new(node_type)
        for name, value in inputs.items():
            node.inputs[name].default_value = value
        tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def _export(material):
    materials = extension_submodule("btf_addon.blender.export.surface_shaders")
    messages: list[str] = []
    return materials.analytic_btf(material, messages), messages


def test_each_shader_becomes_its_analytic_btf(bpy_module, fresh_scene):
    bpy = bpy_module
    btf, messages = _export(_material(bpy, "ShaderNodeBsdfDiffuse", Color=(0.2, 0.4, 0.6, 1.0)))
    assert btf.meta.codec == "lambertian" and not messages
    np.testing.assert_allclose(btf.albedo, [0.2, 0.4, 0.6], rtol=1e-6)

    btf, _ = _export(_material(bpy, "ShaderNodeBsdfGlossy", Roughness=0.3))
    assert btf.meta.codec == "ggx" and btf.roughness == pytest.approx(0.3)

    principled = _material(bpy, "ShaderNodeBsdfPrincipled", Metallic=0.25, Roughness=0.7, IOR=2.0)
    btf, messages = _export(principled)
    assert btf.meta.codec == "principled" and not messages
    assert btf.metallic == pytest.approx(0.25) and btf.roughness == pytest.approx(0.7)
    assert btf.specular_f0 == pytest.approx((1 / 3) ** 2, rel=1e-5)  # ((n − 1)/(n + 1))²

    emission = _material(bpy, "ShaderNodeEmission")
    emission.diffuse_color = (0.9, 0.1, 0.1, 1.0)
    btf, messages = _export(emission)
    assert btf.meta.codec == "principled" and "not rendered" in messages[0]
    np.testing.assert_allclose(btf.base_color, [0.9, 0.1, 0.1], rtol=1e-6)


def test_textured_inputs_are_reported(bpy_module, fresh_scene):
    bpy = bpy_module
    material = _material(bpy, "ShaderNodeBsdfPrincipled")
    tree = material.node_tree
    texture = tree.nodes.new("ShaderNodeTexChecker")
    tree.links.new(texture.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    _, messages = _export(material)
    assert any("Base Color is driven by nodes" in m for m in messages)


def test_equal_settings_share_one_btf(bpy_module, fresh_scene):
    """The GPU back ends upload one set of tables per BTF object: materials whose shaders have
    the same settings (to 6 decimals) get the same object, different settings another."""
    bpy = bpy_module
    colour = (0.2, 0.4, 0.6, 1.0)
    first, _ = _export(_material(bpy, "ShaderNodeBsdfDiffuse", Color=colour))
    same, _ = _export(_material(bpy, "ShaderNodeBsdfDiffuse", Color=colour))
    other, _ = _export(_material(bpy, "ShaderNodeBsdfDiffuse", Color=(0.2, 0.4, 0.7, 1.0)))
    assert same is first and other is not first
    np.testing.assert_allclose(other.albedo, [0.2, 0.4, 0.7], rtol=1e-6)


def test_a_script_changing_btf_settings_reaches_the_evaluated_material(bpy_module, fresh_scene):
    """What F12, the viewport and the VR preview export is the depsgraph's evaluated copy: a
    change made from Python (not the UI) must reach it. Blender does not tag an ID when an
    add-on's property is set from Python; the properties' update callback does."""
    bpy = bpy_module
    bpy.ops.mesh.primitive_cube_add()
    material = with_nodes(bpy.data.materials.new("Tagged"))
    bpy.context.object.data.materials.append(material)
    evaluated = bpy.context.object.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert evaluated.material_slots[0].material.btf.exposure == 0.0
    material.btf.exposure, material.btf.source = 1.5, "//elsewhere.btfm"
    depsgraph = bpy.context.evaluated_depsgraph_get()
    copy = bpy.context.object.evaluated_get(depsgraph).material_slots[0].material.btf
    assert (copy.exposure, copy.source) == (1.5, "//elsewhere.btfm")
