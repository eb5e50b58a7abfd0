"""Helpers for the Blender tests (tests/blender)."""

from __future__ import annotations

import importlib

EXTENSION_MODULE = "bl_ext.user_default.btf_materials"


def extension_submodule(name: str):
    """A module of the installed extension, e.g. ``btf_addon.blender.world``."""
    return importlib.import_module(f"{EXTENSION_MODULE}.{name}")


def init_gpu_module(bpy) -> None:
    """Background Blender refuses to draw with ``gpu`` until one render has set up a context:
    render one tiny Workbench frame."""
    scene = bpy.context.scene
    engine, (x, y) = scene.render.engine, (scene.render.resolution_x, scene.render.resolution_y)
    camera = scene.camera
    temporary = None
    if camera is None:  # rendering needs a camera; add one for this frame only
        temporary = bpy.data.objects.new("gpu-init", bpy.data.cameras.new("gpu-init"))
        scene.collection.objects.link(temporary)
        scene.camera = temporary
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = scene.render.resolution_y = 8
    try:
        bpy.ops.render.render(write_still=False)
    finally:
        scene.render.engine = engine
        scene.render.resolution_x, scene.render.resolution_y = x, y
        scene.camera = camera
        if temporary is not None:
            data = temporary.data
            bpy.data.objects.remove(temporary)
            bpy.data.cameras.remove(data)
