"""The BTF material's Mapping sub-panel (a child of ``BTF_PT_material``): UV or Box mapping,
real-world size, texel filter, and what one tile measures on the active object."""

from __future__ import annotations

import bpy
import numpy as np
from bpy.types import Panel

from ...core.errors import BTFError
from ...core.mapping import Placement, uv_units_per_uv
from ..export.materials import BTFFileKey, file_key, load_cached, placement

#: UV density per mesh datablock, computed once: (pointer, loops, uv map, scale) → units/UV.
_density_cache: dict[tuple, float | None] = {}
#: Sources that failed to load, with the reason: the panel redraws on every mouse move and must
#: not retry (and re-parse) a broken file each time. A rewritten file has a new key.
_unreadable: dict[BTFFileKey, str] = {}


def mesh_units_per_uv(obj, uv_name: str = "") -> float | None:
    """World units per UV unit of ``obj``'s mesh (its scale included), or None without a UV
    map or UV area. Cached per mesh, loop count, UV map and object scale."""
    mesh = getattr(obj, "data", None)
    if obj is None or obj.type != "MESH" or mesh is None or not mesh.uv_layers:
        return None
    layer = mesh.uv_layers.get(uv_name) if uv_name else None
    layer = layer or next((uv for uv in mesh.uv_layers if uv.active_render), mesh.uv_layers[0])
    scale = tuple(round(float(s), 6) for s in obj.matrix_world.to_scale())
    key = (mesh.as_pointer(), len(mesh.loops), len(mesh.vertices), layer.name, scale)
    if key not in _density_cache:
        mesh.calc_loop_triangles()
        tris = mesh.loop_triangles
        loops = np.empty(len(tris) * 3, dtype=np.int64)
        tris.foreach_get("loops", loops)
        verts = np.empty(len(tris) * 3, dtype=np.int64)
        tris.foreach_get("vertices", verts)
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        uv = np.empty(len(mesh.loops) * 2, dtype=np.float64)
        layer.data.foreach_get("uv", uv)
        m = np.array(obj.matrix_world, dtype=np.float64)[:3, :3]
        positions = co.reshape(-1, 3)[verts] @ m.T
        if len(_density_cache) > 256:  # a long session's edits: forget old meshes
            _density_cache.clear()
        _density_cache[key] = uv_units_per_uv(positions, uv.reshape(-1, 2)[loops])
    return _density_cache[key]


#: How the panel names where a material's own tile size came from.
ORIGINS = {
    "ASSUMED": lambda s: f"assumed on import: {s.assumed_texel_mm:g} mm per texel",
    "SET": lambda _s: "set by you",
    "UNKNOWN": lambda _s: "set on this material",
}


def stated_size(settings) -> tuple[tuple[float, float] | None, str]:
    """The tile size in use and where it came from, for the panel."""
    size = tuple(settings.tile_size_mm)
    if min(size) > 0.0:
        return (float(size[0]), float(size[1])), ORIGINS[settings.tile_size_origin](settings)
    if not settings.source:
        return None, "no BTF source"
    try:
        key = file_key(settings.source)
    except OSError as exc:
        return None, f"source not readable ({exc})"
    if key in _unreadable:
        return None, _unreadable[key]
    try:
        meta = load_cached(settings.source).meta
    except (BTFError, OSError) as exc:
        if len(_unreadable) > 64:
            _unreadable.clear()
        _unreadable[key] = f"source not readable ({exc})"
        return None, _unreadable[key]
    return meta.tile_size_mm, meta.tile_size_source


class BTF_PT_material_mapping(Panel):
    bl_label = "Mapping"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"
    bl_parent_id = "BTF_PT_material"

    @classmethod
    def poll(cls, context) -> bool:
        return context.material is not None

    def draw(self, context) -> None:
        settings = context.material.btf
        layout = self.layout
        layout.use_property_split = True
        layout.active = settings.enabled
        layout.prop(settings, "mapping")
        layout.prop(settings, "texel_filter")
        layout.prop(settings, "use_real_world_size")
        col = layout.column()
        col.active = settings.use_real_world_size
        col.prop(settings, "tile_size_mm")
        size, origin = stated_size(settings)
        if size is None:
            col.label(
                text=f"Tile size unknown ({origin}): set it to use real-world size", icon="ERROR"
            )
        else:
            assumed = settings.tile_size_origin == "ASSUMED" and min(settings.tile_size_mm) > 0
            col.label(
                text=f"Tile {size[0]:g} × {size[1]:g} mm ({origin})",
                icon="QUESTION" if assumed else "INFO",
            )
            if assumed:
                col.label(text="The source states no size: measure your sample, set it above")
        if settings.mapping == "UV":
            layout.prop(settings, "uv_map")
        else:
            layout.prop(settings, "box_space")
            layout.prop(settings, "box_blend")
        layout.prop(settings, "uv_scale", text="Scale")
        layout.prop(settings, "uv_rotation", text="Rotation")
        layout.prop(settings, "uv_offset")
        self._draw_here(context, settings, size)

    def _draw_here(self, context, settings, size) -> None:
        """ "1 tile ≈ 12 mm here": the tile on the active object, in the scene's units."""
        obj = context.object
        metres_per_unit = float(context.scene.unit_settings.scale_length)
        values = placement(settings)
        values["tile_size_mm"] = size
        p = Placement(uv_scale=settings.uv_scale, uv_rotation_rad=settings.uv_rotation, **values)
        if settings.mapping == "UV":
            units = mesh_units_per_uv(obj, settings.uv_map)
            mm = p.tile_mm_here(units, metres_per_unit)
            if mm is None:
                self.layout.label(
                    text="No UV map or UV area on the active object: use Box", icon="ERROR"
                )
                return
        else:
            a = p.block_matrix(None, metres_per_unit)
            mm = metres_per_unit * 1000.0 / max(float(np.linalg.norm(a[:, 0])), 1e-30)
        where = obj.name if obj is not None else "here"
        self.layout.label(text=f"1 tile ≈ {mm:.3g} mm on {where}")


classes = (BTF_PT_material_mapping,)
register, unregister = bpy.utils.register_classes_factory(classes)
