"""The demo scene: synthetic BTFs on Suzanne and a sphere under a bundled studiolight."""

from __future__ import annotations

import math
from pathlib import Path

import bpy

from ..core.codecs.dense import tabulate
from ..core.codecs.presets import make_preset
from ..core.formats.container import write_container
from . import compat
from .addon import ENGINE_ID


def studiolight(name: str = "forest") -> Path:
    return Path(bpy.utils.system_resource("DATAFILES")) / "studiolights" / "world" / f"{name}.exr"


def btf_material(name: str, source: Path, uv_scale: float = 1.0) -> bpy.types.Material:
    material = compat.with_nodes(bpy.data.materials.new(name))
    material.btf.enabled = True
    material.btf.source = str(source)
    material.btf.uv_scale = uv_scale
    return material


def build_demo_scene(data_dir: Path, resolution: tuple[int, int] = (640, 360)) -> bpy.types.Scene:
    """Replace the current file by the demo scene; its BTFs are written into ``data_dir``."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    data_dir.mkdir(parents=True, exist_ok=True)
    woven = data_dir / "woven-ubo81.btfm"
    if not woven.exists():  # ray-cast once (seconds), then tabulated on the UBO 81×81 grid
        write_container(woven, tabulate(make_preset("woven", texels=8)))
    glossy = data_dir / "ggx.btfm"
    if not glossy.exists():
        write_container(glossy, make_preset("ggx", albedo=(0.9, 0.55, 0.2), roughness=0.35))
    scene = bpy.context.scene
    scene.render.engine = ENGINE_ID
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    # Saved PNGs pass through the view transform: "Standard" is the plain sRGB curve (values
    # above 1 clip), without AgX's tone curve, and no dither noise, so an 8-bit PNG of the
    # demo is exactly linear → sRGB of the render.
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.dither_intensity = 0.0

    bpy.ops.mesh.primitive_monkey_add(size=1.6, location=(-1.1, 0.0, 0.0), rotation=(0, 0, -0.5))
    monkey = bpy.context.object
    bpy.ops.object.shade_smooth()
    subdivision = monkey.modifiers.new("Subdivision", "SUBSURF")
    # F12 evaluates render levels (default 2), the viewport levels: one level in both.
    subdivision.levels = subdivision.render_levels = 1
    monkey.data.materials.append(btf_material("Woven", woven, uv_scale=3.0))

    bpy.ops.mesh.primitive_uv_sphere_add(
        radius=0.8, location=(1.1, 0.0, -0.2), segments=64, ring_count=32
    )
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(btf_material("Glossy", glossy))

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 40.0
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -6.0, 1.2)
    cam.rotation_euler = (math.radians(80.0), 0.0, 0.0)
    scene.camera = cam

    world = compat.with_nodes(bpy.data.worlds.new("Forest"))
    nodes, links = world.node_tree.nodes, world.node_tree.links
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(str(studiolight()))
    links.new(texture.outputs["Color"], nodes["Background"].inputs["Color"])
    scene.world = world
    return scene
