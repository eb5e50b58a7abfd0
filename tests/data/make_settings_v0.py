"""Make tests/data/settings_v0.blend with the code of commit 5d216fc (before issue 14): run
from the root of a checkout of that commit (``git archive 5d216fc | tar -x -C DIR``)."""

import sys
from pathlib import Path

import bpy

root = Path.cwd()
sys.path.insert(0, str(root))
import btf_addon  # noqa: E402  (after the sys.path line)
from btf_addon.blender import compat  # noqa: E402

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
cam.location = (0.0, 0.0, 2.2)  # the 2 m plane fills the frame
scene.camera = cam
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
sun.data.energy = 3.0
sun.rotation_euler = (0.5, 0.3, 0.0)
scene.collection.objects.link(sun)
world = compat.with_nodes(bpy.data.worlds.new("Grey"))
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.3, 0.3, 1.0)
scene.world = world
out = root / "tests" / "data" / "settings_v0.blend"
bpy.ops.wm.save_as_mainfile(filepath=str(out), compress=True, relative_remap=False)
print("saved", out, out.stat().st_size)
print("set?", scene.btf_render.is_property_set("final_mode"), mat.btf.is_property_set("enabled"))
