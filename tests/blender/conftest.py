"""Blender tests run against the extension as users install it.

The session builds the zip with Blender's own builder, installs it into an isolated user folder
(``BLENDER_USER_RESOURCES``, set here before bpy is imported) through
``bpy.ops.extensions.package_install_files`` and enables it as
``bl_ext.user_default.btf_materials``.
"""

from __future__ import annotations

import atexit
import importlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from blender_helpers import EXTENSION_MODULE
from helpers import ROOT

# Before any `import bpy` in this process: Blender reads it once, at start-up.
USER_RESOURCES = tempfile.mkdtemp(prefix="btf-blender-user-")
os.environ["BLENDER_USER_RESOURCES"] = USER_RESOURCES
# The installed extension (bundled PoCL, pyopencl, OpenEXR...) is about 570 MB: a session that
# left it behind filled CI's disk after a few runs. Removed when the interpreter exits, after
# Blender is done with it.
atexit.register(shutil.rmtree, USER_RESOURCES, ignore_errors=True)


def pytest_collection_modifyitems(items):
    for item in items:
        if "tests/blender/" in str(item.fspath):
            item.add_marker(pytest.mark.blender)


@pytest.fixture(scope="session")
def extension_zip(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "build_extension.py"), "--output-dir", str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, (
        f"build failed (run `make wheels` first?)\n{proc.stdout}\n{proc.stderr}"
    )
    zips = sorted(out.glob("btf_materials-*-linux_x64.zip"))
    assert zips, proc.stdout
    return zips[0]


@pytest.fixture(scope="session")
def bpy_module():
    pytest.importorskip("bpy", reason="Blender as a Python module (pip install bpy==5.0.1)")
    import bpy

    return bpy


@pytest.fixture(scope="session")
def installed(bpy_module, extension_zip):
    """The extension's top module, installed and enabled the way a user's Blender does it."""
    bpy = bpy_module
    result = bpy.ops.extensions.package_install_files(
        filepath=str(extension_zip), repo="user_default", enable_on_install=True
    )
    assert result == {"FINISHED"}
    assert EXTENSION_MODULE in bpy.context.preferences.addons
    return importlib.import_module(EXTENSION_MODULE)


@pytest.fixture
def fresh_scene(bpy_module, installed):
    """Factory startup file (empty scene) between tests; the extension stays enabled."""
    bpy_module.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    assert EXTENSION_MODULE in bpy_module.context.preferences.addons
    return bpy_module.context.scene


def pytest_terminal_summary(terminalreporter):
    """End the report with the Blender these tests ran on, so a failure names its version."""
    bpy = sys.modules.get("bpy")
    if bpy is not None:
        terminalreporter.write_line(
            f"Blender tests ran on Blender {bpy.app.version_string} "
            f"(Python {sys.version.split()[0]})"
        )
