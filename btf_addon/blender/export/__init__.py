"""The evaluated depsgraph → the plain-array scene every renderer draws (``scene/``).

One module per concern: ``depsgraph`` assembles the scene; ``meshes``, ``camera``, ``lights``,
``materials`` (with ``surface_shaders`` for materials without BTF settings) and ``world``
convert one kind of Blender data each, and ``light_bake`` reads the scene's light bake;
``cache`` keeps what a viewport may reuse and
``updates`` reads the depsgraph's updates into what the cache must forget.
"""

from __future__ import annotations

from .cache import CachedEnvironment, CachedMesh, ExportCache, MeshKey
from .depsgraph import export_scene
from .materials import ExportedMaterial, export_material
from .updates import ChangedIds, changed_ids

__all__ = [
    "CachedEnvironment",
    "CachedMesh",
    "ChangedIds",
    "ExportCache",
    "ExportedMaterial",
    "MeshKey",
    "changed_ids",
    "export_material",
    "export_scene",
]
