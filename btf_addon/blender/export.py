"""The evaluated depsgraph → a plain-array ``scene.scene.Scene``.

Meshes come with modifiers applied and instances expanded (``depsgraph.object_instances``),
triangulated through loop triangles, with per-corner normals (Blender's own, so smooth/flat
shading and custom normals are honoured), UVs and generated tangents. Materials: a material
slot whose ``btf`` settings are enabled is drawn with that BTF; any other material with an
analytic BTF of its surface shader (``materials.py``).
Every simplification or problem is recorded in ``Scene.messages`` for the UI to show.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import bpy
import numpy as np

from ..core.codecs import load_btf
from ..core.errors import BTFError
from ..core.model import BTF
from ..scene.lights import AreaLight, Light, PointLight, SunLight
from ..scene.scene import Camera, Material, Mesh, Scene
from ..scene.tangents import corner_tangents
from .materials import analytic_btf
from .world import environment_from_world

log = logging.getLogger(__name__)

# Loading a BTF is costly (text tables, checksums): keep them by absolute path and mtime.
_btf_cache: dict[tuple[str, float], BTF] = {}


def load_cached(path: str) -> BTF:
    resolved = Path(bpy.path.abspath(path)).resolve()
    key = (str(resolved), resolved.stat().st_mtime if resolved.exists() else -1.0)
    if key not in _btf_cache:
        _btf_cache[key] = load_btf(resolved)
    return _btf_cache[key]


def export_material(material, messages: list[str]) -> tuple[Material, str]:
    """→ (render material, UV map name or '' for the active render UV map)."""
    settings = getattr(material, "btf", None) if material is not None else None
    if settings is not None and settings.enabled:
        if not settings.source:
            messages.append(f"material {material.name!r}: BTF enabled but no source set")
        else:
            try:
                btf = load_cached(settings.source)
                return Material(
                    btf, settings.uv_scale, settings.uv_rotation, settings.exposure, material.name
                ), settings.uv_map
            except (BTFError, OSError) as exc:
                messages.append(f"material {material.name!r}: {exc}")
    name = material.name if material is not None else "default"
    return Material(analytic_btf(material, messages), name=name), ""


def export_light(light, world: np.ndarray, messages: list[str]) -> Light | None:
    """A Blender light → scene/lights.py in Cycles' units (power in watts, colour, exposure)."""
    strength = np.array(light.color, dtype=np.float64) * light.energy
    strength *= 2.0 ** getattr(light, "exposure", 0.0)  # Blender 4.x+ lights have exposure
    axes = world[:3, :3]
    position = world[:3, 3].copy()
    minus_z = -axes[:, 2] / max(np.linalg.norm(axes[:, 2]), 1e-30)
    if light.type == "SUN":
        return SunLight(-minus_z, strength)
    if light.type in {"POINT", "SPOT"}:
        spot = {}
        if light.type == "SPOT":
            spot = dict(
                axis=minus_z,
                cos_half_angle=math.cos(light.spot_size / 2),
                blend=float(light.spot_blend),
            )
        return PointLight.from_power(
            position, strength, radius=float(light.shadow_soft_size), **spot
        )
    if light.type == "AREA":
        if getattr(light, "spread", math.pi) < math.pi - 1e-6:
            messages.append(f"area light {light.name!r}: spread is rendered as 180°")
        rectangular = light.shape in {"RECTANGLE", "ELLIPSE"}
        size_y = light.size_y if rectangular else light.size
        # The object's scale stretches the light, as in Cycles.
        return AreaLight.from_power(
            position,
            minus_z,
            axes[:, 0] * light.size / 2,
            axes[:, 1] * size_y / 2,
            strength,
            ellipse=light.shape in {"DISK", "ELLIPSE"},
        )
    messages.append(f"{light.type.lower()} light {light.name!r} is not supported")
    return None


def export_mesh(obj, slot_uv_names: list[str], messages: list[str]) -> list[Mesh]:
    """One object-space Mesh per material slot in use; ``Mesh.material`` is the slot index
    (export_scene maps it to the scene's material list and sets the world matrix)."""
    mesh = obj.to_mesh()
    try:
        mesh.calc_loop_triangles()
        tris = mesh.loop_triangles
        n_tris = len(tris)
        if n_tris == 0:
            return []
        loops = np.empty(n_tris * 3, dtype=np.int64)
        tris.foreach_get("loops", loops)
        verts = np.empty(n_tris * 3, dtype=np.int64)
        tris.foreach_get("vertices", verts)
        slots = np.empty(n_tris, dtype=np.int64)
        tris.foreach_get("material_index", slots)
        slots = np.clip(slots, 0, len(slot_uv_names) - 1)
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        positions = co.reshape(-1, 3)[verts]
        corner_normals = np.empty(len(mesh.loops) * 3, dtype=np.float32)
        mesh.corner_normals.foreach_get("vector", corner_normals)
        normals = corner_normals.reshape(-1, 3)[loops]
        out = []
        for slot in np.unique(slots):
            uvs = _corner_uvs(obj, mesh, loops, slot_uv_names[slot], messages)
            corners = np.repeat(slots == slot, 3)
            p, n, uv = positions[corners], normals[corners], uvs[corners]
            out.append(Mesh(p, n, uv, corner_tangents(p, n, uv), np.eye(4), int(slot), obj.name))
        return out
    finally:
        obj.to_mesh_clear()


def _corner_uvs(obj, mesh, loops, uv_name: str, messages: list[str]) -> np.ndarray:
    layer = mesh.uv_layers.get(uv_name) if uv_name else None
    if layer is None:
        layer = next((uv for uv in mesh.uv_layers if uv.active_render), None)
        if uv_name:
            messages.append(
                f"object {obj.name!r}: UV map {uv_name!r} not found, using "
                f"{layer.name if layer else 'none'}"
            )
    if layer is None:
        message = (
            f"object {obj.name!r} has no UV map: its BTF cannot be placed; add one "
            "(UV > Smart UV Project)"
        )
        if message not in messages:
            messages.append(message)
        return np.zeros((len(loops), 2), dtype=np.float32)
    uv = np.empty(len(mesh.loops) * 2, dtype=np.float32)
    layer.data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)[loops]


def export_camera(scene, width: int, height: int) -> Camera:
    cam_obj = scene.camera
    if cam_obj is None:
        raise BTFError("the scene has no camera: add one (Add > Camera) and make it active")
    cam = cam_obj.data
    m = np.array(cam_obj.matrix_world, dtype=np.float64)
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0)  # drop object scale: a camera has none
    aspect = width / height
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if aspect >= 1 else "VERTICAL"
        sensor = cam.sensor_width
    else:
        sensor = cam.sensor_width if fit == "HORIZONTAL" else cam.sensor_height
    # Blender measures shift in units of the sensor-fit dimension; Camera in the larger one.
    shift_factor = (aspect if fit == "HORIZONTAL" else 1.0) / max(aspect, 1.0)
    shift = (cam.shift_x * shift_factor, cam.shift_y * shift_factor)
    if cam.type == "ORTHO":
        larger = (
            cam.ortho_scale
            if (fit == "HORIZONTAL") == (aspect >= 1)
            else (cam.ortho_scale / aspect if aspect >= 1 else cam.ortho_scale * aspect)
        )
        return Camera(
            m,
            perspective=False,
            ortho_scale=larger,
            clip_start=cam.clip_start,
            clip_end=cam.clip_end,
            shift=shift,
        )
    half = sensor / 2 / cam.lens
    half_h = half / aspect if fit == "HORIZONTAL" else half
    if cam.type != "PERSP":
        log.warning("panoramic cameras are drawn as perspective")
    return Camera(
        m,
        True,
        2 * math.atan(half_h),
        clip_start=cam.clip_start,
        clip_end=cam.clip_end,
        shift=shift,
    )


@dataclass
class ExportCache:
    """What earlier exports produced, so that a viewport re-exports only what changed.

    Meshes are kept in object space per (object name, mesh data name, mesh data pointer), with
    the material names of their slots;
    world matrices and the material list are rebuilt on every export, which is cheap."""

    meshes: dict[tuple, tuple[list[Mesh], list[str], list[str]]] = field(default_factory=dict)
    environment: tuple[str, object, list[str]] | None = None

    def invalidate(self, objects=(), materials=(), world: bool = False) -> None:
        materials = set(materials)
        for key in list(self.meshes):
            if key[0] in objects or materials.intersection(self.meshes[key][1]):
                del self.meshes[key]  # a material's UV map choice changes the exported UVs
        if world:
            self.environment = None


def export_scene(
    depsgraph, width: int, height: int, cache: ExportCache | None = None, viewport: bool = False
) -> Scene:
    """The evaluated scene as plain arrays. ``viewport``: the view comes from the 3D view's own
    matrices, so a scene without a camera is fine (a placeholder camera is exported)."""
    scene = depsgraph.scene
    cache = cache if cache is not None else ExportCache()
    messages: list[str] = []
    materials: list[Material] = []
    material_ids: dict[str, tuple[int, str]] = {}
    meshes: list[Mesh] = []
    lights: list[Light] = []
    used: set[tuple] = set()
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "LIGHT":
            light = export_light(obj.data, np.array(inst.matrix_world, dtype=np.float64), messages)
            if light is not None:
                lights.append(light)
            continue
        if obj.type not in {"MESH", "CURVE", "SURFACE", "META", "FONT"}:
            continue
        slot_ids, slot_names = [], []
        for slot in obj.material_slots or [None]:
            material = slot.material if slot is not None else None
            key = material.name if material is not None else ""
            if key not in material_ids:
                exported, uv_name = export_material(material, messages)
                material_ids[key] = (len(materials), uv_name)
                materials.append(exported)
            slot_ids.append(material_ids[key])
            slot_names.append(key)
        # Geometry-nodes instances come as the generating object with other mesh data (all
        # instances of one geometry share it): the key holds the data, the name invalidates.
        name = obj.original.name if obj.original is not None else obj.name
        key = (name, obj.data.name if obj.data else "", obj.data.as_pointer() if obj.data else 0)
        used.add(key)
        if key not in cache.meshes:
            object_messages: list[str] = []
            exported_meshes = export_mesh(obj, [uv for _, uv in slot_ids], object_messages)
            cache.meshes[key] = (exported_meshes, slot_names, object_messages)
        cached, _, object_messages = cache.meshes[key]
        messages += [m for m in object_messages if m not in messages]
        world = np.array(inst.matrix_world, dtype=np.float64)
        for mesh in cached:
            meshes.append(
                replace(mesh, world_from_object=world, material=slot_ids[mesh.material][0])
            )
    for key in set(cache.meshes) - used:  # deleted objects, replaced evaluated data
        del cache.meshes[key]
    world_name = scene.world.name if scene.world is not None else ""
    if cache.environment is None or cache.environment[0] != world_name:
        env, env_messages = environment_from_world(scene.world)
        cache.environment = (world_name, env, env_messages)
    _, env, env_messages = cache.environment
    messages += env_messages
    if viewport and scene.camera is None:
        camera = Camera(np.eye(4))
    else:
        camera = export_camera(scene, width, height)
    return Scene(meshes, materials, camera, env, messages, lights)


def changed_ids(depsgraph) -> tuple[set[str], set[str], bool]:
    """(objects whose geometry changed, materials changed, World changed) from the depsgraph's
    updates. Transform-only changes need no re-export: world matrices are applied per export."""
    objects, materials, world = set(), set(), False
    for update in depsgraph.updates:
        datablock = update.id
        if isinstance(datablock, bpy.types.Object):
            if update.is_updated_geometry or update.is_updated_shading:
                objects.add(datablock.original.name if datablock.original else datablock.name)
        elif isinstance(datablock, bpy.types.Material):
            materials.add(datablock.name)
        elif isinstance(datablock, bpy.types.World | bpy.types.Image):
            world = True
    return objects, materials, world
