"""The viewport re-exports and re-uploads only what the depsgraph says changed."""

from __future__ import annotations

import numpy as np
from blender_helpers import extension_submodule, init_gpu_module, with_nodes


def two_objects(bpy):
    bpy.ops.mesh.primitive_cube_add(location=(-1.5, 0.0, 0.0))
    a = bpy.context.object
    a.name = "A"
    bpy.ops.mesh.primitive_uv_sphere_add(location=(1.5, 0.0, 0.0))
    b = bpy.context.object
    b.name = "B"
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    bpy.context.scene.collection.objects.link(cam)
    cam.location = (0.0, -8.0, 0.0)
    cam.rotation_euler = (1.5708, 0.0, 0.0)
    bpy.context.scene.camera = cam
    return a, b


def arrays_by_object(scene):
    return {m.name: (m.positions, np.array(m.world_from_object)) for m in scene.meshes}


def test_only_changed_objects_are_exported_and_uploaded(bpy_module, fresh_scene):
    bpy = bpy_module
    export = extension_submodule("btf_addon.blender.export")
    gpu_draw = extension_submodule("btf_addon.blender.gpu_draw")
    init_gpu_module(bpy)
    a, _b = two_objects(bpy)
    # The drawer batches a material's meshes: A has a material of its own, so its batch holds
    # A alone and B's batch can be kept when A changes.
    a.data.materials.append(with_nodes(bpy.data.materials.new("Red")))
    cache = export.ExportCache()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    first = export.export_scene(depsgraph, 32, 32, cache)
    drawer = gpu_draw.scene_drawer(first)
    before = arrays_by_object(first)

    # A transform only: nothing re-exported, A's matrix updated.
    a.location.x -= 0.5
    bpy.context.view_layer.update()
    moved = export.export_scene(bpy.context.evaluated_depsgraph_get(), 32, 32, cache)
    after = arrays_by_object(moved)
    assert after["A"][0] is before["A"][0] and after["B"][0] is before["B"][0]
    assert after["A"][1][0, 3] == before["A"][1][0, 3] - 0.5

    # A's geometry: the depsgraph reports A only, and only A is exported and uploaded again.
    reported = {}

    def capture(_scene, depsgraph):
        reported.setdefault("ids", export.changed_ids(depsgraph))

    bpy.app.handlers.depsgraph_update_post.append(capture)
    try:
        a.data.vertices[0].co.z += 0.5
        a.data.update()
        bpy.context.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(capture)
    objects, materials, world = reported["ids"]
    assert "A" in objects and "B" not in objects and not world
    cache.invalidate(objects, materials, world)
    edited = export.export_scene(bpy.context.evaluated_depsgraph_get(), 32, 32, cache)
    final = arrays_by_object(edited)
    assert final["A"][0] is not before["A"][0] and final["B"][0] is before["B"][0]
    uploaded = [vertices for vertices, _ in drawer.batches]
    env_tex = drawer.env_tex
    redrawn = gpu_draw.scene_drawer(edited, previous=drawer)
    assert redrawn.uploads == {"tables": 0, "meshes": 1}  # B's buffer and both tables reused
    # The same GPU objects, not new uploads of equal data: one of the two batches is B's.
    kept = [v for v, _ in redrawn.batches if any(v is u for u in uploaded)]
    assert len(kept) == 1
    assert redrawn.env_tex is env_tex and redrawn.device is drawer.device


def test_material_change_invalidates_its_objects(bpy_module, fresh_scene):
    bpy = bpy_module
    export = extension_submodule("btf_addon.blender.export")
    a, _b = two_objects(bpy)
    material = bpy.data.materials.new("Red")
    a.data.materials.append(material)
    cache = export.ExportCache()
    export.export_scene(bpy.context.evaluated_depsgraph_get(), 32, 32, cache)
    cache.invalidate(materials={"Red"})
    names = {key.object_name for key in cache.meshes}
    assert "A" not in names and "B" in names
    cache.invalidate(world=True)
    assert cache.environment is None
