"""What the exporter sees of modifiers and instances (the evaluated depsgraph, as F12 renders),
what its cache keeps, and the camera's sensor fit."""

from __future__ import annotations

import math

import numpy as np
import pytest
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
    # One cache entry per geometry, not per instance: the kit cube (two empties), the plane's
    # own mesh, and the generated cube (four corners).
    assert sorted(key.object_name for key in cache.meshes) == ["Cube", "Plane", "Plane"]
    # A second export reuses every cached mesh.
    before = {key: entry.meshes for key, entry in cache.meshes.items()}
    export.export_scene(bpy.context.evaluated_depsgraph_get(), 16, 16, cache)
    assert cache.meshes.keys() == before.keys()
    assert all(cache.meshes[key].meshes is meshes for key, meshes in before.items())


def test_cache_forgets_deleted_objects_and_edited_materials(bpy_module, fresh_scene):
    bpy = bpy_module
    _camera(bpy, fresh_scene)
    fresh_scene.world = None
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.object
    cube.data.materials.append(bpy.data.materials.new("Red"))
    bpy.ops.mesh.primitive_uv_sphere_add(location=(3.0, 0.0, 0.0))
    sphere = bpy.context.object
    export = extension_submodule("btf_addon.blender.export")
    cache = export.ExportCache()
    export.export_scene(bpy.context.evaluated_depsgraph_get(), 16, 16, cache)
    entries = {key.object_name: entry for key, entry in cache.meshes.items()}
    assert entries["Cube"].material_names == ("Red",) and entries["Sphere"].material_names == ("",)
    cache.invalidate(materials={"Red"})
    assert [key.object_name for key in cache.meshes] == ["Sphere"]
    assert cache.environment is not None and cache.environment.world_name == ""
    bpy.data.objects.remove(sphere)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), 16, 16, cache)
    assert [key.object_name for key in cache.meshes] == ["Cube"]  # re-exported; Sphere dropped
    assert [m.name for m in exported.materials] == ["Red"]
    assert "the scene has no World: black" in exported.messages


@pytest.mark.parametrize(
    ("sensor_fit", "width", "height", "sensor_mm"),
    [
        # Landscape: the 36 mm width spans the image width, the height gets 36 / 2 = 18 mm.
        ("AUTO", 32, 16, 18.0),
        ("HORIZONTAL", 32, 16, 18.0),
        ("VERTICAL", 32, 16, 24.0),  # sensor_height spans the height
        # Portrait: AUTO fits the larger side (now the height) to sensor_width.
        ("AUTO", 16, 32, 36.0),
        ("HORIZONTAL", 16, 32, 72.0),
        ("VERTICAL", 16, 32, 24.0),
    ],
)
def test_camera_sensor_fit(bpy_module, fresh_scene, sensor_fit, width, height, sensor_mm):
    """The vertical field of view is the sensor height the fit gives (sensor 36 × 24 mm)."""
    bpy = bpy_module
    _camera(bpy, fresh_scene)
    data = fresh_scene.camera.data
    data.sensor_fit, data.sensor_width, data.sensor_height, data.lens = sensor_fit, 36, 24, 50
    camera = extension_submodule("btf_addon.blender.export.camera")
    exported = camera.export_camera(fresh_scene, width, height)
    # Exact up to float rounding of the same formula: 1e-12 rad.
    assert exported.fov_y_rad == pytest.approx(2 * math.atan(sensor_mm / 2 / 50), abs=1e-12)
