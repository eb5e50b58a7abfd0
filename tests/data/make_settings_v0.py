"""Make tests/data/settings_v0.blend with the code of commit 5d216fc (before issue 14)."""

import sys
from pathlib import Path

import bpy

root = Path.cwd()
sys.path.insert(0, str(root))
import btf_addon  # noqa: E402  (after the sys.path line)

btf_addon.register()
bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
scene = bpy.context.scene
scene.render.engine = "BTF_RENDER"
scene.render.resolution_x, scene.render.resolution_y = 32, 24
scene.render.resolution_percentage = 100
bpy.ops.mesh.primitive_plane_add(size=2.0)
plane = bpy.context.object
mat = bpy.data.materials.new("Woven")
mat.btf.enabled = True
mat.btf.source = "//woven.btfm"
plane.data.materials.append(mat)
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
cam.location = (0.0, 0.0, 4.0)
scene.camera = cam
out = root / "tests" / "data" / "settings_v0.blend"
bpy.ops.wm.save_as_mainfile(filepath=str(out), compress=True, relative_remap=False)
print("saved", out, out.stat().st_size)
print("set?", scene.btf_render.is_property_set("final_mode"), mat.btf.is_property_set("enabled"))
