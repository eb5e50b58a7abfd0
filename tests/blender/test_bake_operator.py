"""Bake Light for VR in Blender (issue 34): the operator refuses an unsaved file, bakes a saved
one beside it (scripted: to the end), keeps the bake's relative path and report on the scene,
the panel shows one line per object, and the command line's ``bake`` of the same file and knobs
writes the same values bit for bit (both run blender/bake/run.py's functions)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from blender_helpers import draw_panel, extension_submodule, sphere_on_ground
from helpers import run_cli

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container

pytestmark = pytest.mark.opencl

#: Small knobs: about 300 points on the sphere and ground, seconds on PoCL.
KNOBS = {"spacing": 0.5, "view_bins": 2, "samples": 16}


def _scene(bpy, tmp_path):
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (32, 24), 12, 6)
    for name, value in KNOBS.items():
        setattr(scene.btf_bake, name, value)
    return scene


def test_an_unsaved_file_is_refused_with_what_to_do(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    _scene(bpy, tmp_path)
    assert not bpy.data.filepath
    with pytest.raises(RuntimeError, match=r"save the \.blend first"):
        bpy.ops.btf.bake_light()
    assert not list(tmp_path.glob("*.light_bake.*"))


def test_operator_and_command_line_bake_the_same_data(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    scene = _scene(bpy, tmp_path)
    blend = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert bpy.ops.btf.bake_light() == {"FINISHED"}
    written = tmp_path / f"scene.{scene.name}.light_bake.npz"
    assert written.is_file() and (tmp_path / f"scene.{scene.name}.light_bake.json").is_file()
    assert scene.btf_bake.path == f"//{written.name}"  # relative, like BTF sources
    report = json.loads(scene.btf_bake.report)
    assert [m["baked"] for m in report["meshes"]] == [True, True]  # sphere on its ground
    assert report["knobs"]["samples"] == KNOBS["samples"]

    module = extension_submodule("btf_addon.blender.bake.operator")
    labels = draw_panel(module.BTF_PT_render_light_bake, bpy.context).labels
    lines = [label for label in labels if "baked at" in label]
    assert len(lines) == 2 and all("shadows" in line for line in lines), labels

    store = extension_submodule("btf_addon.render.light_bake")
    ours = store.load(written)
    out = tmp_path / "cli"
    out.mkdir()
    args = [f"--{k.replace('_', '-')}={v}" for k, v in KNOBS.items()]
    run_cli("bake", "--blend", str(blend), "-o", str(out), *args)
    theirs = store.load(out / written.name)
    assert ours.knobs == theirs.knobs
    for key, array in ours.arrays.items():
        np.testing.assert_array_equal(array, theirs.arrays[key], err_msg=key)
    assert np.any(ours.arrays["ratio"] > 0)


def test_baking_again_keeps_what_is_unchanged(bpy_module, fresh_scene, tmp_path):
    """Baked twice: the second keeps both objects (the panel says so) with the same values;
    the sphere moved, both are traced again (each lies beside the other), saying why; Re-bake
    Everything traces both though nothing changed."""
    bpy = bpy_module
    scene = _scene(bpy, tmp_path)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    store = extension_submodule("btf_addon.render.light_bake")
    written = tmp_path / f"scene.{scene.name}.light_bake.npz"
    assert bpy.ops.btf.bake_light() == {"FINISHED"}
    first = store.load(written)

    def meshes() -> dict[str, dict]:
        return {m["name"]: m for m in json.loads(scene.btf_bake.report)["meshes"]}

    assert bpy.ops.btf.bake_light() == {"FINISHED"}
    assert [m["kept"] for m in meshes().values()] == [True, True]
    module = extension_submodule("btf_addon.blender.bake.operator")
    labels = draw_panel(module.BTF_PT_render_light_bake, bpy.context).labels
    kept = [label for label in labels if "(kept: unchanged since the last bake; " in label]
    assert len(kept) == 2, labels
    again = store.load(written)
    for key, array in first.arrays.items():
        assert again.arrays[key].tobytes() == array.tobytes(), key

    sphere = next(o for o in scene.objects if o.type == "MESH" and o.name.startswith("Sphere"))
    ground = next(o for o in scene.objects if o.type == "MESH" and o is not sphere)
    sphere.location.z += 0.05
    assert bpy.ops.btf.bake_light() == {"FINISHED"}
    moved = meshes()
    assert not any(m["kept"] for m in moved.values())
    assert moved[sphere.name]["rebaked"] == "it changed"
    assert moved[ground.name]["rebaked"] == f"'{sphere.name}' beside it changed"

    assert bpy.ops.btf.bake_light() == {"FINISHED"}  # the moved scene, unchanged since
    assert all(m["kept"] for m in meshes().values())
    assert bpy.ops.btf.bake_light(rebake_all=True) == {"FINISHED"}
    assert not any(m["kept"] or m["rebaked"] for m in meshes().values())
