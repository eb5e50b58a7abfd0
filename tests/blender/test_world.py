"""The World's environment as Blender sets it up, read through the add-on's Blender layer
(blender/export/world.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from blender_helpers import extension_submodule, with_nodes
from helpers import random_hemisphere, studiolights_dir

from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment


def environment_from_world(world):
    return extension_submodule("btf_addon.blender.export.world").environment_from_world(world)


def make_world(bpy, exr_path, rotation_z_deg=0.0, strength=1.0, interpolation="Linear"):
    world = with_nodes(bpy.data.worlds.new("W"))
    nodes, links = world.node_tree.nodes, world.node_tree.links
    background = nodes["Background"]
    background.inputs["Strength"].default_value = strength
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(str(exr_path))
    texture.interpolation = interpolation
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value[2] = math.radians(rotation_z_deg)
    coords = nodes.new("ShaderNodeTexCoord")
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], background.inputs["Color"])
    bpy.context.scene.world = world
    return world


def test_world_extraction_equals_reading_the_exr_and_rotating(bpy_module, fresh_scene, rng):
    exr = studiolights_dir() / "forest.exr"
    world = make_world(bpy_module, exr, rotation_z_deg=30.0, strength=2.0)
    env, messages = environment_from_world(world)
    assert messages == []
    direct = Environment(read_exr(exr), strength=2.0, rotation_z_rad=math.radians(30.0))
    dirs = random_hemisphere(rng, 5000) * rng.choice([-1, 1], size=(5000, 1))
    np.testing.assert_array_equal(env.lookup(dirs), direct.lookup(dirs))
    np.testing.assert_allclose(env.pdf(dirs), direct.pdf(dirs), rtol=1e-12)


def test_plain_world_colour_is_a_constant_environment(bpy_module, fresh_scene):
    world = with_nodes(bpy_module.data.worlds.new("Plain"))  # Blender 5: worlds always have nodes
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.3, 0.4, 1.0)
    env, messages = environment_from_world(world)
    assert messages == []
    np.testing.assert_allclose(
        env.lookup(np.array([[0, 0, 1.0], [1, 0, 0]])), [[0.2, 0.3, 0.4]] * 2, rtol=1e-6
    )


def test_unsupported_world_gives_a_message_and_a_constant(bpy_module, fresh_scene):
    world = with_nodes(bpy_module.data.worlds.new("Sky"))
    nodes = world.node_tree.nodes
    sky = nodes.new("ShaderNodeTexSky")
    world.node_tree.links.new(sky.outputs["Color"], nodes["Background"].inputs["Color"])
    env, messages = environment_from_world(world)
    assert len(messages) == 1 and "Sky Texture" in messages[0]
    assert env.width == 1 and env.height == 1


@pytest.mark.parametrize("rotation", [0.0, 50.0])
def test_orientation_matches_what_cycles_renders(bpy_module, fresh_scene, tmp_path, rotation):
    """Cycles renders the World seen by a narrow camera; the add-on's lookup of the same
    directions must reproduce it, and the opposite rotation sign must not."""
    bpy = bpy_module
    exr = studiolights_dir() / "forest.exr"
    make_world(bpy, exr, rotation_z_deg=rotation, interpolation="Closest")
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.cycles.filter_width = 0.01
    scene.view_settings.view_transform = "Standard"
    size = 24
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    cam_data = bpy.data.cameras.new("C")
    cam_data.lens, cam_data.sensor_width, cam_data.sensor_fit = 100.0, 36.0, "HORIZONTAL"
    cam = bpy.data.objects.new("C", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.rotation_euler = (math.radians(80.0), 0.0, math.radians(-35.0))  # a view near the horizon
    bpy.context.view_layer.update()
    out = tmp_path / "render.exr"
    scene.render.filepath = str(out)
    bpy.ops.render.render(write_still=True)
    rendered = read_exr(out)  # row 0 = top

    # The same pixels' directions. filter_width 0.01 makes every Cycles sample land within
    # 1/100 pixel of the pixel centre, so centre lookups (Closest) are the exact expectation.
    half = 0.5 * cam_data.sensor_width / cam_data.lens
    rot = np.array(cam.matrix_world.to_3x3())
    xs = ((np.arange(size) + 0.5) / size * 2 - 1) * half
    ys = (1 - (np.arange(size) + 0.5) / size * 2) * half
    gx, gy = np.meshgrid(xs, ys)
    dirs = np.stack([gx, gy, -np.ones_like(gx)], axis=-1).reshape(-1, 3) @ rot.T
    errors = {}
    for sign in (+1, -1):
        env = Environment(read_exr(exr), rotation_z_rad=sign * math.radians(rotation))
        expected = env.lookup(dirs).reshape(size, size, 3)
        errors[sign] = np.abs(rendered - expected).mean() / expected.mean()
    # A sample 1/100 pixel off-centre can still cross into the neighbouring map pixel: allow a
    # few such pixels (1% of the mean), nothing like a mis-oriented map (tens of percent).
    assert errors[+1] < 0.01, errors
    if rotation:
        assert errors[-1] > 0.1, errors
