"""An evaluated object → object-space triangle meshes with per-corner attributes.

Triangulated through loop triangles, with Blender's own corner normals (so smooth/flat shading
and custom normals are honoured), UVs and generated tangents.
"""

from __future__ import annotations

import numpy as np

from ...scene.scene import Mesh
from ...scene.tangents import corner_tangents
from .materials import BOX_MAPPED

#: Object types (Blender's identifiers) whose evaluated data is a mesh we can draw.
GEOMETRY_OBJECT_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "META", "FONT"})


def export_mesh(obj, slot_uv_names: list[str], messages: list[str]) -> list[Mesh]:
    """One object-space Mesh per material slot in use; ``Mesh.material`` is the slot index
    (export_scene maps it to the scene's material list and sets the world matrix).
    ``slot_uv_names``: per slot, the UV map its material asks for ('' = active render map)."""
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
    """(len(loops), 2) float32: the named UV map (else the active render one) at ``loops``;
    zeros, with a message, when the mesh has none."""
    box_mapped = uv_name == BOX_MAPPED  # UVs optional: the box projection places the tile
    if box_mapped:
        uv_name = ""
    layer = mesh.uv_layers.get(uv_name) if uv_name else None
    if layer is None:
        layer = next((uv for uv in mesh.uv_layers if uv.active_render), None)
        if uv_name:
            messages.append(
                f"object {obj.name!r}: UV map {uv_name!r} not found, using "
                f"{layer.name if layer else 'none'}"
            )
    if layer is None and box_mapped:
        return np.zeros((len(loops), 2), dtype=np.float32)
    if layer is None:
        message = (
            f"object {obj.name!r} has no UV map: its UV-mapped BTF cannot be placed; add "
            "one (UV > Smart UV Project) or set the material's Mapping to Box"
        )
        if message not in messages:
            messages.append(message)
        return np.zeros((len(loops), 2), dtype=np.float32)
    uv = np.empty(len(mesh.loops) * 2, dtype=np.float32)
    layer.data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)[loops]
