"""What the exporter sees of modifiers and instances: the evaluated depsgraph, as F12 renders."""

from __future__ import annotations

import numpy as np
from blender_helpers import extension_submodule


def _camera(bpy, scene):
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam


def _triangles(exported, name):
    return sum(m.triangle_count for m in exported.meshes if m.name == name)


def test_modifiers_are_applied(bpy_module, fresh_scene):
    bpy = bpy_module
    _camera(bpy, fresh_scene)
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.object
    cube.modifiers.new("Array", "ARRAY").count = 3
    export = extension_submodule("btf_addon.blender.export")
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), 16, 16)
    assert _triangles(exported, "Cube") == 3 * 12
    xs = np.concatenate([m.world_space_corners()[:, 0] for m in exported.meshes])
    assert xs.max() - xs.min() > 5.9  # three cubes side by side (relative offset 1: 6 units)


def test_collection_and_geometry_node_instances(bpy_module, fresh_scene):
    """Two empties instancing a collection with a cube, and a plane whose geometry nodes put a
    generated cube (other mesh data under the plane's name) on each of its 4 corners."""
    bpy = bpy_module
    scene = fresh_scene
    _camera(bpy, scene)
    collection = bpy.data.collections.new("Kit")
    bpy.ops.mesh.primitive_cube_add(size=0.5)
    kit_cube = bpy.context.object
    for c in kit_cube.users_collection:
        c.objects.unlink(kit_cube)
    collection.objects.link(kit_cube)
    for x in (-5.0, 5.0):
        empty = bpy.data.objects.new(f"Empty{x}", None)
        empty.instance_type, empty.instance_collection = "COLLECTION", collection
        empty.location = (x, 0.0, 0.0)
        scene.collection.objects.link(empty)
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.object
    tree = bpy.data.node_groups.new("corners", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    on_points = tree.nodes.new("GeometryNodeInstanceOnPoints")
    join = tree.nodes.new("GeometryNodeJoinGeometry")
    tree.links.new(group_in.outputs[0], on_points.inputs["Points"])
    tree.links.new(tree.nodes.new("GeometryNodeMeshCube").outputs[0], on_points.inputs["Instance"])
    tree.links.new(on_points.outputs[0], join.inputs[0])
    tree.links.new(group_in.outputs[0], join.inputs[0])
    tree.links.new(join.outputs[0], group_out.inputs[0])
    plane.modifiers.new("GN", "NODES").node_group = tree

    export = extension_submodule("btf_addon.blender.export")
    cache = export.ExportCache()
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), 16, 16, cache)
    kit = [m for m in exported.meshes if m.name == "Cube"]
    assert sorted(m.world_from_object[0, 3] for m in kit) == [-5.0, 5.0]
    # The plane's own 2 triangles plus 4 generated cubes of 12, each at a corner.
    assert _triangles(exported, "Plane") == 2 + 4 * 12
    cubes = [m for m in exported.meshes if m.name == "Plane" and m.triangle_count == 12]
    corners = sorted(tuple(m.world_from_object[:2, 3]) for m in cubes)
    assert corners == [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
    # A second export reuses every cached mesh (one export per geometry, not per instance).
    before = {key: value[0] for key, value in cache.meshes.items()}
    export.export_scene(bpy.context.evaluated_depsgraph_get(), 16, 16, cache)
    assert all(cache.meshes[key][0] is meshes for key, meshes in before.items())
