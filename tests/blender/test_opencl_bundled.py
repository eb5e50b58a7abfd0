"""OpenCL out of the box: on Linux the zip bundles PoCL (pocl-binary-distribution), so F12
from the installed extension renders on a machine with no OpenCL driver registered at all:
ray traced where the bundled PoCL (LLVM 14) can build for this CPU, else through the GLSL path
with one warning that names the reason (CPUs newer than LLVM 14, e.g. AMD Zen 5). Which of the
two this machine gets is read from the device report, so the test holds on either CPU.

The check runs in a fresh Blender process (bpy in a subprocess): an empty
``OCL_ICD_VENDORS`` folder hides every system driver, and the extension's own site-packages
is put first on sys.path, as in Blender, where it is the only pyopencl (this venv has its own,
with PoCL, which would otherwise prove nothing). About 30 s (install and one 24 × 16 frame)."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile

import pytest
from helpers import cli_env

SCRIPT = r"""
import json, math, sys
import bpy

zip_path, out = sys.argv[-2], sys.argv[-1]
site = bpy.utils.user_resource(
    "EXTENSIONS", path=f".local/lib/python{sys.version_info[0]}.{sys.version_info[1]}/site-packages"
)
already = "pyopencl" in sys.modules  # imported before the path change: the test is void
# First on sys.path before the install: enabling the extension starts importing pyopencl on a
# thread (cl/warm.py), which must find the wheels the install puts here, as in Blender. The
# folder exists first so that Python's finder for it sees what is unpacked into it later.
import os
os.makedirs(site, exist_ok=True)
sys.path.insert(0, site)
assert bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo="user_default", enable_on_install=True
) == {"FINISHED"}
import importlib
final_render = importlib.import_module(
    "bl_ext.user_default.btf_materials.btf_addon.blender.final_render"
)
scene = bpy.context.scene
scene.render.engine = "BTF_RENDER"
scene.render.resolution_x, scene.render.resolution_y = 24, 16
scene.render.resolution_percentage = 100
scene.btf_render.lights_total = 4
# The startup file's own cube sits exactly where the new one goes: two coincident surfaces,
# where which one a ray sees is a tie the BVH's layout decides. Only ours stays.
startup_cube = bpy.data.objects.get("Cube")
if startup_cube is not None:
    bpy.data.objects.remove(startup_cube)
bpy.ops.mesh.primitive_cube_add()
# A dark cube against a bright World: contrast whichever path draws it. (Lit by the startup
# file's grey World, the cube's visible face came out 0.04 against the World's 0.05: within 0.04
# of each other after the view transform, although correctly rendered.)
scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
dark = bpy.data.materials.new("Dark")
dark.diffuse_color = (0.02, 0.02, 0.02, 1.0)  # what a material without nodes renders with
if dark.node_tree is not None:  # Blender 5 gives a new material its Principled BSDF
    dark.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = dark.diffuse_color
bpy.context.object.data.materials.append(dark)
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
cam.location = (0.0, -6.0, 0.0)
cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
scene.camera = cam
scene.render.filepath = out + ".png"
result = bpy.ops.render.render(write_still=True)
import pyopencl
devices = importlib.import_module("bl_ext.user_default.btf_materials.btf_addon.cl.devices")
saved = bpy.data.images.load(out + ".png")
rgb = [v for i, v in enumerate(saved.pixels[:]) if i % 4 != 3]
with open(out, "w") as fh:
    json.dump({"result": sorted(result), "device": final_render.last_device,
               "pyopencl": pyopencl.__file__, "site": site, "already": already,
               "report": devices.device_report(), "min": min(rgb), "max": max(rgb)}, fh)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PoCL is bundled for Linux")
def test_f12_renders_without_any_system_opencl(extension_zip, tmp_path):
    user = tempfile.mkdtemp(prefix="btf-blender-user-", dir=tmp_path)
    no_vendors = tmp_path / "no-vendors"
    no_vendors.mkdir()
    env = cli_env(
        BLENDER_USER_RESOURCES=user, OCL_ICD_VENDORS=str(no_vendors), OCL_ICD_FILENAMES=""
    )
    out = tmp_path / "result.json"
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(extension_zip), str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0 and out.exists(), proc.stdout[-3000:] + proc.stderr[-3000:]
    got = json.loads(out.read_text())
    assert not got["already"], "pyopencl was imported before the extension's site-packages"
    assert got["pyopencl"].startswith(got["site"]), got  # the bundled pyopencl, not the venv's
    assert got["result"] == ["FINISHED"]
    report = got["report"]
    assert len(report) == 1 and report[0]["bundled"], report  # only the bundled PoCL is seen
    bundled = report[0]
    assert "PoCL" in bundled["label"] and "bundled" in bundled["label"], bundled
    # An image of the lit cube against the World, not a blank frame: values span a range.
    assert got["max"] - got["min"] > 0.1, got
    if bundled["builds"]:
        assert got["device"] == f"OpenCL on {bundled['label']}", (got, proc.stdout[-2000:])
        assert "OpenCL unavailable" not in proc.stdout
    else:  # this CPU is newer than the bundled LLVM: the GLSL path, with one warning and why
        assert got["device"].startswith("GLSL fallback"), got
        warnings = [line for line in proc.stdout.splitlines() if "OpenCL unavailable" in line]
        assert len(warnings) == 1, proc.stdout[-3000:]
        assert bundled["reason"] in warnings[0] and "pocl-opencl-icd" in warnings[0], warnings
