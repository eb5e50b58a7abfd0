"""The evaluated depsgraph → a plain-array ``scene.scene.Scene``.

Meshes come with modifiers applied and instances expanded (``depsgraph.object_instances``).
Every simplification or problem is recorded in ``Scene.messages`` for the UI to show.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...scene.lights import Light
from ...scene.scene import Camera, Mesh, Scene
from .cache import CachedEnvironment, CachedMesh, ExportCache, MeshKey
from .camera import export_camera
from .light_bake import scene_light_bake
from .lights import export_light
from .materials import MaterialTable, SlotMaterial
from .meshes import GEOMETRY_OBJECT_TYPES, export_mesh
from .world import environment_from_world


def export_scene(
    depsgraph,
    width: int,
    height: int,
    cache: ExportCache | None = None,
    viewport: bool = False,
    light_bake: bool = True,
) -> Scene:
    """The evaluated scene as plain arrays. ``cache``: reuse (and fill) an earlier export's
    meshes and environment. ``viewport``: the view comes from the 3D view's own matrices, so a
    scene without a camera is fine (a placeholder camera is exported). ``light_bake``: read the
    scene's light bake for the drawer (False where the path tracer renders: F12, the accuracy
    report's ladder, a bake; a missing bake is then no message of theirs)."""
    scene = depsgraph.scene
    cache = cache if cache is not None else ExportCache()
    messages: list[str] = []
    materials = MaterialTable(messages)
    meshes: list[Mesh] = []
    lights: list[Light] = []
    used: set[MeshKey] = set()
    for inst in depsgraph.object_instances:
        obj = inst.object
        world_from_object = np.array(inst.matrix_world, dtype=np.float64)
        if obj.type == "LIGHT":
            light = export_light(obj.data, world_from_object, messages)
            if light is not None:
                lights.append(light)
            continue
        if obj.type not in GEOMETRY_OBJECT_TYPES:
            continue
        slots = [materials.slot(s.material if s is not None else None) for s in _slots(obj)]
        key = MeshKey.of(obj)
        used.add(key)
        entry = _cached_mesh(cache, key, obj, slots)
        messages += [m for m in entry.messages if m not in messages]
        for mesh in entry.meshes:
            material = slots[mesh.material].index
            meshes.append(replace(mesh, world_from_object=world_from_object, material=material))
    cache.keep_only(used)
    environment = _cached_environment(cache, scene.world)
    messages += environment.messages
    if viewport and scene.camera is None:
        camera = Camera(np.eye(4))
    else:
        camera = export_camera(scene, width, height, depsgraph=depsgraph)
    out = Scene(meshes, materials.materials, camera, environment.environment, messages, lights)
    out.metres_per_unit = float(scene.unit_settings.scale_length)  # real-world sizes (mapping)
    if light_bake:
        out.light_bake = scene_light_bake(scene, out.messages)  # the drawer plays it back
    return out


def _slots(obj) -> list:
    """The object's material slots; an object without any renders as one empty slot."""
    return list(obj.material_slots) or [None]


def _cached_mesh(cache: ExportCache, key: MeshKey, obj, slots: list[SlotMaterial]) -> CachedMesh:
    entry = cache.meshes.get(key)
    if entry is None:
        messages: list[str] = []
        meshes = export_mesh(obj, [slot.uv_map for slot in slots], messages)
        entry = CachedMesh(tuple(meshes), tuple(slot.name for slot in slots), tuple(messages))
        cache.meshes[key] = entry
    return entry


def _cached_environment(cache: ExportCache, world) -> CachedEnvironment:
    name = world.name if world is not None else ""
    if cache.environment is None or cache.environment.world_name != name:
        environment, messages = environment_from_world(world)
        cache.environment = CachedEnvironment(name, environment, tuple(messages))
    return cache.environment
