"""The bpy-free layers import in plain Python without pulling in bpy or a GPU library."""

from __future__ import annotations

import subprocess
import sys

from helpers import ROOT

PURE_PACKAGES = [
    "btf_addon",
    "btf_addon.core",
    "btf_addon.cl",
    "btf_addon.gl",
    "btf_addon.scene",
    "btf_addon.render",
    "btf_addon.diagnostics",
    "btf_addon.controllers",
    "btf_addon.xr.bridge",  # pyopenxr, moderngl and EGL only inside functions
    "btf_addon.cli.main",
]


def test_pure_layers_import_without_bpy_or_gpu_libraries():
    import pkgutil

    import btf_addon.core

    core_modules = [
        f"btf_addon.core.{m.name}" for m in pkgutil.iter_modules(btf_addon.core.__path__)
    ]
    code = (
        "import importlib, sys\n"
        f"for name in {PURE_PACKAGES + core_modules!r}: importlib.import_module(name)\n"
        "gpu = ('bpy', 'pyopencl', 'moderngl', 'OpenEXR', 'hidraw')\n"
        "bad = [m for m in gpu if m in sys.modules]\n"
        "print('LEAKED', bad) if bad else print('CLEAN')\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=False
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "CLEAN", out.stdout
    assert len(core_modules) >= 10  # the walk really found the core's modules


def test_only_the_blender_layer_imports_bpy_at_module_level():
    """Outside blender/, bpy may only be imported inside a function that is never called on
    import (the doctor's probe, which runs in its own subprocess)."""
    import ast

    offenders = []
    for path in (ROOT / "btf_addon").rglob("*.py"):
        if path.relative_to(ROOT / "btf_addon").parts[0] == "blender":
            continue
        for node in ast.parse(path.read_text()).body:  # module level only
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            if any(n.split(".")[0] in ("bpy", "pyopencl", "moderngl") for n in names):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert offenders == []
