"""The built extension: validated zip, real install path, clean register/unregister."""

from __future__ import annotations

import inspect
import sys
import zipfile

from blender_helpers import EXTENSION_MODULE, extension_submodule, init_gpu_module


def test_zip_holds_the_extension_and_nothing_else(extension_zip):
    names = zipfile.ZipFile(extension_zip).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    assert "btf_addon/core/codecs/mlvq.py" in names
    assert any(n.startswith("wheels/pyopencl-") and "manylinux" in n for n in names)
    assert not any("win_amd64" in n or "macosx" in n for n in names)  # split per platform
    banned = (
        "tests/",
        "docs/",
        ".venv/",
        "tools/",
        "benchmarks/",
        ".git",
        "__pycache__",
        "Makefile",
        "pyproject.toml",
        "requirements-dev.txt",
        ".ci/",
    )
    assert [n for n in names if n.startswith(banned) or "/__pycache__/" in n] == []


def test_installed_through_the_extension_path(bpy_module, installed):
    assert installed.__name__ == EXTENSION_MODULE
    assert "user_default/btf_materials" in installed.__file__.replace("\\", "/")
    assert hasattr(bpy_module.types.Material, "btf")


def test_register_unregister_register_leaves_nothing_stale(bpy_module, installed, fresh_scene):
    import addon_utils

    bpy = bpy_module
    names = ("BTF_PT_material", "BTF_OT_check_system")

    def registered_classes():
        layer = [
            m
            for name, m in sys.modules.items()
            if name.startswith(EXTENSION_MODULE + ".btf_addon.blender.")
        ]
        return [c for m in layer for c in getattr(m, "classes", ())]

    classes = registered_classes()
    assert len(classes) >= 4 and all(c.is_registered for c in classes)
    assert all(hasattr(bpy.types, n) for n in names)
    addon_utils.disable(EXTENSION_MODULE, default_set=True)
    assert EXTENSION_MODULE not in bpy.context.preferences.addons
    assert not hasattr(bpy.types.Material, "btf")
    assert "btf" not in bpy.types.Material.bl_rna.properties
    assert not any(hasattr(bpy.types, n) for n in names)
    assert not any(c.is_registered for c in classes)
    addon_utils.enable(EXTENSION_MODULE, default_set=True)
    assert all(hasattr(bpy.types, n) for n in names)
    assert all(c.is_registered for c in registered_classes())
    material = bpy.data.materials.new("m")
    material.btf.enabled = True
    material.btf.source = "//materials/alu"
    material.btf.uv_scale = 2.5
    assert (material.btf.enabled, material.btf.source) == (True, "//materials/alu")
    assert bpy.ops.btf.check_system() == {"FINISHED"}


def test_gpu_module_can_be_initialised_in_background(bpy_module, fresh_scene):
    import gpu

    init_gpu_module(bpy_module)
    offscreen = gpu.types.GPUOffScreen(8, 8)
    try:
        assert offscreen.width == 8
    finally:
        offscreen.free()


def test_check_system_reports_every_probe(bpy_module, installed, capfd, monkeypatch):
    """Check System reports each probe but Blender's (it runs inside Blender) once: INFO when
    found, WARNING with the hint when missing. OpenEXR is made missing for real: a None entry
    in sys.modules makes ``import OpenEXR`` raise ImportError."""
    probes = extension_submodule("btf_addon.diagnostics.probes").PROBES
    monkeypatch.setitem(sys.modules, "OpenEXR", None)
    capfd.readouterr()
    assert bpy_module.ops.btf.check_system() == {"FINISHED"}
    lines = capfd.readouterr().out.splitlines()  # background Blender prints reports
    for name, probe in probes.items():
        found = [line for line in lines if line.split(": ")[1:2] == [name]]
        assert len(found) == (0 if name == "blender" else 1), (name, lines)
        if found:
            ok = found[0].startswith(f"Info: {name}: ok ")
            missing = found[0].startswith(f"Warning: {name}: missing (")
            assert ok or (missing and found[0].endswith(probe.hint)), found[0]
    openexr = next(line for line in lines if line.startswith("Warning: openexr: missing ("))
    assert "(ModuleNotFoundError: import of OpenEXR halted" in openexr, openexr


def test_check_system_is_found_and_lists_every_opencl_device(bpy_module, installed, capfd):
    """Check System is where users look (F3 search, Render menu, the add-on's preferences:
    not INTERNAL) and says, per OpenCL device, whether it builds and which one F12 uses."""
    bpy = bpy_module
    op = extension_submodule("btf_addon.blender.operators").BTF_OT_check_system
    assert "INTERNAL" not in getattr(op, "bl_options", set())  # F3 search finds it
    draws = [f.__name__ for f in bpy.types.TOPBAR_MT_render._dyn_ui_initialize()]
    assert "_render_menu" in draws
    prefs = extension_submodule("btf_addon.blender.preferences").BTF_AddonPreferences
    assert "btf.check_system" in inspect.getsource(prefs.draw)
    report = extension_submodule("btf_addon.cl.devices").device_report()
    capfd.readouterr()
    assert bpy.ops.btf.check_system() == {"FINISHED"}
    lines = [line for line in capfd.readouterr().out.splitlines() if "opencl device: " in line]
    assert len(lines) == len(report), lines
    for row, line in zip(report, lines, strict=True):
        assert row["label"] in line
        assert ("builds" in line) == row["builds"] and ("F12 renders on this one" in line) == row[
            "used"
        ]
