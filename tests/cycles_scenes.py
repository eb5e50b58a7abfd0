"""The scenes both renderers draw in the Cycles comparisons (tests/blender/test_cycles_compare.py)
and the time-to-equal-error benchmark (benchmarks/bench_vs_cycles.py): a smooth UV sphere, an
optional ground plane, a camera and the bundled forest.exr World, built through bpy."""

from __future__ import annotations

import math

import numpy as np
from blender_helpers import forest_world, with_nodes

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr

SIZE = (48, 36)


def relative_rmse(image: np.ndarray, reference: np.ndarray) -> float:
    return float(np.sqrt(np.mean((image - reference) ** 2)) / np.sqrt(np.mean(reference**2)))


def cycles_material(bpy, kind: str, roughness: float = 0.3):
    material = with_nodes(bpy.data.materials.new(kind))
    nodes, links = material.node_tree.nodes, material.node_tree.links
    for node in list(nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            nodes.remove(node)
    if kind == "diffuse":
        bsdf = nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Roughness"].default_value = 0.0
    else:
        bsdf = nodes.new("ShaderNodeBsdfGlossy")
        bsdf.distribution = "GGX"
        bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    links.new(bsdf.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    return material


def principled_material(bpy, metallic: float):
    """A Principled BSDF with single-scatter GGX (Cycles' default adds multiple scattering,
    which the analytic model leaves out) and no BTF: rendered by our analytic model."""
    material = with_nodes(bpy.data.materials.new("principled"))
    node = material.node_tree.nodes["Principled BSDF"]
    node.distribution = "GGX"
    node.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1.0)
    node.inputs["Roughness"].default_value = 0.4
    node.inputs["Metallic"].default_value = metallic
    return material


def build(bpy, tmp_path, kind: str, ground: bool, roughness: float = 0.3, world: str = "forest"):
    """kind "glossy" is GGX of ``roughness``; ``world``: a bundled studiolight's name."""
    scene = bpy.context.scene
    if kind.startswith("principled"):
        material = principled_material(bpy, 1.0 if kind == "principled-metal" else 0.0)
    elif kind.endswith("-node"):  # the Cycles material alone: our engine reads its node
        material = cycles_material(bpy, kind.removesuffix("-node"), roughness)
    else:
        btf = LambertianBTF(0.8) if kind == "diffuse" else GGXBTF(0.8, roughness)
        write_container(tmp_path / "m.btfm", btf)
        material = cycles_material(bpy, kind, roughness)
        material.btf.enabled = True  # the same material carries both renderers' descriptions
        material.btf.source = str(tmp_path / "m.btfm")
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=64, ring_count=32)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(material)
    if ground:
        bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, -1.0))
        bpy.context.object.data.materials.append(material)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -4.5, 1.5)
    cam.rotation_euler = (math.radians(75.0), 0.0, 0.0)
    scene.world = forest_world(bpy, image=world)
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    return scene


def cycles_reference(bpy, scene, tmp_path, samples: int, bounces: int, seed: int = 7) -> np.ndarray:
    scene.render.engine = "CYCLES"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    # Blender's default film (Blackman-Harris 1.5 px) on both sides: our F12 filters the same.
    scene.cycles.max_bounces = bounces
    scene.cycles.diffuse_bounces = scene.cycles.glossy_bounces = bounces
    scene.cycles.seed = seed
    # Exactly `samples` per pixel: adaptive sampling would stop at its noise threshold (1 %).
    scene.cycles.use_adaptive_sampling = False
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "cycles.exr")
    bpy.ops.render.render(write_still=True)
    return read_exr(tmp_path / "cycles.exr")


def add_light(bpy, scene, kind: str):
    """One light of each kind Blender has besides the Sun, placed to light the sphere and
    throw its shadow onto the ground; the spot's blend exercises the smoothstep edge."""
    data = bpy.data.lights.new(kind, kind)
    if kind == "POINT":
        data.energy, data.shadow_soft_size = 300.0, 0.0
        location, rotation = (2.0, -1.5, 2.5), (0.0, 0.0, 0.0)
    elif kind == "SPOT":
        data.energy, data.shadow_soft_size = 600.0, 0.0
        data.spot_size, data.spot_blend = math.radians(50.0), 0.4
        location, rotation = (0.0, -2.0, 4.0), (math.radians(26.0), 0.0, 0.0)
    else:
        data.energy, data.shape = 400.0, "RECTANGLE"
        data.size, data.size_y = 1.5, 0.6
        location, rotation = (-2.0, -1.0, 2.5), (math.radians(-30.0), math.radians(-40.0), 0.0)
    obj = bpy.data.objects.new(kind, data)
    obj.location, obj.rotation_euler = location, rotation
    scene.collection.objects.link(obj)
