"""Issue 15 inside Blender: the svd codec's GLSL through Blender's gpu module, and the import
operator taking a UBO2014 .btf."""

from __future__ import annotations

import numpy as np
from blender_helpers import extension_submodule, init_gpu_module
from helpers import random_queries
from svd_cases import svd_cases


def test_blender_gpu_svd_matches_numpy_within_1_255(bpy_module, fresh_scene, rng):
    init_gpu_module(bpy_module)
    import blender_gpu_query as gpu_query

    svd_mod = extension_submodule("btf_addon.core.codecs.svd")
    reference = svd_cases()["yuv"]
    # The extension's own class (its module path differs from the checkout's).
    btf = svd_mod.SVDBTF.from_params(reference.params(), reference.tables())
    q = random_queries(rng, 3_000)
    got = gpu_query.blender_gpu_btf(btf).evaluate_angles(q)
    want = reference.evaluate_angles(q)
    assert want.max() * np.pi > 0.05
    assert np.abs(got - want).max() * np.pi <= 1.0 / 255.0


def test_import_operator_takes_a_ubo2014_btf(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    from btf_addon.core.formats.ubo2014_writer import write_ubo2014

    path = tmp_path / "woven.btf"
    write_ubo2014(path, svd_cases()["yuv"])
    bpy.ops.mesh.primitive_cube_add()
    bpy.context.object.select_set(True)
    result = bpy.ops.btf.import_material(filepath=str(path))
    assert result == {"FINISHED"}
    material = bpy.data.materials["woven"]
    assert material.btf.enabled and bpy.path.abspath(material.btf.source).endswith("woven.btf")
    export = extension_submodule("btf_addon.blender.export")
    messages: list[str] = []
    exported = export.export_material(material, messages)
    assert exported.material.btf.meta.codec == "svd" and not messages
